// sls_projector: a projector from the device registry (drivers/device_registry.h), with the
// scan's pattern set (sdk/session/scan_setup.h) to load.
#include <cstddef>
#include <cstring>
#include <memory>

#include "drivers/device_registry.h"
#include "sdk/capi/capi_guard.h"
#include "sdk/capi/context_internal.h"
#include "sdk/capi/device_handles.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/error.h"
#include "sdk/session/sim_charuco_board.h"
#include "sdk/session/scan_setup.h"
#include "sls/sls_projector.h"

namespace {

constexpr std::size_t kProjectorInfoFirstVersionSize = offsetof(sls_projector_info, height) + sizeof(int);

}  // namespace

extern "C" {

SLS_CAPI_DEFINE_INIT(sls_projector_info, height, sls::capi::zeroed<sls_projector_info>())

SLS_API sls_status sls_projector_open(sls_context* context, const char* uri, sls_projector** projector,
                                      sls_error** error) {
  SLS_CAPI_REQUIRE(projector != nullptr, error, "projector (the output pointer) is NULL");
  *projector = nullptr;
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  SLS_CAPI_REQUIRE(uri != nullptr, error, "uri is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::drivers::OpenOptions options = sls::session::device_open_options(context->device);
    std::unique_ptr<sls::drivers::Projector> opened = sls::drivers::open_projector(uri, options);
    sls::drivers::ProjectorInfo info = opened->info();
    *projector = new sls_projector{std::move(opened), std::move(info)};
  });
}

SLS_API void sls_projector_close(sls_projector* projector) { delete projector; }

SLS_API sls_status sls_projector_get_info(const sls_projector* projector, sls_projector_info* info,
                                          sls_error** error) {
  SLS_CAPI_REQUIRE(projector != nullptr, error, "projector is NULL");
  SLS_CAPI_REQUIRE(info != nullptr, error, "info (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    sls_projector_info filled;
    sls_projector_info_init(&filled);
    filled.uri = projector->info.uri.c_str();
    filled.model = projector->info.model.c_str();
    filled.firmware = projector->info.firmware.c_str();
    filled.width = projector->info.width;
    filled.height = projector->info.height;
    sls::capi::write_versioned(filled, info, kProjectorInfoFirstVersionSize, "sls_projector_info");
  });
}

SLS_API sls_status sls_projector_load_scan_patterns(sls_projector* projector, int* pattern_count, sls_error** error) {
  SLS_CAPI_REQUIRE(projector != nullptr, error, "projector is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    projector->projector->load_patterns(sls::session::scan_pattern_set(*projector->projector));
    if (pattern_count != nullptr) *pattern_count = static_cast<int>(projector->projector->patterns().size());
  });
}

SLS_API sls_status sls_projector_show_pattern(sls_projector* projector, int index, sls_error** error) {
  SLS_CAPI_REQUIRE(projector != nullptr, error, "projector is NULL");
  return sls::capi::guarded(__func__, error, [&] { projector->projector->show_pattern(index); });
}

SLS_API sls_status sls_projector_get_current_pattern(const sls_projector* projector, int* index, sls_error** error) {
  SLS_CAPI_REQUIRE(projector != nullptr, error, "projector is NULL");
  SLS_CAPI_REQUIRE(index != nullptr, error, "index (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] { *index = projector->projector->current_pattern(); });
}

SLS_API sls_status sls_projector_go_dark(sls_projector* projector, sls_error** error) {
  SLS_CAPI_REQUIRE(projector != nullptr, error, "projector is NULL");
  return sls::capi::guarded(__func__, error, [&] { projector->projector->go_dark(); });
}

}  // extern "C"
