// sls_calibration_capture: session::capture_calibration (sdk/session/calibration_capture.h,
// what `sls calibrate --camera` runs) behind the C API, on the caller's open device handles.
// Built in every configuration: the capture needs no OpenCV.
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "sdk/capi/capi_guard.h"
#include "sdk/capi/device_handles.h"
#include "sdk/capi/progress_callback.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/session/calibration_capture.h"
#include "sls/sls_calibration_capture.h"

namespace {

namespace fs = std::filesystem;
using sls::session::CalibrationPose;
using sls::session::CalibrationPoseKind;
using sls::session::PoseDecision;

// Both structs as first published (API 0.7).
constexpr std::size_t kConfigFirstVersionSize = offsetof(sls_calibration_capture_config, max_retries) + sizeof(int);
constexpr std::size_t kResultFirstVersionSize =
    offsetof(sls_calibration_capture_result, capture_seconds) + sizeof(double);

// The fields appended in 0.9 start past the 0.7 structs, padding included (versioned_struct.h).
static_assert(offsetof(sls_calibration_capture_config, more_cameras) >=
                  sls::capi::size_ending_at<sls_calibration_capture_config>(kConfigFirstVersionSize),
              "more_cameras lies in the padding of the 0.7 config");
static_assert(offsetof(sls_calibration_capture_result, cameras) >=
                  sls::capi::size_ending_at<sls_calibration_capture_result>(kResultFirstVersionSize),
              "cameras lies in the padding of the 0.7 result");

sls_calibration_capture_config capture_config_defaults() {
  sls_calibration_capture_config config = sls::capi::zeroed<sls_calibration_capture_config>();
  const sls::session::CalibrationCaptureOptions library;
  config.hand_poses = library.hand_poses;
  config.home_turntable = library.home_turntable ? 1 : 0;
  config.exposure_us = library.exposure_us;
  config.image_timeout_ms = static_cast<int>(library.image_timeout.count());
  config.turntable_timeout_ms = static_cast<int>(library.turntable_timeout.count());
  config.max_retries = library.max_retries;
  return config;
}

sls::session::CalibrationCaptureOptions capture_options(const sls_calibration_capture_config& config) {
  if (config.turntable_angle_count > 0 && config.turntable_angles_deg == nullptr) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.turntable_angles_deg is NULL but config.turntable_angle_count is {}",
                     config.turntable_angle_count);
  }
  sls::session::CalibrationCaptureOptions options;
  options.hand_poses = config.hand_poses;
  if (config.turntable_angle_count > 0) {
    options.turntable_angles_deg.assign(config.turntable_angles_deg,
                                        config.turntable_angles_deg + config.turntable_angle_count);
  }
  options.exposure_us = config.exposure_us;
  options.image_timeout = std::chrono::milliseconds(config.image_timeout_ms);
  options.turntable_timeout = std::chrono::milliseconds(config.turntable_timeout_ms);
  options.max_retries = config.max_retries;
  options.home_turntable = config.home_turntable != 0;
  options.resume = config.resume != 0;
  options.validate();
  return options;
}

// The head's other cameras (config.more_cameras, API 0.9), checked: none NULL, none `camera`
// or another of them again (one device cannot be two cameras of a head).
std::vector<sls::drivers::Camera*> more_cameras(const sls_calibration_capture_config& config, const sls_camera* camera) {
  if (config.more_camera_count == 0) return {};
  if (config.more_cameras == nullptr) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.more_cameras is NULL but config.more_camera_count is {}",
                     config.more_camera_count);
  }
  if (config.more_camera_count >= static_cast<std::size_t>(sls::ScannerCalibration::kMaxCameras)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.more_camera_count is {} (a head has at most {} cameras)",
                     config.more_camera_count, sls::ScannerCalibration::kMaxCameras);
  }
  std::vector<sls::drivers::Camera*> cameras;
  std::vector<const sls_camera*> seen = {camera};
  for (std::size_t k = 0; k < config.more_camera_count; ++k) {
    const sls_camera* more = config.more_cameras[k];
    if (more == nullptr) sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.more_cameras[{}] is NULL", k);
    const auto again = std::find(seen.begin(), seen.end(), more);
    if (again != seen.end()) {
      sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.more_cameras[{}] ({}) is camera {} of the head again",
                       k, more->info.uri, again - seen.begin());
    }
    seen.push_back(more);
    cameras.push_back(more->camera.get());
  }
  return cameras;
}

