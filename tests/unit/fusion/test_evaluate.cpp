// The quality metrics of `sls eval` (sdk/eval/evaluate.h): nearest neighbours, statistics,
// C2C and edge C2C against the simulator's exact scenes, visibility, coverage, and the whole
// evaluation of a result folder against a small simulated recording.
#include "sdk/eval/evaluate.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/sim_recording.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"
#include "tests/support/test_support.h"

namespace sls::eval {
namespace {

constexpr double kUm = 1e-6;

// Runs `body`, which must throw sls::Error with `code` and a message containing `needle`.
template <typename Body>
void expect_error(const Body& body, ErrorCode code, const std::string& needle) {
  try {
    body();
    ADD_FAILURE() << "no error (expected one mentioning '" << needle << "')";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), code) << error.what();
    EXPECT_NE(std::string(error.what()).find(needle), std::string::npos) << error.what();
  }
}

std::vector<Eigen::Vector3d> positions(const std::vector<sim::SurfaceSample>& samples, double shift_m = 0.0) {
  std::vector<Eigen::Vector3d> out;
  for (const sim::SurfaceSample& s : samples) {
    // Through float, as a cloud read from PLY would be.
    out.push_back((s.position + shift_m * s.normal).cast<float>().cast<double>());
  }
  return out;
}

TEST(PointGrid, NearestAndWithinMatchBruteForce) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-0.005, 0.005);
  std::vector<Eigen::Vector3d> points(4000);
  for (Eigen::Vector3d& p : points) p = Eigen::Vector3d(coordinate(rng), coordinate(rng), coordinate(rng));
  const PointGrid grid(points, 4e-4);
  for (const double radius : {2e-4, 4e-4, 1.1e-3}) {
    for (int q = 0; q < 300; ++q) {
      const Eigen::Vector3d p(coordinate(rng), coordinate(rng), coordinate(rng));
      double best = HUGE_VAL;
      for (const Eigen::Vector3d& candidate : points) best = std::min(best, (candidate - p).norm());
      double distance = -1.0;
      const std::ptrdiff_t found = grid.nearest(p, radius, &distance);
      if (best <= radius) {
        ASSERT_GE(found, 0);
        EXPECT_DOUBLE_EQ(distance, best);
        EXPECT_TRUE(grid.any_within(p, radius));
      } else {
        EXPECT_EQ(found, -1);
        EXPECT_FALSE(grid.any_within(p, radius));
      }
    }
  }
  EXPECT_EQ(PointGrid({}, 1e-3).nearest(Eigen::Vector3d::Zero(), 1.0), -1);
  EXPECT_THROW(PointGrid(points, 0.0), Error);
  EXPECT_THROW(PointGrid({Eigen::Vector3d(1e4, 0.0, 0.0)}, 1e-3), Error);
}

TEST(DistanceStats, MeanRmsNearestRankPercentileAndMax) {
  std::vector<double> values;
  for (int n = 100; n >= 1; --n) values.push_back(n);
  const DistanceStats stats = distance_stats(values);
  EXPECT_EQ(stats.count, 100u);
  EXPECT_DOUBLE_EQ(stats.mean_m, 50.5);
  EXPECT_DOUBLE_EQ(stats.rms_m, std::sqrt(338350.0 / 100.0));  // sum of squares 1..100
  EXPECT_DOUBLE_EQ(stats.p95_m, 95.0);
  EXPECT_DOUBLE_EQ(stats.max_m, 100.0);
  EXPECT_EQ(distance_stats({}).count, 0u);
  EXPECT_DOUBLE_EQ(distance_stats({3.0}).p95_m, 3.0);
}

TEST(SurfaceErrors, ExactSamplesOfThePlaneAndSphereAreOnTheSurface) {
  for (const sim::Scene& scene : {sim::make_plane_scene(), sim::make_sphere_scene()}) {
    SCOPED_TRACE(scene.name());
    const std::vector<Eigen::Vector3d> exact = positions(scene.reference_samples(2e-4));
    ASSERT_GT(exact.size(), 1000u);
    const SurfaceErrors errors = surface_errors(exact, scene, 75e-6);
    EXPECT_EQ(errors.all.count, exact.size());
    EXPECT_LT(errors.all.mean_m, 0.01 * kUm);
    EXPECT_LT(errors.all.max_m, 0.01 * kUm);
    EXPECT_FALSE(errors.has_creases);
    EXPECT_EQ(errors.edge.count, 0u);
  }
}

