// Synthetic board views for calib's solvers: corners projected exactly through a known camera,
// projector and pose (the simulated demo rig's values), with Gaussian noise of a given σ, over
// board poses like a calibration capture's. Shared by the calib tests.
#pragma once

#include <cmath>
#include <optional>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "calib/procam_calibration.h"
#include "calib/view_observation.h"
#include "sdk/core/calibration.h"
#include "sdk/core/camera_model_shared.h"

namespace sls::calib::synthetic {

inline constexpr double kDegree = M_PI / 180.0;

inline ScannerCalibration demo_rig() {
  ScannerCalibration c;
  c.camera = {800, 600, 6666.666, 6666.666, 399.5, 299.5, -0.3, 0.0, 0.0, 2e-4, -1e-4};
  c.projector = {912, 1140, 5700.0, 11400.0, 455.5, 569.5, -0.1, 0.0, 0.0, 0.0, 0.0};
  // The projector 25° around the vertical through the focus 100 mm ahead.
  const Eigen::Matrix3d r(Eigen::AngleAxisd(-25.0 * kDegree, Eigen::Vector3d::UnitY()));
  const Eigen::Vector3d focus(0.0, 0.0, 0.1);
  c.T_camera_projector = Pose(r, focus - r * Eigen::Vector3d(0.0, 0.0, 0.1));
  return c;
}

inline BoardSpec board() { return {9, 7, 0.0006}; }

inline Eigen::Vector2d project_point(const CameraIntrinsics& c, const Eigen::Vector3d& p) {
  Vec2d pixel{};
  project(c, Vec3d{p.x(), p.y(), p.z()}, &pixel);
  return {pixel.x, pixel.y};
}

inline ViewObservation observe(const ScannerCalibration& rig, const Pose& T_camera_board, double sigma_px, std::mt19937* rng,
                        std::optional<double> angle = std::nullopt) {
  std::normal_distribution<double> noise(0.0, sigma_px);
  ViewObservation view;
  view.name = "synthetic";
  view.board_found = true;
  view.turntable_angle_deg = angle;
  const Pose T_projector_board = rig.T_camera_projector.inverse() * T_camera_board;
  for (const Eigen::Vector3d& p : board().object_points()) {
    view.camera_corners.push_back(project_point(rig.camera, T_camera_board * p) + Eigen::Vector2d(noise(*rng), noise(*rng)));
    view.projector.corners.push_back(project_point(rig.projector, T_projector_board * p) +
                                     Eigen::Vector2d(noise(*rng), noise(*rng)));
    view.projector.valid.push_back(1);
    view.projector.samples.push_back(100);
  }
  return view;
}

// Hand poses: tilted 18° / 28° about axes going once round, the board's centre spread over
// the field (±3.5 mm across, ±2.5 mm up, ±1.5 mm in depth at 100 mm).
inline std::vector<Pose> hand_poses(int count) {
  std::vector<Pose> poses;
  const Eigen::Vector3d centre_local(0.5 * 8 * 0.0006, 0.5 * 6 * 0.0006, 0.0);
  for (int i = 0; i < count; ++i) {
    const double azimuth = 2.0 * M_PI * i / count;
    const double tilt = (i % 2 == 0 ? 28.0 : 18.0) * kDegree;
    const Eigen::Matrix3d r(Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(azimuth), std::sin(azimuth), 0.0)));
    const Eigen::Vector3d centre(3.0e-3 * std::cos(1.7 * i), 2.0e-3 * std::sin(2.3 * i), 0.1 + 1.5e-3 * std::sin(0.9 * i));
    poses.emplace_back(r, centre - r * centre_local);
  }
  return poses;
}

inline ProcamSettings settings() {
  ProcamSettings s;
  s.board = board();
  s.camera_width = 800;
  s.camera_height = 600;
  s.projector_width = 912;
  s.projector_height = 1140;
  return s;
}

}  // namespace sls::calib::synthetic