// What the folder must be for the capture, said in the C API's terms before any device moves
// (RecordingWriter refuses the same, without the way out). A head's recordings are in
// folder/camera0, ...
void check_folder(const std::string& folder, bool resume, bool head) {
  std::error_code error;
  const fs::path first = head ? fs::path(sls::head_camera_folder(folder, 0)) : fs::path(folder);
  const bool holds_recording = fs::exists(first / "manifest.json", error);
  if (resume && !holds_recording) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.resume: {} holds no recording to continue (no {}manifest.json)", folder,
                     head ? "camera0/" : "");
  }
  if (!resume && fs::exists(folder, error) && (!fs::is_directory(folder, error) || !fs::is_empty(folder, error))) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "recording_folder {} is not an empty folder{}; set config.resume to continue it, or choose "
                     "another",
                     folder, holds_recording ? " (it holds a recording, maybe one cut off)" : "");
  }
}

// The caller's pose callback as the library's confirmation. An answer that is no decision
// ends the capture (the library adds the frames kept to the message).
sls::session::PoseConfirmation pose_confirmation(sls_calibration_pose_callback callback, void* user) {
  if (callback == nullptr) return {};
  return [callback, user](const CalibrationPose& pose) {
    const std::string description = pose.describe();
    sls_calibration_pose asked = sls::capi::zeroed<sls_calibration_pose>();
    asked.kind = pose.kind == CalibrationPoseKind::kHand ? SLS_CALIBRATION_POSE_HAND : SLS_CALIBRATION_POSE_TURNTABLE;
    asked.index = pose.index;
    asked.count = pose.count;
    asked.turntable_angle_deg = pose.turntable_angle_deg.value_or(0.0);
    asked.description = description.c_str();
    const int answer = callback(&asked, user);
    switch (answer) {
      case SLS_CALIBRATION_POSE_CAPTURE: return PoseDecision::kCapture;
      case SLS_CALIBRATION_POSE_SKIP: return PoseDecision::kSkip;
      case SLS_CALIBRATION_POSE_STOP: return PoseDecision::kStop;
      default:
        sls::throw_error(sls::ErrorCode::kInvalidArgument,
                         "the pose callback answered {} for calibration {} (SLS_CALIBRATION_POSE_CAPTURE, _SKIP or "
                         "_STOP)",
                         answer, description);
    }
  };
}

sls_calibration_capture_result to_c(const sls::session::CalibrationCapture& captured) {
  sls_calibration_capture_result result;
  sls_calibration_capture_result_init(&result);
  result.poses_captured = static_cast<std::size_t>(captured.captured_poses());
  result.poses_skipped = static_cast<std::size_t>(captured.skipped_poses());
  result.stopped = captured.stopped ? 1 : 0;
  result.frames = static_cast<std::size_t>(captured.frames);
  result.hand_frames = static_cast<std::size_t>(captured.hand_frames);
  result.turntable_frames = static_cast<std::size_t>(captured.turntable_frames);
  result.resumed_from = static_cast<std::size_t>(captured.resumed_from);
  result.images_per_frame = captured.images_per_frame;
  result.incomplete_frames = static_cast<std::size_t>(captured.statistics.incomplete_frames);
  result.retries = static_cast<std::size_t>(captured.statistics.retries);
  result.seconds = captured.seconds;
  result.capture_seconds = captured.capture_seconds;
  result.cameras = static_cast<std::size_t>(captured.cameras);
  return result;
}