TEST(SurfaceErrors, SamplesShiftedFiveMicronsAreFiveMicronsOff) {
  for (const sim::Scene& scene : {sim::make_plane_scene(), sim::make_sphere_scene()}) {
    SCOPED_TRACE(scene.name());
    for (const double sign : {1.0, -1.0}) {
      const SurfaceErrors errors = surface_errors(positions(scene.reference_samples(2e-4), sign * 5e-6), scene, 75e-6);
      EXPECT_NEAR(errors.all.mean_m, 5e-6, 0.01 * kUm);
      EXPECT_NEAR(errors.all.rms_m, 5e-6, 0.01 * kUm);
      EXPECT_NEAR(errors.all.p95_m, 5e-6, 0.01 * kUm);
    }
  }
}

TEST(SurfaceErrors, EdgeRegionIsThePointsNearTheKnurlsCreases) {
  const sim::Scene screw = sim::make_knurled_screw_scene();
  const std::vector<sim::SurfaceSample> samples = screw.reference_samples(1e-4, sim::ZRange{0.006, 0.008});
  const double band = 3.0 * 25e-6;
  const SurfaceErrors exact = surface_errors(positions(samples), screw, band);
  ASSERT_TRUE(exact.has_creases);
  std::size_t near = 0;
  for (const sim::SurfaceSample& s : samples) near += screw.distance_to_creases(s.position) <= band ? 1u : 0u;
  EXPECT_EQ(exact.edge.count, near);
  EXPECT_GT(exact.edge.count, samples.size() / 20);
  EXPECT_LT(exact.edge.count, samples.size() / 2);
  EXPECT_LT(exact.all.max_m, 0.01 * kUm);
  EXPECT_LT(exact.edge.max_m, 0.01 * kUm);
  // Pushed out 5 µm along the normals: 5 µm on the flanks; at a ridge (convex) still 5 µm,
  // in a groove (concave) the other flank can be nearer, so the edge mean is at most 5 µm.
  const SurfaceErrors shifted = surface_errors(positions(samples, 5e-6), screw, band);
  EXPECT_NEAR(shifted.all.p95_m, 5e-6, 0.01 * kUm);
  EXPECT_LE(shifted.edge.mean_m, 5e-6 + 0.01 * kUm);
  EXPECT_GT(shifted.edge.mean_m, 3.5e-6);
  std::printf("knurled screw band z 6..8 mm: %zu samples, %zu in the edge band; +5 um: mean %.4f um, edge mean %.4f um\n",
              samples.size(), exact.edge.count, shifted.all.mean_m / kUm, shifted.edge.mean_m / kUm);
}

TEST(Coverage, DenseSamplingCoversAllAndHalfOfItHalf) {
  const sim::Scene sphere = sim::make_sphere_scene();
  const std::vector<Eigen::Vector3d> reference = positions(sphere.reference_samples(5e-5));
  const double radius = 2.0 * 25e-6;
  const Coverage all = coverage(reference, nullptr, PointGrid(reference, radius), radius);
  EXPECT_EQ(all.considered, reference.size());
  EXPECT_EQ(all.covered, reference.size());
  EXPECT_DOUBLE_EQ(all.fraction(), 1.0);
  std::vector<Eigen::Vector3d> half;
  for (const Eigen::Vector3d& p : reference) {
    if (p.x() >= 0.0) half.push_back(p);
  }
  const Coverage partial = coverage(reference, nullptr, PointGrid(half, radius), radius);
  EXPECT_NEAR(partial.fraction(), 0.5, 0.01);
  std::printf("sphere, %zu reference points: coverage %.4f by all, %.4f by the x >= 0 half\n", reference.size(),
              all.fraction(), partial.fraction());
  // A mask counts only the points it selects.
  std::vector<std::uint8_t> mask(reference.size(), 0);
  for (std::size_t n = 0; n < reference.size(); ++n) mask[n] = reference[n].x() >= 0.001 ? 1 : 0;
  EXPECT_DOUBLE_EQ(coverage(reference, &mask, PointGrid(half, radius), radius).fraction(), 1.0);
}

