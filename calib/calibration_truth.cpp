#include "calib/calibration_truth.h"

#include <algorithm>
#include <cmath>

namespace sls::calib {
namespace {

constexpr double kDegree = M_PI / 180.0;

double focal_error(const CameraIntrinsics& estimated, const CameraIntrinsics& exact) {
  return std::max(std::fabs(estimated.fx - exact.fx) / exact.fx, std::fabs(estimated.fy - exact.fy) / exact.fy);
}

double principal_point_error(const CameraIntrinsics& estimated, const CameraIntrinsics& exact) {
  return std::hypot(estimated.cx - exact.cx, estimated.cy - exact.cy);
}

}  // namespace

double CalibrationErrors::focal_rel_err() const { return std::max(camera_focal_rel_err, projector_focal_rel_err); }

double CalibrationErrors::principal_point_err_px() const {
  return std::max(camera_principal_point_err_px, projector_principal_point_err_px);
}

PoseErrors compare_poses(const Pose& estimated, const Pose& exact) {
  PoseErrors errors;
  const double baseline = exact.translation().norm();
  errors.baseline_rel_err = std::fabs(estimated.translation().norm() - baseline) / baseline;
  errors.rotation_err_deg =
      Pose(estimated.rotation().transpose() * exact.rotation(), Eigen::Vector3d::Zero()).angle_rad() / kDegree;
  return errors;
}

CalibrationErrors compare_calibrations(const ScannerCalibration& estimated, const ScannerCalibration& exact) {
  CalibrationErrors errors;
  errors.camera_focal_rel_err = focal_error(estimated.camera, exact.camera);
  errors.projector_focal_rel_err = focal_error(estimated.projector, exact.projector);
  errors.camera_principal_point_err_px = principal_point_error(estimated.camera, exact.camera);
  errors.projector_principal_point_err_px = principal_point_error(estimated.projector, exact.projector);
  const PoseErrors pose = compare_poses(estimated.T_camera_projector, exact.T_camera_projector);
  errors.baseline_rel_err = pose.baseline_rel_err;
  errors.rotation_err_deg = pose.rotation_err_deg;
  if (estimated.turntable && exact.turntable) {
    const Eigen::Vector3d d = estimated.turntable->direction_camera.normalized();
    const Eigen::Vector3d d_exact = exact.turntable->direction_camera.normalized();
    errors.axis_direction_err_deg = std::acos(std::clamp(d.dot(d_exact), -1.0, 1.0)) / kDegree;
    const Eigen::Vector3d offset = estimated.turntable->point_camera - exact.turntable->point_camera;
    errors.axis_point_err_um = (offset - d_exact * d_exact.dot(offset)).norm() * 1e6;
    if (estimated.turntable->angle_sigma_deg && exact.turntable->angle_sigma_deg) {
      errors.angle_sigma_true_deg = exact.turntable->angle_sigma_deg;
      errors.angle_sigma_estimated_deg = estimated.turntable->angle_sigma_deg;
    }
    if (estimated.turntable->tilt_sigma_deg && exact.turntable->tilt_sigma_deg) {
      errors.tilt_sigma_true_deg = exact.turntable->tilt_sigma_deg;
      errors.tilt_sigma_estimated_deg = estimated.turntable->tilt_sigma_deg;
    }
  }
  return errors;
}

}  // namespace sls::calib
