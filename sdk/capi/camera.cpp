// sls_camera: a camera from the device registry (drivers/device_registry.h) with a one-call
// software-triggered grab into the caller's buffer.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>

#include "drivers/device_registry.h"
#include "sdk/capi/capi_guard.h"
#include "sdk/capi/context_internal.h"
#include "sdk/capi/device_handles.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/error.h"
#include "sdk/session/sim_charuco_board.h"
#include "sls/sls_camera.h"

namespace {

constexpr std::size_t kCameraInfoFirstVersionSize = offsetof(sls_camera_info, bit_depth) + sizeof(int);
constexpr std::size_t kFrameInfoFirstVersionSize = offsetof(sls_frame_info, frames_missed) + sizeof(std::uint64_t);

void grab(sls_camera& camera, int timeout_ms, std::uint16_t* pixels, std::size_t pixel_count, sls_frame_info* frame) {
  if (frame != nullptr) sls::capi::require_versioned(frame, kFrameInfoFirstVersionSize, "sls_frame_info");
  const std::size_t needed = static_cast<std::size_t>(camera.info.width) * static_cast<std::size_t>(camera.info.height);
  if (pixel_count < needed) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "{}: the buffer holds {} pixels, a {}x{} image needs {}",
                     camera.info.uri, pixel_count, camera.info.width, camera.info.height, needed);
  }
  if (!camera.acquiring) {
    camera.camera->start();
    camera.acquiring = true;
  }
  sls::drivers::CapturedImage captured;
  try {
    camera.camera->software_trigger();
    captured = camera.camera->wait_image(std::chrono::milliseconds(timeout_ms));
  } catch (...) {
    camera.stop_acquisition();  // the next grab starts afresh
    throw;
  }
  if (!captured.complete) {
    camera.stop_acquisition();  // the next grab starts afresh
    sls::throw_error(sls::ErrorCode::kDevice, "{}: frame {} arrived incomplete ({}); grab again", camera.info.uri,
                     captured.frame_id, captured.problem);
  }
  const sls::Image16u& image = captured.image;
  const std::size_t count = static_cast<std::size_t>(image.width()) * static_cast<std::size_t>(image.height());
  if (count > pixel_count) {  // the camera changed its size since it was opened
    sls::throw_error(sls::ErrorCode::kDevice, "{}: the image is {}x{}, not the {}x{} the camera reported",
                     camera.info.uri, image.width(), image.height(), camera.info.width, camera.info.height);
  }
  for (int y = 0; y < image.height(); ++y) {
    std::memcpy(pixels + static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width()), &image(0, y),
                static_cast<std::size_t>(image.width()) * sizeof(std::uint16_t));
  }
  if (frame != nullptr) {
    sls_frame_info filled;
    sls_frame_info_init(&filled);
    filled.width = image.width();
    filled.height = image.height();
    filled.bit_depth = camera.info.bit_depth;
    filled.timestamp_ns = captured.timestamp_ns;
    filled.frame_id = captured.frame_id;
    filled.frames_missed = captured.frames_missed;
    sls::capi::write_versioned(filled, frame, kFrameInfoFirstVersionSize, "sls_frame_info");
  }
}

}  // namespace

extern "C" {

SLS_CAPI_DEFINE_INIT(sls_camera_info, bit_depth, sls::capi::zeroed<sls_camera_info>())

SLS_CAPI_DEFINE_INIT(sls_frame_info, frames_missed, sls::capi::zeroed<sls_frame_info>())

SLS_API sls_status sls_camera_open(sls_context* context, const char* uri, sls_camera** camera, sls_error** error) {
  SLS_CAPI_REQUIRE(camera != nullptr, error, "camera (the output pointer) is NULL");
  *camera = nullptr;
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  SLS_CAPI_REQUIRE(uri != nullptr, error, "uri is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::drivers::OpenOptions options = sls::session::device_open_options(context->device);
    auto opened = std::make_unique<sls_camera>();
    opened->camera = sls::drivers::open_camera(uri, options);
    opened->info = opened->camera->info();
    *camera = opened.release();
  });
}

SLS_API void sls_camera_close(sls_camera* camera) { delete camera; }

SLS_API sls_status sls_camera_get_info(const sls_camera* camera, sls_camera_info* info, sls_error** error) {
  SLS_CAPI_REQUIRE(camera != nullptr, error, "camera is NULL");
  SLS_CAPI_REQUIRE(info != nullptr, error, "info (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    sls_camera_info filled;
    sls_camera_info_init(&filled);
    filled.uri = camera->info.uri.c_str();
    filled.model = camera->info.model.c_str();
    filled.serial = camera->info.serial.c_str();
    filled.width = camera->info.width;
    filled.height = camera->info.height;
    filled.bit_depth = camera->info.bit_depth;
    sls::capi::write_versioned(filled, info, kCameraInfoFirstVersionSize, "sls_camera_info");
  });
}

SLS_API sls_status sls_camera_set_exposure_us(sls_camera* camera, double exposure_us, sls_error** error) {
  SLS_CAPI_REQUIRE(camera != nullptr, error, "camera is NULL");
  SLS_CAPI_REQUIRE(exposure_us > 0.0, error, "exposure_us must be positive");
  return sls::capi::guarded(__func__, error, [&] { camera->camera->set_exposure_us(exposure_us); });
}

SLS_API sls_status sls_camera_grab(sls_camera* camera, int timeout_ms, uint16_t* pixels, size_t pixel_count,
                                   sls_frame_info* frame, sls_error** error) {
  SLS_CAPI_REQUIRE(camera != nullptr, error, "camera is NULL");
  SLS_CAPI_REQUIRE(pixels != nullptr, error, "pixels (the image buffer) is NULL");
  SLS_CAPI_REQUIRE(timeout_ms >= 0, error, "timeout_ms is negative");
  return sls::capi::guarded(__func__, error, [&] { grab(*camera, timeout_ms, pixels, pixel_count, frame); });
}

}  // extern "C"