// A camera 10 cm above the sheet z = 0, looking straight down at it.
TEST(VisibilityMask, PointsOnValidUnoccludedPixelsFacingTheCamera) {
  CameraIntrinsics camera;
  camera.width = 200;
  camera.height = 200;
  camera.fx = camera.fy = 2000.0;  // 50 µm per pixel at 10 cm
  camera.cx = camera.cy = 99.5;
  const Pose T_object_camera(Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal().toDenseMatrix(), Eigen::Vector3d(0.0, 0.0, 0.1));
  // pixel u = 99.5 + 20000 x, v = 99.5 - 20000 y.
  Image32f depth(200, 200, 0.1f);
  Image8u valid(200, 200, 0);
  for (int y = 0; y < 200; ++y) {
    for (int x = 0; x < 100; ++x) valid(x, y) = 255;  // lit only on the left (x < 0)
  }
  for (int y = 0; y < 50; ++y) {
    for (int x = 0; x < 50; ++x) depth(x, y) = 0.05f;  // something in front, top left (x, y < -2.5 mm)
  }
  const std::vector<Eigen::Vector3d> points = {
      {-0.002, -0.001, 0.0},   // lit, seen
      {0.002, -0.001, 0.0},    // unlit half
      {-0.003, 0.003, 0.0},    // behind the occluder
      {-0.002, -0.001, 0.0},   // as the first, but facing away
      {-0.020, 0.0, 0.0},      // outside the image
  };
  const std::vector<Eigen::Vector3d> normals = {
      Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitZ(),
      Eigen::Vector3d::UnitZ()};
  VisibilityMask mask(points, normals);
  mask.add_frame(camera, T_object_camera, depth, valid, 50e-6);
  EXPECT_EQ(mask.visible(), (std::vector<std::uint8_t>{1, 0, 0, 0, 0}));
  EXPECT_EQ(mask.visible_count(), 1u);
  EXPECT_THROW(mask.add_frame(camera, T_object_camera, Image32f(10, 10), valid, 50e-6), Error);
}

// ---------------------------------------------------------------------------------------
// Trajectory errors on synthetic turntable trajectories.

// A camera 10 cm from the axis, 2 cm up, looking roughly at the object, turned about the
// object's z axis: one revolution in `frames` steps (the last is one step short of the first).
std::vector<StampedPose> turntable_truth(int frames) {
  const Pose T_object_camera0(Eigen::Matrix3d(Eigen::AngleAxisd(-M_PI / 2.0, Eigen::Vector3d::UnitY()) *
                                              Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX())),
                              Eigen::Vector3d(0.1, 0.0, 0.02));
  std::vector<StampedPose> poses;
  for (int i = 0; i < frames; ++i) {
    const double angle = 2.0 * M_PI * i / frames;
    const Pose turn(Eigen::Matrix3d(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ())), Eigen::Vector3d::Zero());
    poses.push_back({0.5 * i, turn * T_object_camera0});
  }
  return poses;
}

// Drift that grows linearly with the frame, in the camera frame (right-multiplied): the
// relative motion first -> last is then off by exactly the last frame's drift.
std::vector<StampedPose> with_drift(std::vector<StampedPose> poses, const Eigen::Vector3d& step_m,
                                    double step_rad) {
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const double n = static_cast<double>(i);
    const Pose drift(Eigen::Matrix3d(Eigen::AngleAxisd(n * step_rad, Eigen::Vector3d(1.0, 2.0, 2.0).normalized())),
                     n * step_m);
    poses[i].T_world_camera = poses[i].T_world_camera * drift;
  }
  return poses;
}

