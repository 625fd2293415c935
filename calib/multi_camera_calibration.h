// A head of several cameras and one projector (issue 17's multi-camera item): each camera
// calibrated against the projector by the one-camera pipeline (calibrate_capture.h), then
// each camera's pose relative to camera 0 from the board poses both saw.
//
// On disk a multi-camera capture is a folder holding one capture per camera in subfolders
// camera0, camera1, ... (contiguous from 0, at least two), each what `sls calibrate --input`
// takes for one camera (a recording, or a folder of captures with one subfolder per board
// pose), all of the same board poses in the same order (frame k, or the pose subfolder of the
// same name, is one board pose seen by every camera). A simulated one (`sls sim --calibration
// --cameras 2`) also holds groundtruth/calibration.yml, the head's exact calibration.
//
// The camera–camera pose comes from cv::stereoCalibrate over the camera corners of the views
// both cameras used, with both cameras' intrinsics fixed at their own calibration's: corners
// located to a few hundredths of a pixel in both images, against composing through the
// projector (T_camera0_projector · T_cameraK_projector⁻¹), which adds both procam poses' errors,
// the projector's corners being the noisier (docs/calibration.md has the two compared).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "calib/calibrate_capture.h"
#include "calib/calibration_truth.h"
#include "calib/procam_calibration.h"
#include "calib/view_observation.h"
#include "sdk/core/calibration.h"
#include "sdk/core/pose.h"
#include "sdk/core/progress.h"

namespace sls::calib {

// Camera K against camera 0.
struct CameraPairSolution {
  Pose T_camera0_camera;   // from stereoCalibrate (camera K frame -> camera 0 frame)
  Pose via_projector;      // T_camera0_projector · T_cameraK_projector⁻¹, for comparison
  double rms_px = 0.0;     // stereoCalibrate's, over both cameras' corners
  int views = 0;           // board poses both cameras used
  int corners = 0;         // corners both kept, over those views
};

// Views are parallel (view v of both is one board pose); each camera's procam calibration
// says which views and corners it used. Throws sls::Error(kInvalidArgument) when the two have
// different view counts, or fewer than `min_views` views both used.
CameraPairSolution calibrate_camera_pair(const std::vector<ViewObservation>& views0, const ProcamCalibration& camera0,
                                         const std::vector<ViewObservation>& views, const ProcamCalibration& camera,
                                         const BoardSpec& board, int min_views = 3);

// Whether `folder` is a multi-camera capture (it has a camera0 subfolder).
bool is_multi_camera_capture(const std::string& folder);

// The camera folders of a multi-camera capture, camera0 first. Throws sls::Error naming the
// folder: kNotFound without camera0, kInvalidArgument with only camera0 or with a gap (camera2
// without camera1).
std::vector<std::string> multi_camera_folders(const std::string& folder);

struct MultiCameraCalibrateResult {
  std::vector<std::string> camera_folders;
  std::vector<CalibrateCaptureResult> cameras;  // each camera against the projector
  std::vector<CameraPairSolution> pairs;        // camera 1 .. N−1 against camera 0
  // The head: camera 0's calibration (projector, turntable axis), the others as additional
  // cameras with their stereo poses.
  ScannerCalibration calibration;
  double camera_camera_rms_px = 0.0;            // over every pair's corners
  std::optional<ScannerCalibration> truth;      // groundtruth/calibration.yml of a simulated capture
  std::vector<PoseErrors> pair_errors;          // per pair, against the truth (stereo)
  std::vector<PoseErrors> pair_errors_via_projector;
  double seconds = 0.0;
};

// options.input is the multi-camera folder; each camera is calibrated with the other options.
// Throws sls::Error naming the camera folder: a layout error (above), camera folders of
// different board pose counts or names, any camera's calibration failing. Progress: each
// camera's as calibrate_capture's, its detail prefixed with the camera folder's name; then stage
// "camera pairs", before each camera's pair with camera0 ("camera1 against camera0") and once done.
MultiCameraCalibrateResult calibrate_multi_camera_capture(const CalibrateCaptureOptions& options,
                                                          const ProgressCallback& progress);

}  // namespace sls::calib
