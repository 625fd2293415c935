// A head of two cameras and one projector from synthetic corners (the demo rig's camera and
// projector, and a second camera mirroring the first across the projector): each camera
// against the projector as the one-camera solve does, then the camera–camera pose, stereo and
// through the projector. And the layout of a multi-camera capture on disk: its errors name the
// folder.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "calib/calibration_truth.h"
#include "calib/multi_camera_calibration.h"
#include "calib/procam_calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "tests/support/test_support.h"
#include "tests/unit/calib/synthetic_views.h"

namespace sls::calib {
namespace {

using namespace synthetic;  // NOLINT(google-build-using-namespace): the shared views

// Issue 17's targets for one camera against the projector, here for each camera and for the
// camera–camera pose.
constexpr double kFocalTolerance = 1e-3;
constexpr double kPrincipalPointTolerancePx = 1.0;
constexpr double kBaselineTolerance = 1e-3;
constexpr double kRotationToleranceDeg = 0.02;

struct Head {
  ScannerCalibration camera0;  // the demo rig
  ScannerCalibration camera1;  // the second camera with the same projector
  Pose T_camera0_camera1;
};

// The second camera 50° round the vertical through the focus (the projector, at 25°, halfway),
// with a lens of its own.
Head mirrored_head() {
  Head head;
  head.camera0 = demo_rig();
  const Eigen::Vector3d focus(0.0, 0.0, 0.1);
  const Eigen::Matrix3d r(Eigen::AngleAxisd(-50.0 * kDegree, Eigen::Vector3d::UnitY()));
  head.T_camera0_camera1 = Pose(r, focus - r * focus);
  head.camera1 = head.camera0;
  head.camera1.camera.cx += 3.0;
  head.camera1.camera.cy -= 2.0;
  head.camera1.camera.k1 = -0.25;
  head.camera1.camera.p1 = -1e-4;
  head.camera1.camera.p2 = 1.5e-4;
  head.camera1.T_camera_projector = head.T_camera0_camera1.inverse() * head.camera0.T_camera_projector;
  return head;
}

struct HeadViews {
  std::vector<ViewObservation> camera0, camera1;
};

// The hand poses turned to face the projector (halfway between the cameras), seen by both.
HeadViews observe_head(const Head& head, int poses, double sigma_px, std::uint32_t seed) {
  std::mt19937 rng(seed);
  const Eigen::Vector3d focus(0.0, 0.0, 0.1);
  const Eigen::Matrix3d face(Eigen::AngleAxisd(-25.0 * kDegree, Eigen::Vector3d::UnitY()));
  const Pose toward_projector(face, focus - face * focus);
  HeadViews views;
  for (const Pose& pose : hand_poses(poses)) {
    const Pose T_camera0_board = toward_projector * pose;
    views.camera0.push_back(observe(head.camera0, T_camera0_board, sigma_px, &rng));
    views.camera1.push_back(observe(head.camera1, head.T_camera0_camera1.inverse() * T_camera0_board, sigma_px, &rng));
  }
  return views;
}

struct HeadSolution {
  ProcamCalibration camera0, camera1;
  CameraPairSolution pair;
  CalibrationErrors errors0, errors1;
  PoseErrors stereo, via_projector;
};

HeadSolution solve(const Head& head, const HeadViews& views) {
  HeadSolution s;
  s.camera0 = calibrate_procam(views.camera0, settings());
  s.camera1 = calibrate_procam(views.camera1, settings());
  s.pair = calibrate_camera_pair(views.camera0, s.camera0, views.camera1, s.camera1, board());
  s.errors0 = compare_calibrations(s.camera0.calibration, head.camera0);
  s.errors1 = compare_calibrations(s.camera1.calibration, head.camera1);
  s.stereo = compare_poses(s.pair.T_camera0_camera, head.T_camera0_camera1);
  s.via_projector = compare_poses(s.pair.via_projector, head.T_camera0_camera1);
  return s;
}

TEST(MultiCameraCalibration, ExactCornersGiveTheExactHead) {
  const Head head = mirrored_head();
  const HeadSolution s = solve(head, observe_head(head, 12, 0.0, 1));
  EXPECT_EQ(s.pair.views, 12);
  EXPECT_EQ(s.pair.corners, 12 * 63);
  EXPECT_LT(s.pair.rms_px, 1e-3);
  for (const CalibrationErrors& e : {s.errors0, s.errors1}) {
    EXPECT_LT(e.camera_focal_rel_err, 1e-5);
    EXPECT_LT(e.camera_principal_point_err_px, 0.01);
  }
  EXPECT_LT(s.stereo.baseline_rel_err, 1e-5);
  EXPECT_LT(s.stereo.rotation_err_deg, 1e-4);
  EXPECT_LT(s.via_projector.baseline_rel_err, 1e-5);
  EXPECT_LT(s.via_projector.rotation_err_deg, 1e-4);
}

// Corners located to 0.03 px (the simulator's demo capture), 12 poses. Measured over three
// draws of the noise (seeds 7, 8, 9; seed 7 is the one run here, ~12 s):
//   focal, camera 0 / 1:        0.116 / 0.054 %, 0.091 / 0.049 %, 0.039 / 0.135 %  (target 0.1 %)
//   principal point, 0 / 1:     21.1 / 14.8 px, 10.2 / 3.9 px, 9.3 / 7.1 px       (target 1 px)
//   camera–camera baseline:     0.077 %, 0.018 %, 0.050 %                         (target 0.1 %)
//   camera–camera rotation:     0.302°, 0.070°, 0.063°                            (target 0.02°)
//   the same through the projector: 0.066 % / 0.303°, 0.015 % / 0.056°, 0.051 % / 0.063°
// The baseline is within issue 17's target; the focal lengths are in four cases of six (both
// cameras in one draw of three, not in the one run here); the principal points and the
// rotation are not, for the reason the one-camera calibration's are not (docs/calibration.md,
// "What limits it": a 7° field barely tells a principal-point shift from a turn of the device,
// and a camera's turn is the camera–camera pose's). What is checked
// beyond the baseline are the bounds this geometry gives, as
// ProcamCalibration.NoisyCornersOfTwelvePoses does; the targets are not loosened (the figures
// are in docs/benchmarks.md). With equal noise on camera and projector corners the stereo pose
// and the one through the projector are alike; on rendered captures the projector's corners
// are the noisier and the stereo pose is the better (benchmarks.md).
TEST(MultiCameraCalibration, NoisyCornersOfTwelvePoses) {
  const Head head = mirrored_head();
  const HeadSolution s = solve(head, observe_head(head, 12, 0.03, 7));
  std::printf("focal %.4f %% / %.4f %%, pp %.3f / %.3f px; camera-camera rms %.4f px, stereo baseline %.4f %% rotation "
              "%.4f°, via projector baseline %.4f %% rotation %.4f°\n",
              100 * s.errors0.camera_focal_rel_err, 100 * s.errors1.camera_focal_rel_err,
              s.errors0.camera_principal_point_err_px, s.errors1.camera_principal_point_err_px, s.pair.rms_px,
              100 * s.stereo.baseline_rel_err, s.stereo.rotation_err_deg, 100 * s.via_projector.baseline_rel_err,
              s.via_projector.rotation_err_deg);
  EXPECT_LT(s.stereo.baseline_rel_err, kBaselineTolerance);
  // stereoCalibrate's RMS is of the 2-D residuals: σ √2 for σ per axis.
  EXPECT_NEAR(s.pair.rms_px, 0.03 * std::sqrt(2.0), 0.005);
  EXPECT_EQ(s.pair.views, 12);
  // Bounds, not the targets (camera 0's focal length is 0.116 % in this draw, above 0.1 %).
  EXPECT_LT(std::max(s.errors0.camera_focal_rel_err, s.errors1.camera_focal_rel_err), 2.0 * kFocalTolerance);
  EXPECT_LT(std::max(s.errors0.camera_principal_point_err_px, s.errors1.camera_principal_point_err_px),
            60.0 * kPrincipalPointTolerancePx);
  EXPECT_LT(s.stereo.rotation_err_deg, 30.0 * kRotationToleranceDeg);
}

TEST(MultiCameraCalibration, PairNeedsTheSamePosesAndEnoughOfThem) {
  const Head head = mirrored_head();
  HeadViews views = observe_head(head, 4, 0.0, 1);
  const ProcamCalibration camera0 = calibrate_procam(views.camera0, settings());
  const ProcamCalibration camera1 = calibrate_procam(views.camera1, settings());
  std::vector<ViewObservation> fewer = views.camera1;
  fewer.pop_back();
  ProcamCalibration camera1_fewer = camera1;
  camera1_fewer.views.pop_back();
  EXPECT_THROW(calibrate_camera_pair(views.camera0, camera0, fewer, camera1_fewer, board()), Error);
  ProcamCalibration two_used = camera1;
  two_used.views[0].used = two_used.views[1].used = false;
  try {
    calibrate_camera_pair(views.camera0, camera0, views.camera1, two_used, board());
    ADD_FAILURE() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("only 2 board pose(s) used by both cameras"), std::string::npos)
        << error.what();
  }
}

// Bad layouts fail at once (before any image is read) and name the folder.
TEST(MultiCameraCapture, LayoutErrorsNameTheFolder) {
  test::TemporaryDirectory directory;
  const std::string head = directory.file("head");
  create_directories(head);
  EXPECT_FALSE(is_multi_camera_capture(head));
  EXPECT_NE(test::message_of([&] { multi_camera_folders(head); }).find(head + ": no camera0"), std::string::npos);
  create_directories(head + "/camera0/pose0");
  EXPECT_TRUE(is_multi_camera_capture(head));
  EXPECT_NE(test::message_of([&] { multi_camera_folders(head); }).find("only camera0"), std::string::npos);
  create_directories(head + "/camera2/pose0");
  const std::string gap = test::message_of([&] { multi_camera_folders(head); });
  EXPECT_NE(gap.find(head + "/camera2 is there but " + head + "/camera1 is missing"), std::string::npos) << gap;
  create_directories(head + "/camera1/pose0");
  create_directories(head + "/camera1/pose1");
  EXPECT_EQ(multi_camera_folders(head).size(), 3u);
  CalibrateCaptureOptions options;
  options.input = head;
  options.patterns = "gray-phase:912x1140";
  options.board = board();
  const std::string counts = test::message_of([&] { calibrate_multi_camera_capture(options, {}); });
  EXPECT_NE(counts.find(head + "/camera1: 2 board poses, " + head + "/camera0 has 1"), std::string::npos) << counts;
}

}  // namespace
}  // namespace sls::calib
