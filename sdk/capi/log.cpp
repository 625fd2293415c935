// sls_log.h: the SDK's logger (sdk/core/log.h) to the caller's callback, and its level.
#include "sls/sls_log.h"

#include <spdlog/spdlog.h>

#include <mutex>

#include "sdk/capi/capi_guard.h"
#include "sdk/capi/log_internal.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/error.h"
#include "sdk/core/log.h"

namespace {

sls_log_level to_c(spdlog::level::level_enum level) {
  switch (level) {
    case spdlog::level::trace: return SLS_LOG_TRACE;
    case spdlog::level::debug: return SLS_LOG_DEBUG;
    case spdlog::level::info: return SLS_LOG_INFO;
    case spdlog::level::warn: return SLS_LOG_WARNING;
    case spdlog::level::err:
    case spdlog::level::critical: return SLS_LOG_ERROR;
    default: return SLS_LOG_OFF;
  }
}

// The C callback and its user pointer, called through the core's plain-function handler. Two
// slots: a new callback is written into the one not in use, then swapped in at once (under the
// sink's lock), so no message sees a half-written one or falls back to stderr meanwhile.
struct CCallback {
  sls_log_callback callback = nullptr;
  void* user = nullptr;
};
CCallback g_slots[2];
int g_active = 0;
std::mutex g_setter;  // one sls_set_log_callback at a time

void forward(spdlog::level::level_enum level, const char* message, void* user) {
  const CCallback& target = *static_cast<const CCallback*>(user);
  if (target.callback != nullptr) target.callback(to_c(level), message, target.user);
}

}  // namespace

namespace sls::capi {

spdlog::level::level_enum log_level_from_c(const sls_log_level& field) {
  const long long level = c_enum_value(field);
  switch (level) {
    case SLS_LOG_TRACE: return spdlog::level::trace;
    case SLS_LOG_DEBUG: return spdlog::level::debug;
    case SLS_LOG_INFO: return spdlog::level::info;
    case SLS_LOG_WARNING: return spdlog::level::warn;
    case SLS_LOG_ERROR: return spdlog::level::err;
    case SLS_LOG_OFF: return spdlog::level::off;
    default: break;
  }
  throw_error(ErrorCode::kInvalidArgument, "log level {} is not an sls_log_level", level);
}

}  // namespace sls::capi

extern "C" {

SLS_API sls_status sls_set_log_callback(sls_log_callback callback, void* user, sls_error** error) {
  return sls::capi::guarded(__func__, error, [&] {
    sls::require_not_in_log_handler();  // before the setters' lock, which the handler's thread may wait for
    const std::lock_guard<std::mutex> lock(g_setter);
    if (callback == nullptr) {
      sls::set_log_handler(nullptr, nullptr);
      return;
    }
    const int next = 1 - g_active;
    g_slots[next] = CCallback{callback, user};
    sls::set_log_handler(forward, &g_slots[next]);
    g_active = next;
  });
}

SLS_API sls_status sls_set_log_level(sls_log_level level, sls_error** error) {
  return sls::capi::guarded(__func__, error,
                            [&] { sls::logger().set_level(sls::capi::log_level_from_c(level)); });
}

SLS_API sls_status sls_get_log_level(sls_log_level* level, sls_error** error) {
  SLS_CAPI_REQUIRE(level != nullptr, error, "level (the output pointer) is NULL");
  *level = to_c(sls::logger().level());
  return SLS_OK;
}

}  // extern "C"
