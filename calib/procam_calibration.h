// Camera and projector intrinsics and their relative pose from board views (the projector as
// an inverse camera, Moreno & Taubin 2012): OpenCV's calibrateCamera for each, then one joint
// refinement of both intrinsics and the extrinsics (stereoCalibrate), then each view's board
// pose under the final model (camera and projector residuals together), from which come the
// per-view and per-corner residuals.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/board.h"
#include "calib/view_observation.h"
#include "sdk/core/calibration.h"
#include "sdk/core/pose.h"
#include "sdk/core/progress.h"

namespace sls::calib {

struct ProcamSettings {
  BoardSpec board;
  int camera_width = 0, camera_height = 0;
  int projector_width = 0, projector_height = 0;
  // k3 (the r^6 term) is poorly determined by a narrow field of view and trades off against
  // k1/k2 and the focal length; fixed at 0 unless asked for.
  bool estimate_k3 = false;
  // Tangential distortion (p1, p2): in a narrow field of view it moves the corners almost as
  // a shift of the principal point with a turn of the device does, so fitted freely it trades
  // with them and the principal point wanders by tens of pixels. kAuto fits p1, p2 only when
  // they lower the residual significantly (an F-test between the nested models, per device);
  // kEstimate always, kZero never. kAuto treats k2 the same way after p1, p2 (a 7° field
  // barely sees r^5: k2 trades with k1 and the focal length).
  enum class Tangential { kAuto, kEstimate, kZero };
  Tangential tangential = Tangential::kAuto;
  // Weigh the joint refinement's camera and projector residuals by their noise (each device's
  // RMS alone): a maximum-likelihood fit rather than one that trusts the noisier device as
  // much as the other.
  bool weight_joint_by_noise = true;
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
  bool camera_tangential = false;     // p1, p2 fitted (else fixed at 0), see ProcamSettings
  bool projector_tangential = false;
  bool camera_k2 = true;              // k2 fitted (else fixed at 0)
  bool projector_k2 = true;
  double projector_weight = 1.0;      // the projector residuals' weight relative to the camera's
  std::vector<ViewSolution> views;  // parallel to the observations
};

// Throws sls::Error(kInvalidArgument) when fewer than min_views views are usable (naming how
// many were rejected and why), or the sizes are missing.
// Progress: stage "solve", before each of its kProcamSolveSteps steps (done 0, 1, 2 of 3: "camera",
// "projector", "camera and projector"); a callback that returns false ends it with kCancelled.
inline constexpr std::size_t kProcamSolveSteps = 3;
ProcamCalibration calibrate_procam(const std::vector<ViewObservation>& views, const ProcamSettings& settings,
                                   const ProgressCallback& progress = {});

// Residuals of one view under a calibration and board pose (observed − predicted).
void view_residuals(const ViewObservation& view, const ScannerCalibration& calibration, const BoardSpec& board,
                    const Pose& T_camera_board, ViewSolution* solution);

// The board pose that best explains a view in camera and projector together (starting from
// `initial`), under a fixed calibration; `masks` (optional) selects the corners used; the
// projector's residuals weigh `projector_weight` times the camera's.
Pose refine_board_pose(const ViewObservation& view, const ScannerCalibration& calibration, const BoardSpec& board,
                       const Pose& initial, const ViewSolution* masks = nullptr, double projector_weight = 1.0);

}  // namespace sls::calib
