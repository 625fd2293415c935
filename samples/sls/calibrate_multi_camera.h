// `sls calibrate --input DIR` on a multi-camera capture (DIR/camera0, DIR/camera1, ...:
// calib/multi_camera_calibration.h): each camera against the projector, then the cameras'
// poses relative to camera 0; one calibration.yml for the head (camera 0 primary).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "calib/calibrate_capture.h"
#include "calib/multi_camera_calibration.h"
#include "samples/sls/cli.h"
#include "sdk/core/progress.h"

namespace sls::cli {

// Camera 0's JSON (calibration_json: the figures a one-camera calibration has, for the
// primary camera) with camera_count, camera_camera_rms_px and `cameras`: per camera its
// folder, camera_rms_px, projector_rms_px, stereo_rms_px, views, intrinsics, its pose
// against camera 0 (cameras 1 ..) with stereo_rms_px's counterpart camera_camera_rms_px, and
// on a simulated capture its truth (the camera's against the projector, and the
// camera–camera pose's baseline_rel_err and rotation_err_deg, stereo and via the projector).
nlohmann::json multi_camera_calibration_json(const calib::MultiCameraCalibrateResult& result);

struct MultiCameraOutput {
  std::string out;     // calibration.yml
  std::string report;  // folder, or empty
  double max_rms_px = 1.0;
  bool force = false;
  ProgressCallback progress;  // the calibration's; none: the context's "calibrate" display
  nlohmann::json capture;     // a head captured just before (`sls calibrate --camera ...`): its
                              // capture figures, the JSON's "capture"; null: none
};

// Calibrates options.input (a multi-camera capture), writes the calibration (unless an RMS,
// a camera's stereo or the camera–camera one, is above max_rms_px without force) and the
// report (camera 0's in the folder, camera K's in folder/cameraK), and prints the result.
int run_multi_camera_calibrate(const Context& context, const calib::CalibrateCaptureOptions& options,
                               const MultiCameraOutput& output);

}  // namespace sls::cli