// The frames of the recording at `folder` (0 when there is none or it cannot be read): what a
// failed capture kept, and a resume starts from.
std::size_t frames_in(const std::string& folder) noexcept {
  try {
    return sls::RecordingReader::open(folder).frame_count();
  } catch (...) {
    return 0;
  }
}

}  // namespace

extern "C" {

SLS_CAPI_DEFINE_INIT(sls_calibration_capture_config, max_retries, capture_config_defaults())

SLS_CAPI_DEFINE_INIT(sls_calibration_capture_result, capture_seconds,
                     sls::capi::zeroed<sls_calibration_capture_result>())

SLS_API sls_status sls_calibration_capture(sls_camera* camera, sls_projector* projector, sls_turntable* turntable,
                                           const char* recording_folder, const sls_calibration_capture_config* config,
                                           sls_calibration_pose_callback pose_callback,
                                           sls_calibration_progress_callback progress, void* user,
                                           sls_calibration_capture_result* result, sls_error** error) {
  SLS_CAPI_REQUIRE(camera != nullptr, error, "camera is NULL");
  SLS_CAPI_REQUIRE(projector != nullptr, error, "projector is NULL");
  SLS_CAPI_REQUIRE(recording_folder != nullptr && recording_folder[0] != '\0', error,
                   "recording_folder is NULL or empty");
  // The caller's result struct checked first: a bad one must not cost a capture.
  const sls_status result_checked = sls::capi::guarded(__func__, error, [&] {
    if (result != nullptr) sls::capi::require_versioned(result, kResultFirstVersionSize, "sls_calibration_capture_result");
  });
  if (result_checked != SLS_OK) return result_checked;
  const std::string folder = recording_folder;
  std::string first_recording = folder;  // a head's: camera 0's, in folder/camera0
  const sls_status status = sls::capi::guarded(__func__, error, [&] {
    sls_calibration_capture_config defaults;
    sls_calibration_capture_config_init(&defaults);
    const sls_calibration_capture_config resolved =
        config == nullptr ? defaults
                          : sls::capi::read_versioned(config, defaults, kConfigFirstVersionSize,
                                                      "sls_calibration_capture_config");
    const sls::session::CalibrationCaptureOptions options = capture_options(resolved);
    const sls::PatternSet patterns = resolved.pattern_set != nullptr && resolved.pattern_set[0] != '\0'
                                         ? sls::pattern_set_from_name(resolved.pattern_set)
                                         : sls::session::calibration_pattern_set(*projector->projector);
    sls::session::CalibrationDevices devices;
    devices.more_cameras = more_cameras(resolved, camera);
    if (!devices.more_cameras.empty()) first_recording = sls::head_camera_folder(folder, 0);
    check_folder(folder, options.resume, !devices.more_cameras.empty());
    // The sequencer starts the cameras itself: a stream a grab left running would refuse that.
    camera->stop_acquisition();
    for (std::size_t k = 0; k < devices.more_cameras.size(); ++k) resolved.more_cameras[k]->stop_acquisition();
    devices.camera = camera->camera.get();
    devices.projector = projector->projector.get();
    if (turntable != nullptr) {
      devices.turntable = turntable->turntable.get();
      devices.turntable_name = "turntable " + turntable->uri;
    }
    const sls::session::CalibrationCapture captured =
        sls::session::capture_calibration(folder, devices, patterns, options, pose_confirmation(pose_callback, user),
                                          sls::capi::progress_callback(progress, user));
    if (result != nullptr) {
      sls::capi::write_versioned(to_c(captured), result, kResultFirstVersionSize, "sls_calibration_capture_result");
    }
  });
  if (status != SLS_OK && result != nullptr) {
    // What a resume would start from; the struct was checked above, so this cannot fail.
    sls::capi::guarded(__func__, nullptr, [&] {
      sls_calibration_capture_result kept;
      sls_calibration_capture_result_init(&kept);
      kept.frames = frames_in(first_recording);
      sls::capi::write_versioned(kept, result, kResultFirstVersionSize, "sls_calibration_capture_result");
    });
  }
  return status;
}

}  // extern "C"
