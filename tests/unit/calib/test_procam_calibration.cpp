// calib's solve against known answers: board corners projected exactly through a known camera,
// projector and pose (the simulated demo rig's values), with Gaussian noise of a given σ, over
// board poses like a calibration capture's; the calibration must recover what made them.
// No images: what is tested is the solve (camera, projector, joint refinement, outlier
// rejection, the turntable axis), not the detection.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "calib/calibration_truth.h"
#include "calib/procam_calibration.h"
#include "calib/turntable_axis.h"
#include "sdk/core/camera_model_shared.h"

namespace sls::calib {
namespace {

constexpr double kDegree = M_PI / 180.0;

ScannerCalibration demo_rig() {
  ScannerCalibration c;
  c.camera = {800, 600, 6666.666, 6666.666, 399.5, 299.5, -0.3, 0.0, 0.0, 2e-4, -1e-4};
  c.projector = {912, 1140, 5700.0, 11400.0, 455.5, 569.5, -0.1, 0.0, 0.0, 0.0, 0.0};
  // The projector 25° around the vertical through the focus 100 mm ahead.
  const Eigen::Matrix3d r(Eigen::AngleAxisd(-25.0 * kDegree, Eigen::Vector3d::UnitY()));
  const Eigen::Vector3d focus(0.0, 0.0, 0.1);
  c.T_camera_projector = Pose(r, focus - r * Eigen::Vector3d(0.0, 0.0, 0.1));
  return c;
}

BoardSpec board() { return {9, 7, 0.0006}; }

Eigen::Vector2d project_point(const CameraIntrinsics& c, const Eigen::Vector3d& p) {
  Vec2d pixel{};
  project(c, Vec3d{p.x(), p.y(), p.z()}, &pixel);
  return {pixel.x, pixel.y};
}

ViewObservation observe(const ScannerCalibration& rig, const Pose& T_camera_board, double sigma_px, std::mt19937* rng,
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
std::vector<Pose> hand_poses(int count) {
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

ProcamSettings settings() {
  ProcamSettings s;
  s.board = board();
  s.camera_width = 800;
  s.camera_height = 600;
  s.projector_width = 912;
  s.projector_height = 1140;
  return s;
}

TEST(ProcamCalibration, ExactCornersGiveTheExactCalibration) {
  const ScannerCalibration rig = demo_rig();
  std::mt19937 rng(1);
  std::vector<ViewObservation> views;
  for (const Pose& pose : hand_poses(12)) views.push_back(observe(rig, pose, 0.0, &rng));
  const ProcamCalibration result = calibrate_procam(views, settings());
  const CalibrationErrors errors = compare_calibrations(result.calibration, rig);
  EXPECT_LT(result.stereo_rms_px, 1e-3);
  EXPECT_LT(errors.focal_rel_err(), 1e-5);
  EXPECT_LT(errors.principal_point_err_px(), 0.01);
  EXPECT_LT(errors.baseline_rel_err, 1e-5);
  EXPECT_LT(errors.rotation_err_deg, 1e-4);
  EXPECT_EQ(result.camera_outliers + result.projector_outliers, 0);
  // Exact corners see the camera's p1, p2 (2e-4, -1e-4: < 0.01 px at the image's corners).
  EXPECT_TRUE(result.camera_tangential);
}

// Corners located to 0.03 px (what the simulator's demo capture gives, measured against its
// exact corners). The focal lengths and the baseline come out well inside issue 17's targets;
// the principal points do not: a 7° field of view barely tells a principal-point shift from
// a turn of the device (both move every pixel alike), so they wander by tens of pixels with a
// matching turn between camera and projector. Printed, and bounded by what the geometry gives.
TEST(ProcamCalibration, NoisyCornersOfTwelvePoses) {
  const ScannerCalibration rig = demo_rig();
  std::mt19937 rng(7);
  std::vector<ViewObservation> views;
  for (const Pose& pose : hand_poses(12)) views.push_back(observe(rig, pose, 0.03, &rng));
  const ProcamCalibration result = calibrate_procam(views, settings());
  const CalibrationErrors e = compare_calibrations(result.calibration, rig);
  std::printf("σ 0.03 px, 12 poses: rms %.4f/%.4f/%.4f px, focal %.4f %% / %.4f %%, pp %.3f / %.3f px, baseline %.4f %%, "
              "rotation %.4f°, outliers %d/%d\n",
              result.camera_rms_px, result.projector_rms_px, result.stereo_rms_px, 100 * e.camera_focal_rel_err,
              100 * e.projector_focal_rel_err, e.camera_principal_point_err_px, e.projector_principal_point_err_px,
              100 * e.baseline_rel_err, e.rotation_err_deg, result.camera_outliers, result.projector_outliers);
  // 0.03 px of noise hides p1, p2 and k2 (their effect is < 0.1 px): held at 0, not fitted to
  // the noise. The projector's noise is the camera's, so its residuals weigh about the same.
  EXPECT_FALSE(result.camera_tangential);
  EXPECT_FALSE(result.projector_tangential);
  EXPECT_FALSE(result.camera_k2);
  EXPECT_FALSE(result.projector_k2);
  EXPECT_NEAR(result.projector_weight, 1.0, 0.1);
  EXPECT_LT(e.camera_focal_rel_err, 1e-3);
  EXPECT_LT(e.projector_focal_rel_err, 3e-3);
  EXPECT_LT(e.baseline_rel_err, 1e-3);
  EXPECT_LT(e.principal_point_err_px(), 60.0);
  EXPECT_LT(e.rotation_err_deg, 0.6);
}

}  // namespace
}  // namespace sls::calib