TEST(TrajectoryErrors, KnownDriftGivesTheLoopClosureError) {
  const std::vector<StampedPose> truth = turntable_truth(36);
  // Per frame 1 um, 4/3 um along x, y and 0.001 deg: after 35 steps 35 * 5/3 um and 0.035 deg.
  const double step_rad = 0.001 * M_PI / 180.0;
  const std::vector<StampedPose> estimated = with_drift(truth, Eigen::Vector3d(1e-6, 4e-6 / 3.0, 0.0), step_rad);
  std::string why;
  const std::optional<TrajectoryErrors> errors = trajectory_errors(estimated, truth, &why);
  ASSERT_TRUE(errors) << why;
  EXPECT_EQ(errors->matched_frames, 36u);
  EXPECT_EQ(errors->unmatched_frames, 0u);
  EXPECT_NEAR(errors->loop_closure_error_m, 35.0 * 5e-6 / 3.0, 1e-12);
  EXPECT_NEAR(errors->loop_closure_error_rad, 35.0 * step_rad, 1e-12);
  EXPECT_DOUBLE_EQ(errors->first_timestamp_s, 0.0);
  EXPECT_DOUBLE_EQ(errors->last_timestamp_s, 17.5);
  // The drift moves positions too (the rotation swings the camera about its own centre only,
  // so just the translations count): ATE is positive but below the largest offset.
  EXPECT_GT(errors->ate_rmse_m, 1e-6);
  EXPECT_LE(errors->ate_max_m, 35.0 * 5e-6 / 3.0 + 1e-12);
  // The exact trajectory has neither error.
  const std::optional<TrajectoryErrors> exact = trajectory_errors(truth, truth);
  ASSERT_TRUE(exact);
  EXPECT_LT(exact->ate_rmse_m, 1e-12);
  EXPECT_LT(exact->loop_closure_error_m, 1e-12);
  EXPECT_LT(exact->loop_closure_error_rad, 1e-9);
}

TEST(TrajectoryErrors, AlignmentRemovesAGlobalRigidOffsetExactly) {
  const std::vector<StampedPose> truth = turntable_truth(24);
  // Positions off by +-10 um along the axis, alternating: the best alignment is the identity
  // (the offsets cancel in the centroid and the cross-covariance), so ATE is exactly 10 um.
  std::vector<StampedPose> estimated = truth;
  for (std::size_t i = 0; i < estimated.size(); ++i) {
    const Pose offset(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, i % 2 == 0 ? 10e-6 : -10e-6));
    estimated[i].T_world_camera = offset * estimated[i].T_world_camera;
  }
  // The estimate in another world frame (a tracker's: the first camera's).
  const Pose T_world_object(Eigen::Matrix3d(Eigen::AngleAxisd(2.0, Eigen::Vector3d(0.3, -0.5, 0.8).normalized())),
                            Eigen::Vector3d(0.03, -0.2, 0.11));
  for (const bool offsets : {false, true}) {
    SCOPED_TRACE(offsets ? "with +-10 um offsets" : "exact");
    std::vector<StampedPose> moved = offsets ? estimated : truth;
    for (StampedPose& pose : moved) pose.T_world_camera = T_world_object * pose.T_world_camera;
    const std::optional<TrajectoryErrors> errors = trajectory_errors(moved, truth);
    ASSERT_TRUE(errors);
    EXPECT_NEAR(errors->ate_rmse_m, offsets ? 10e-6 : 0.0, 1e-10);
    EXPECT_NEAR(errors->ate_max_m, offsets ? 10e-6 : 0.0, 1e-10);
    EXPECT_TRUE(errors->T_truth_estimate.is_approx(T_world_object.inverse(), 1e-8));
    // The last frame has an odd index: its offset differs from the first's by 20 um.
    EXPECT_NEAR(errors->loop_closure_error_m, offsets ? 20e-6 : 0.0, 1e-10);
    // The truth moved by the alignment lies on the estimate.
    const std::vector<StampedPose> aligned = truth_in_estimate_frame(truth, *errors);
    for (std::size_t i = 0; i < truth.size(); ++i) {
      EXPECT_LT((aligned[i].T_world_camera.translation() - moved[i].T_world_camera.translation()).norm(), 10e-6 + 1e-9);
    }
  }
}

