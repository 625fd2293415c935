// sls_context: version check, configuration, backend selection.
#include <cstring>
#include <new>

#include "sdk/capi/capi_guard.h"
#include "sdk/capi/context_internal.h"
#include "sdk/capi/log_internal.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/log.h"
#include "sls/sls_context.h"
#include "sls/sls_version.h"

namespace {

sls_context_config context_config_defaults() {
  sls_context_config config = sls::capi::zeroed<sls_context_config>();
  config.log_level = SLS_LOG_WARNING;
  config.device = SLS_DEVICE_AUTO;
  return config;
}

// The caller's config, which may come from older headers (smaller struct_size): fields it
// lacks keep their defaults.
sls_context_config read_config(const sls_context_config* user) {
  sls_context_config defaults;
  sls_context_config_init(&defaults);
  if (user == nullptr) return defaults;
  constexpr std::size_t kFirstVersionSize = offsetof(sls_context_config, cuda_device_id) + sizeof(int);
  return sls::capi::read_versioned(user, defaults, kFirstVersionSize, "sls_context_config");
}

sls::Device resolve_device(const sls_context_config& config) {
  if (config.cuda_device_id < 0) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "cuda_device_id {} is negative", config.cuda_device_id);
  }
  const long long preference = sls::capi::c_enum_value(config.device);
  switch (preference) {
    case SLS_DEVICE_CPU: return sls::Device::cpu();
    case SLS_DEVICE_CUDA: {
      const sls::Device device = sls::Device::cuda(config.cuda_device_id);
      sls::require_device(device);
      return device;
    }
    case SLS_DEVICE_AUTO:
      return config.cuda_device_id < sls::cuda_device_count() ? sls::Device::cuda(config.cuda_device_id)
                                                                : sls::Device::cpu();
    default: break;
  }
  sls::throw_error(sls::ErrorCode::kInvalidArgument, "device {} is not an sls_device_preference", preference);
}

}  // namespace

extern "C" {

SLS_API int sls_get_api_version(void) { return SLS_API_VERSION; }

SLS_API const char* sls_get_build_info(void) { return SLS_BUILD_INFO; }

SLS_CAPI_DEFINE_INIT(sls_context_config, cuda_device_id, context_config_defaults())

SLS_API sls_status sls_context_create(int api_version, const sls_context_config* config, sls_context** context,
                                      sls_error** error) {
  SLS_CAPI_REQUIRE(context != nullptr, error, "context (the output pointer) is NULL");
  *context = nullptr;
  const int caller_major = api_version / 10000, caller_minor = (api_version / 100) % 100;
  if (api_version < 0 || caller_major != SLS_API_VERSION_MAJOR || caller_minor > SLS_API_VERSION_MINOR) {
    return sls::capi::report(
        SLS_ERROR_VERSION_MISMATCH, __func__,
        "compiled against slscan API " + std::to_string(caller_major) + "." + std::to_string(caller_minor) +
            ", but the library provides " + std::to_string(SLS_API_VERSION_MAJOR) + "." +
            std::to_string(SLS_API_VERSION_MINOR),
        error);
  }
  return sls::capi::guarded(__func__, error, [&] {
    const sls_context_config resolved = read_config(config);
    sls::logger().set_level(sls::capi::log_level_from_c(resolved.log_level));
    const sls::Device device = resolve_device(resolved);
    *context = new sls_context{resolved, device};
  });
}

SLS_API void sls_context_destroy(sls_context* context) { delete context; }

SLS_API sls_status sls_context_uses_cuda(const sls_context* context, int* uses_cuda, sls_error** error) {
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  SLS_CAPI_REQUIRE(uses_cuda != nullptr, error, "uses_cuda (the output pointer) is NULL");
  *uses_cuda = context->device.is_cuda() ? 1 : 0;
  return SLS_OK;
}

SLS_API sls_status sls_get_cuda_device_count(int* count, sls_error** error) {
  SLS_CAPI_REQUIRE(count != nullptr, error, "count (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] { *count = sls::cuda_device_count(); });
}

}  // extern "C"
