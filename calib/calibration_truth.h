// A calibration against the exact one (the simulator's): the figures issue 17 sets targets
// for. Focal lengths relative, principal points in pixels, baseline relative, the rotation
// between camera and projector in degrees, the turntable axis' direction in degrees and its
// distance from the exact axis (µm) at the estimated axis point (the one nearest the board).
#pragma once

#include <optional>

#include "sdk/core/calibration.h"

namespace sls::calib {

struct CalibrationErrors {
  double camera_focal_rel_err = 0.0;       // max over fx, fy of |est − exact| / exact
  double projector_focal_rel_err = 0.0;
  double camera_principal_point_err_px = 0.0;  // |(cx, cy) − exact|
  double projector_principal_point_err_px = 0.0;
  double baseline_rel_err = 0.0;           // | |t| − |t exact| | / |t exact|
  double rotation_err_deg = 0.0;           // angle of R_est^T R_exact
  std::optional<double> axis_direction_err_deg;  // both calibrations have an axis
  std::optional<double> axis_point_err_um;
  // The table's true angle and tilt σ (the exact calibration's TurntableAxis::angle_sigma_deg,
  // tilt_sigma_deg) beside the estimated ones, when both calibrations have them.
  std::optional<double> angle_sigma_true_deg, angle_sigma_estimated_deg;
  std::optional<double> tilt_sigma_true_deg, tilt_sigma_estimated_deg;

  double focal_rel_err() const;            // the larger of camera and projector
  double principal_point_err_px() const;
};

// A relative pose (camera–projector or camera–camera) against the exact one: its baseline's
// relative error and the angle between the rotations (degrees).
struct PoseErrors {
  double baseline_rel_err = 0.0;
  double rotation_err_deg = 0.0;
};
PoseErrors compare_poses(const Pose& estimated, const Pose& exact);

CalibrationErrors compare_calibrations(const ScannerCalibration& estimated, const ScannerCalibration& exact);

}  // namespace sls::calib