TEST(TrajectoryErrors, FramesAreMatchedByTimestampWhateverTheOrderAndGaps) {
  const std::vector<StampedPose> truth = turntable_truth(20);
  const double step_rad = 0.002 * M_PI / 180.0;
  const std::vector<StampedPose> drifted = with_drift(truth, Eigen::Vector3d(0.0, 0.0, 2e-6), step_rad);
  // Lost frames 3, 7 and the last one (19); shuffled; timestamps off by a nanosecond; one
  // pose at a time the recording never had.
  std::vector<StampedPose> estimated;
  for (std::size_t i = 0; i < drifted.size(); ++i) {
    if (i == 3 || i == 7 || i == 19) continue;
    StampedPose pose = drifted[i];
    pose.timestamp_s += i % 2 == 0 ? 1e-9 : -1e-9;
    estimated.push_back(pose);
  }
  estimated.push_back({1000.0, Pose::identity()});
  std::mt19937 rng(3);
  std::shuffle(estimated.begin(), estimated.end(), rng);
  // The truth too may come unsorted and may hold frames the estimate lacks.
  std::vector<StampedPose> truth_shuffled = truth;
  std::shuffle(truth_shuffled.begin(), truth_shuffled.end(), rng);

  const std::optional<TrajectoryErrors> errors = trajectory_errors(estimated, truth_shuffled);
  ASSERT_TRUE(errors);
  EXPECT_EQ(errors->matched_frames, 17u);
  EXPECT_EQ(errors->unmatched_frames, 1u);
  EXPECT_DOUBLE_EQ(errors->first_timestamp_s, 1e-9);
  EXPECT_NEAR(errors->last_timestamp_s, 9.0, 1e-8);  // frame 18
  EXPECT_NEAR(errors->loop_closure_error_m, 18.0 * 2e-6, 1e-12);
  EXPECT_NEAR(errors->loop_closure_error_rad, 18.0 * step_rad, 1e-12);

  // Against itself, whatever the order: no error.
  const std::optional<TrajectoryErrors> same = trajectory_errors(estimated, estimated);
  ASSERT_TRUE(same);
  EXPECT_LT(same->ate_rmse_m, 1e-12);

  // Fewer than two matches: no figures, and why.
  std::string why;
  EXPECT_FALSE(trajectory_errors({truth[0]}, truth, &why));
  EXPECT_NE(why.find("1 of the 1"), std::string::npos) << why;
  EXPECT_FALSE(trajectory_errors({{5000.0, Pose()}, {5001.0, Pose()}}, truth, &why));
  EXPECT_NE(why.find("0 of the 2"), std::string::npos) << why;
}

// ---------------------------------------------------------------------------------------
// A result folder against a small simulated recording (depth mode, four views of the sphere).

class EvaluateResult : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    directory_ = new test::TemporaryDirectory();
    sim::SimRecordingOptions options;
    options.object = "sphere";
    options.depth_mode = true;
    options.rig.preset = "ci";
    options.rig.frames = 4;
    options.reference_spacing_m = 100e-6;
    sim::write_sim_recording(recording(), options, Device::cpu(), {});
  }
  static void TearDownTestSuite() {
    delete directory_;
    directory_ = nullptr;
  }
  static std::string recording() { return directory_->file("recording"); }
  static std::string truth(const std::string& name) { return recording() + "/groundtruth/" + name; }

  // A result folder holding `cloud` and a report.json with the voxel size.
  std::string result(const std::string& name, const PointCloud& cloud, bool with_report = true) {
    const std::string folder = directory_->file(name);
    create_directories(folder);
    write_ply(folder + "/cloud.ply", cloud);
    if (with_report) write_file_atomic(folder + "/report.json", R"({"voxel_size_m": 5e-05})");
    return folder;
  }

  static test::TemporaryDirectory* directory_;
};

