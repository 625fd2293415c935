// sls_turntable: a turntable from the device registry (drivers/device_registry.h).
#include <chrono>
#include <cmath>
#include <memory>

#include "drivers/device_registry.h"
#include "sdk/capi/capi_guard.h"
#include "sdk/capi/context_internal.h"
#include "sdk/capi/device_handles.h"
#include "sdk/core/error.h"
#include "sdk/session/sim_charuco_board.h"
#include "sls/sls_turntable.h"

extern "C" {

SLS_API sls_status sls_turntable_open(sls_context* context, const char* uri, sls_turntable** turntable,
                                      sls_error** error) {
  SLS_CAPI_REQUIRE(turntable != nullptr, error, "turntable (the output pointer) is NULL");
  *turntable = nullptr;
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  SLS_CAPI_REQUIRE(uri != nullptr, error, "uri is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::drivers::OpenOptions options = sls::session::device_open_options(context->device);
    *turntable = new sls_turntable{sls::drivers::open_turntable(uri, options), uri};
  });
}

SLS_API void sls_turntable_close(sls_turntable* turntable) { delete turntable; }

SLS_API sls_status sls_turntable_home(sls_turntable* turntable, int timeout_ms, sls_error** error) {
  SLS_CAPI_REQUIRE(turntable != nullptr, error, "turntable is NULL");
  SLS_CAPI_REQUIRE(timeout_ms > 0, error, "timeout_ms must be positive");
  return sls::capi::guarded(__func__, error,
                            [&] { turntable->turntable->home(std::chrono::milliseconds(timeout_ms)); });
}

SLS_API sls_status sls_turntable_move_to_deg(sls_turntable* turntable, double angle_deg, int timeout_ms,
                                             sls_error** error) {
  SLS_CAPI_REQUIRE(turntable != nullptr, error, "turntable is NULL");
  SLS_CAPI_REQUIRE(std::isfinite(angle_deg) && angle_deg >= 0.0 && angle_deg < 360.0, error,
                   "angle_deg must be in [0, 360)");
  SLS_CAPI_REQUIRE(timeout_ms > 0, error, "timeout_ms must be positive");
  return sls::capi::guarded(__func__, error, [&] {
    turntable->turntable->move_to_deg(angle_deg, std::chrono::milliseconds(timeout_ms));
  });
}

SLS_API sls_status sls_turntable_get_position_deg(const sls_turntable* turntable, double* angle_deg,
                                                  sls_error** error) {
  SLS_CAPI_REQUIRE(turntable != nullptr, error, "turntable is NULL");
  SLS_CAPI_REQUIRE(angle_deg != nullptr, error, "angle_deg (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] { *angle_deg = turntable->turntable->position_deg(); });
}

SLS_API sls_status sls_turntable_get_steps_per_revolution(const sls_turntable* turntable, int* steps,
                                                          sls_error** error) {
  SLS_CAPI_REQUIRE(turntable != nullptr, error, "turntable is NULL");
  SLS_CAPI_REQUIRE(steps != nullptr, error, "steps (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] { *steps = turntable->turntable->steps_per_revolution(); });
}

}  // extern "C"
