// Camera and projector intrinsics and their relative pose from board views (the projector as
// an inverse camera, Moreno & Taubin 2012): OpenCV's calibrateCamera for each, then one joint
// refinement of both intrinsics and the extrinsics (stereoCalibrate), then each view's board
// pose under the final model (camera and projector residuals together), from which come the
// per-view and per-corner residuals.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/board.h"
#include "calib/view_observation.h"
#include "sdk/core/calibration.h"
#include "sdk/core/pose.h"

namespace sls::calib {

struct ProcamSettings {
  BoardSpec board;
  int camera_width = 0, camera_height = 0;
  int projector_width = 0, projector_height = 0;
  // k3 (the r^6 term) is poorly determined by a narrow field of view and trades off against
  // k1/k2 and the focal length; fixed at 0 unless asked for.
  bool estimate_k3 = false;
  // A view whose board normal is farther than this from the camera's axis is rejected ("too
  // oblique"): corners foreshortened to slivers are located badly.
  double max_obliquity_deg = 65.0;
  int min_views = 3;
};

struct ViewSolution {
  bool used = false;
  std::string rejected_reason;                       // from observation or from the solve
  Pose T_camera_board;                               // board frame -> camera frame
  double obliquity_deg = 0.0;                        // board normal vs the camera's axis
  std::vector<Eigen::Vector2d> camera_residuals_px;  // observed − predicted, per corner
  std::vector<Eigen::Vector2d> projector_residuals_px;  // zero where the corner has no projector position
  double camera_rms_px = 0.0;                        // over the inlier corners
  double projector_rms_px = 0.0;
  // Corners used (1) or dropped as mislocated (0); the projector's start as its valid ones.
  std::vector<std::uint8_t> camera_inlier, projector_inlier;
};

struct ProcamCalibration {
  ScannerCalibration calibration;
  double camera_rms_px = 0.0;     // calibrateCamera of the camera alone
  double projector_rms_px = 0.0;  // calibrateCamera of the projector alone
  double stereo_rms_px = 0.0;     // the joint refinement, over both
  double joint_camera_rms_px = 0.0;     // under the final model, per device
  double joint_projector_rms_px = 0.0;
  int views_used = 0;
  int camera_outliers = 0;     // corners dropped as mislocated (see procam_calibration.cpp)
  int projector_outliers = 0;
  std::vector<ViewSolution> views;  // parallel to the observations
};

// Throws sls::Error(kInvalidArgument) when fewer than min_views views are usable (naming how
// many were rejected and why), or the sizes are missing.
ProcamCalibration calibrate_procam(const std::vector<ViewObservation>& views, const ProcamSettings& settings);

// Residuals of one view under a calibration and board pose (observed − predicted).
void view_residuals(const ViewObservation& view, const ScannerCalibration& calibration, const BoardSpec& board,
                    const Pose& T_camera_board, ViewSolution* solution);

// The board pose that best explains a view in camera and projector together (starting from
// `initial`), under a fixed calibration; `masks` (optional) selects the corners used.
Pose refine_board_pose(const ViewObservation& view, const ScannerCalibration& calibration, const BoardSpec& board,
                       const Pose& initial, const ViewSolution* masks = nullptr);

}  // namespace sls::calib
