// calib's solve against known answers: board corners projected exactly through a known camera,
// projector and pose (the simulated demo rig's values), with Gaussian noise of a given σ, over
// board poses like a calibration capture's; the calibration must recover what made them.
// No images: what is tested is the solve (camera, projector, joint refinement, outlier
// rejection, the turntable axis), not the detection.
#include <array>
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "calib/calibration_truth.h"
#include "calib/procam_calibration.h"
#include "calib/turntable_axis.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/error.h"
#include "sdk/core/progress.h"
#include "tests/unit/calib/synthetic_views.h"

namespace sls::calib {
namespace {

using namespace synthetic;  // NOLINT(google-build-using-namespace): the shared views

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

// The solve says what it works on, step by step (a head's camera takes seconds here), and stops
// at the next step when asked, as kCancelled.
TEST(ProcamCalibration, ReportsEachStepOfTheSolveAndStopsWhenAsked) {
  const ScannerCalibration rig = demo_rig();
  std::mt19937 rng(1);
  std::vector<ViewObservation> views;
  for (const Pose& pose : hand_poses(6)) views.push_back(observe(rig, pose, 0.0, &rng));
  std::vector<ProgressUpdate> updates;
  calibrate_procam(views, settings(), [&updates](const ProgressUpdate& update) {
    updates.push_back(update);
    return true;
  });
  ASSERT_EQ(updates.size(), kProcamSolveSteps);
  const char* const steps[] = {"camera", "projector", "camera and projector"};
  for (std::size_t k = 0; k < updates.size(); ++k) {
    EXPECT_EQ(updates[k].stage, "solve");
    EXPECT_EQ((std::array<std::size_t, 2>{updates[k].done, updates[k].total}),
              (std::array<std::size_t, 2>{k, kProcamSolveSteps}));
    EXPECT_EQ(updates[k].detail, steps[k]);
  }
  std::size_t calls = 0;
  try {
    calibrate_procam(views, settings(), [&calls](const ProgressUpdate& update) {
      ++calls;
      return update.detail != "projector";
    });
    FAIL() << "not stopped";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kCancelled) << error.what();
  }
  EXPECT_EQ(calls, 2u);
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

// The board on the turntable: the axis 3 mm behind the board (the camera's −y: the table's
// z up), the board facing the camera at the focus at 0° and turned to `recorded` ± 25° with the
// table's true angle `recorded + jitter` (degrees); corners with σ_px of noise.
struct TableViews {
  std::vector<ViewObservation> views;
  std::vector<ViewSolution> solutions;
  std::vector<double> jitter_deg;
  std::vector<std::array<double, 2>> tilt_deg;
};
TableViews table_views(const ScannerCalibration& rig, int count, double jitter_sigma_deg, double sigma_px,
                       unsigned seed, double wobble_sigma_deg = 0.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> jitter(0.0, 1.0);
  Eigen::Matrix3d r;
  r.col(0) = Eigen::Vector3d::UnitX();
  r.col(2) = -Eigen::Vector3d::UnitY();
  r.col(1) = r.col(2).cross(r.col(0));
  const Pose T_camera_axis(r, Eigen::Vector3d(0.0, 0.0, 0.103));
  const Eigen::Vector3d centre_local(0.5 * 8 * 0.0006, 0.5 * 6 * 0.0006, 0.0);
  const Pose T_camera_board0(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.0, 0.0, 0.1) - centre_local);
  const Pose T_axis_board = T_camera_axis.inverse() * T_camera_board0;
  TableViews out;
  for (int i = 0; i < count; ++i) {
    const double recorded = -25.0 + 50.0 * i / (count - 1);
    const double j = jitter_sigma_deg * jitter(rng);
    const Pose turn(Eigen::Matrix3d(Eigen::AngleAxisd((recorded + j) * kDegree, Eigen::Vector3d::UnitZ())),
                    Eigen::Vector3d::Zero());
    // The table's wobble: a turn about an axis across its own, through the axis point.
    const Eigen::Vector3d tilt(wobble_sigma_deg * jitter(rng), wobble_sigma_deg * jitter(rng), 0.0);
    const Pose wobble(Eigen::Matrix3d(Eigen::AngleAxisd(tilt.norm() * kDegree,
                                                        tilt.norm() > 0.0 ? tilt.normalized() : Eigen::Vector3d::UnitX())),
                      Eigen::Vector3d::Zero());
    const Pose T_camera_board = T_camera_axis * wobble * turn * T_axis_board;
    out.tilt_deg.push_back({tilt.x(), tilt.y()});
    out.views.push_back(observe(rig, T_camera_board, sigma_px, &rng, recorded));
    ViewSolution solution;
    solution.used = true;
    solution.T_camera_board = T_camera_board;
    out.solutions.push_back(solution);
    out.jitter_deg.push_back(j);
  }
  return out;
}

double sample_sigma(const std::vector<double>& values) {
  double mean = 0.0, sum = 0.0;
  for (const double v : values) mean += v / static_cast<double>(values.size());
  for (const double v : values) sum += (v - mean) * (v - mean);
  return std::sqrt(sum / static_cast<double>(values.size() - 1));
}

// Exact corners, a jittery table: the spread of the views' turns against their recorded
// angles is the jitter's (the board's mount on the table takes its mean, and the axis, fitted
// with the recorded angles trusted, a part growing with the angle: each view's turn is not its
// jitter, up to half of it went into the axis' point), and none of it is noise.
TEST(TurntableAxis, AngleSigmaFromExactCornersIsTheJitter) {
  const ScannerCalibration rig = demo_rig();
  const TableViews table = table_views(rig, 9, 0.01, 0.0, 21);
  const AxisFit fit = fit_turntable_axis(table.views, table.solutions, rig, board());
  ASSERT_TRUE(fit.fitted) << fit.reason;
  ASSERT_EQ(fit.angle_residuals_deg.size(), table.jitter_deg.size());
  double mean = 0.0;
  for (const double j : table.jitter_deg) mean += j / static_cast<double>(table.jitter_deg.size());
  const double sigma = sample_sigma(table.jitter_deg);
  std::printf("[axis] exact corners, jitter sigma %.5f deg drawn: angle sigma %.5f, noise %.6f, jitter %.5f deg\n",
              sigma, fit.angle_sigma_deg, fit.angle_noise_deg, fit.angle_jitter_deg);
  double agree = 0.0;  // the turns follow the jitter: their correlation
  for (std::size_t v = 0; v < table.jitter_deg.size(); ++v) {
    agree += fit.angle_residuals_deg[v] * (table.jitter_deg[v] - mean);
  }
  EXPECT_GT(agree / (static_cast<double>(table.jitter_deg.size() - 1) * sigma * fit.angle_sigma_deg), 0.8);
  EXPECT_NEAR(fit.angle_sigma_deg, sigma, 0.15 * sigma);
  EXPECT_LT(fit.angle_noise_deg, 0.02 * sigma);  // what the axis took up of the jitter is left as misfit
  EXPECT_NEAR(fit.angle_jitter_deg, fit.angle_sigma_deg, 0.01 * sigma);
  ASSERT_TRUE(fit.axis.angle_sigma_deg.has_value());
  EXPECT_EQ(*fit.axis.angle_sigma_deg, fit.angle_sigma_deg);
  EXPECT_LT(fit.tilt_sigma_deg, 0.02 * sigma);  // it turned about its axis only
  // An exact table: nothing to find.
  const TableViews exact = table_views(rig, 9, 0.0, 0.0, 21);
  const AxisFit exact_fit = fit_turntable_axis(exact.views, exact.solutions, rig, board());
  ASSERT_TRUE(exact_fit.fitted) << exact_fit.reason;
  EXPECT_LT(exact_fit.angle_sigma_deg, 1e-6);
  EXPECT_LT(exact_fit.tilt_sigma_deg, 1e-6);
  ASSERT_TRUE(exact_fit.axis.tilt_sigma_deg.has_value());
}

// Exact corners, a table that wobbles: the views' tilts across the axis are the wobble (less
// its mean, which the axis' direction takes), apart from its turns.
TEST(TurntableAxis, TiltSigmaFromExactCornersIsTheWobble) {
  const ScannerCalibration rig = demo_rig();
  const TableViews table = table_views(rig, 9, 0.0, 0.0, 22, 0.01);
  const AxisFit fit = fit_turntable_axis(table.views, table.solutions, rig, board());
  ASSERT_TRUE(fit.fitted) << fit.reason;
  ASSERT_EQ(fit.tilt_residuals_deg.size(), table.tilt_deg.size());
  double spread = 0.0;
  for (int k = 0; k < 2; ++k) {
    std::vector<double> component;
    for (const auto& t : table.tilt_deg) component.push_back(t[static_cast<std::size_t>(k)]);
    spread += 0.5 * sample_sigma(component) * sample_sigma(component);
  }
  const double sigma = std::sqrt(spread);
  std::printf("[axis] exact corners, wobble sigma %.5f deg drawn: tilt sigma %.5f, noise %.6f, wobble %.5f deg; "
              "angle sigma %.6f deg\n",
              sigma, fit.tilt_sigma_deg, fit.tilt_noise_deg, fit.tilt_wobble_deg, fit.angle_sigma_deg);
  EXPECT_NEAR(fit.tilt_sigma_deg, sigma, 0.15 * sigma);
  EXPECT_LT(fit.tilt_noise_deg, 0.05 * sigma);
  EXPECT_LT(fit.angle_sigma_deg, 0.1 * sigma);
  ASSERT_TRUE(fit.axis.tilt_sigma_deg.has_value());
  EXPECT_EQ(*fit.axis.tilt_sigma_deg, fit.tilt_sigma_deg);
}

// Noisy corners (what the simulator's demo capture gives), an exact table and one of the
// simulator's jitter: over captures, the spread is the board poses' noise and the jitter
// added in squares, and the noise estimate from the corners' residuals says which is which.
TEST(TurntableAxis, AngleSigmaOfNoisyCornersIsTheBoardsNoise) {
  const ScannerCalibration rig = demo_rig();
  for (const double jitter : {0.0, 0.002}) {
    double sigma = 0.0, noise = 0.0, jitter_estimate = 0.0, tilt = 0.0, tilt_noise = 0.0;
    const int trials = 30;
    for (int trial = 0; trial < trials; ++trial) {
      const TableViews table = table_views(rig, 7, jitter, 0.03, 100 + static_cast<unsigned>(trial));
      const AxisFit fit = fit_turntable_axis(table.views, table.solutions, rig, board());
      ASSERT_TRUE(fit.fitted) << fit.reason;
      sigma += fit.angle_sigma_deg * fit.angle_sigma_deg / trials;
      noise += fit.angle_noise_deg * fit.angle_noise_deg / trials;
      jitter_estimate += fit.angle_jitter_deg * fit.angle_jitter_deg / trials;
      tilt += fit.tilt_sigma_deg * fit.tilt_sigma_deg / trials;
      tilt_noise += fit.tilt_noise_deg * fit.tilt_noise_deg / trials;
      EXPECT_GE(fit.angle_sigma_deg, fit.angle_jitter_deg);
    }
    std::printf("[axis] 7 views, corners 0.03 px, jitter %.4f deg: RMS over %d captures of the angle sigma %.5f, "
                "its noise part %.5f, the jitter estimate %.5f deg; tilt sigma %.5f, its noise part %.5f\n",
                jitter, trials, std::sqrt(sigma), std::sqrt(noise), std::sqrt(jitter_estimate), std::sqrt(tilt),
                std::sqrt(tilt_noise));
    // Over captures the spread's mean square is the noise's plus the jitter's: within the
    // scatter of 30 captures × 5 degrees of freedom (±15 % at 1σ on the mean square).
    EXPECT_NEAR(sigma, noise + jitter * jitter, 0.3 * (noise + jitter * jitter));
    EXPECT_NEAR(tilt, tilt_noise, 0.3 * tilt_noise);  // no wobble: the tilts are the board's noise
  }
}

}  // namespace
}  // namespace sls::calib