test::TemporaryDirectory* EvaluateResult::directory_ = nullptr;

TEST_F(EvaluateResult, TheReferenceItselfIsExactAndCoversWhatWasSeen) {
  const PointCloud reference = read_ply_cloud(truth("reference.ply"));
  const EvalReport report = evaluate_result(result("exact", reference), recording(), {});
  EXPECT_EQ(report.scene_name, "sphere");
  EXPECT_DOUBLE_EQ(report.voxel_size_m, 5e-5);
  EXPECT_EQ(report.voxel_size_source, "report.json");
  EXPECT_EQ(report.cloud_points, reference.size());
  EXPECT_LT(report.cloud.all.mean_m, 0.01 * kUm);
  EXPECT_LT(report.cloud.all.p95_m, 0.01 * kUm);
  EXPECT_EQ(report.coverage_basis, "visible");
  EXPECT_EQ(report.frames_checked, 4u);
  EXPECT_EQ(report.alignment, "none");
  // Four views around the axis see the sphere's side, not its poles.
  EXPECT_GT(report.coverage.considered, reference.size() / 4);
  EXPECT_LT(report.coverage.considered, reference.size());
  EXPECT_DOUBLE_EQ(report.coverage.fraction(), 1.0);
  EXPECT_FALSE(report.trajectory);
  EXPECT_NE(report.trajectory_note.find("trajectory.txt"), std::string::npos) << report.trajectory_note;
  EXPECT_TRUE(report.cloud_point_errors_m.empty());
  std::printf("sphere recording: %zu reference points, %zu seen by 4 frames\n", reference.size(),
              report.coverage.considered);
}

TEST_F(EvaluateResult, HalfTheSurfaceCoversAboutHalf) {
  PointCloud half;
  for (const Eigen::Vector3f& p : read_ply_cloud(truth("reference.ply")).positions) {
    if (p.x() >= 0.0f) half.positions.push_back(p);
  }
  const EvalReport report = evaluate_result(result("half", half), recording(), {});
  EXPECT_GT(report.coverage.fraction(), 0.3);
  EXPECT_LT(report.coverage.fraction(), 0.7);
  EXPECT_LT(report.cloud.all.max_m, 0.01 * kUm);
}

TEST_F(EvaluateResult, ATrackedResultIsAlignedByItsFirstPose) {
  // As a tracker that starts at the identity would write it: world = the first camera's frame.
  const std::vector<StampedPose> truth_poses = read_tum_trajectory(truth("trajectory.txt"));
  const Pose T_world_object = truth_poses.front().T_world_camera.inverse();
  PointCloud cloud = read_ply_cloud(truth("reference.ply"));
  for (Eigen::Vector3f& p : cloud.positions) p = (T_world_object * p.cast<double>()).cast<float>();
  std::vector<StampedPose> estimated = truth_poses;
  for (StampedPose& pose : estimated) pose.T_world_camera = T_world_object * pose.T_world_camera;
  const std::string folder = result("tracked", cloud);
  write_tum_trajectory(folder + "/trajectory.txt", estimated);
  const EvalReport aligned = evaluate_result(folder, recording(), {});
  EXPECT_EQ(aligned.alignment, "first-pose");
  EXPECT_LT(aligned.cloud.all.mean_m, 0.01 * kUm);
  ASSERT_TRUE(aligned.trajectory) << aligned.trajectory_note;
  EXPECT_EQ(aligned.trajectory->matched_frames, truth_poses.size());
  EXPECT_LT(aligned.trajectory->ate_rmse_m, 1e-9);
  EXPECT_LT(aligned.trajectory->loop_closure_error_m, 1e-9);
  EvalOptions no_align;
  no_align.align_first_pose = false;
  EXPECT_GT(evaluate_result(folder, recording(), no_align).cloud.all.mean_m, 1e-3);
}

// A result in a frame off by a small rigid motion (as a calibration whose principal point is
// traded for a turn of the camera frame gives): registration onto the exact surface finds the
// shape exact again. Moved 150 um across and turned 0.1 deg about an axis through a point off
// the sphere's centre (a turn about the centre alone would not show on a sphere).
TEST_F(EvaluateResult, RegistrationOntoTheSurfaceRemovesARigidOffset) {
  PointCloud cloud = read_ply_cloud(truth("reference.ply"));
  const Eigen::Vector3d pivot(0.004, 0.0, 0.0);
  const Eigen::Matrix3d turn(Eigen::AngleAxisd(0.1 * M_PI / 180.0, Eigen::Vector3d(0.3, 0.2, 1.0).normalized()));
  const Pose moved(turn, pivot - turn * pivot + Eigen::Vector3d(150e-6, -50e-6, 80e-6));
  for (Eigen::Vector3f& p : cloud.positions) p = (moved * p.cast<double>()).cast<float>();
  const std::string folder = result("moved", cloud);
  const EvalReport as_written = evaluate_result(folder, recording(), {});
  EXPECT_GT(as_written.cloud.all.mean_m, 50.0 * kUm);
  EvalOptions options;
  options.register_to_surface = true;
  const EvalReport registered = evaluate_result(folder, recording(), options);
  EXPECT_EQ(registered.alignment, "registered");
  EXPECT_LT(registered.cloud.all.mean_m, 0.05 * kUm);
  EXPECT_LT(registered.cloud.all.max_m, 0.5 * kUm);
}

TEST_F(EvaluateResult, PointErrorsAreKeptOnRequestInTheCloudsOrder) {
  PointCloud cloud = read_ply_cloud(truth("reference.ply"));
  // Every tenth point pushed 20 um outwards (the sphere is centred on the origin).
  for (std::size_t n = 0; n < cloud.size(); n += 10) {
    cloud.positions[n] += 20e-6f * cloud.positions[n].normalized();
  }
  EvalOptions options;
  options.keep_point_errors = true;
  const EvalReport report = evaluate_result(result("point-errors", cloud), recording(), options);
  ASSERT_EQ(report.cloud_point_errors_m.size(), cloud.size());
  for (std::size_t n = 0; n < cloud.size(); ++n) {
    EXPECT_NEAR(report.cloud_point_errors_m[n], n % 10 == 0 ? 20e-6 : 0.0, 0.05 * kUm) << n;
  }
  EXPECT_NEAR(*std::max_element(report.cloud_point_errors_m.begin(), report.cloud_point_errors_m.end()),
              report.cloud.all.max_m, 1e-9);
}

TEST_F(EvaluateResult, VoxelSizeFromTheOptionWhenTheReportHasNone) {
  PointCloud cloud = read_ply_cloud(truth("reference.ply"));
  const std::string folder = result("no-report", cloud, false);
  expect_error([&] { evaluate_result(folder, recording(), {}); }, ErrorCode::kInvalidArgument, "--voxel-um");
  EvalOptions options;
  options.voxel_size_m = 20e-6;
  const EvalReport report = evaluate_result(folder, recording(), options);
  EXPECT_EQ(report.voxel_size_source, "option");
  EXPECT_DOUBLE_EQ(report.coverage_radius_m, 40e-6);
}

TEST_F(EvaluateResult, MissingFilesAndRecordingsWithoutTruthAreClearErrors) {
  const std::string empty = directory_->file("empty");
  create_directories(empty);
  expect_error([&] { evaluate_result(empty, recording(), {}); }, ErrorCode::kNotFound, "cloud.ply");
  const std::string exact = result("exact2", read_ply_cloud(truth("reference.ply")));
  expect_error([&] { evaluate_result(exact, directory_->file("no-such-recording"), {}); }, ErrorCode::kNotFound,
               "no-such-recording");

  // A recording without ground truth (a real scan).
  RecordingInfo info;
  info.camera = {64, 48, 8};
  const std::string plain = directory_->file("plain");
  RecordingWriter::create(plain, info, std::nullopt).close();
  expect_error([&] { evaluate_result(exact, plain, {}); }, ErrorCode::kInvalidArgument, "no ground truth");
}

}  // namespace
}  // namespace sls::eval
