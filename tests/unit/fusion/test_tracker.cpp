// The ICP tracker against exact ground truth (tests/unit/fusion/tracker_test_scenes.h): a
// model volume filled with the closed-form truncated distance of a plane with spherical caps,
// raycast from T_world_model; live depth maps cast exactly from T_true = T_world_model ·
// motion. The registration must land the live surface on the model to a small fraction of
// a voxel; a plane leaves three directions degenerate; unrelated geometry is lost; bad input
// is a clear error. Also the per-pixel pyramid and normal code of track_shared.h, and the
// crease test on a grooved screw. The photometric term is in test_tracker_photometric.cpp.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/scene.h"
#include "fusion/track_shared.h"
#include "fusion/tracker.h"
#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"
#include "tests/unit/fusion/crease_test_scene.h"
#include "tests/unit/fusion/photometric_test_scenes.h"
#include "tests/unit/fusion/tracker_test_scenes.h"

namespace sls::fusion {
namespace {

using test::bumpy_model;
using test::degrees;
using test::kVoxel;
using test::Model;
using test::test_motion;

const Model& plane_model() {
  static const Model model(test::plane_scene());
  return model;
}

void print(const char* name, const TrackingResult& r, const Pose& truth, const test::SurfaceError& e) {
  const Pose error = truth.inverse() * r.T_world_camera;
  std::printf("[tracker] %s: lost=%d %s| |dt| %.3f um, angle %.5f deg, surface RMS %.3f um max %.3f um; "
              "%zu/%zu inliers, residual RMS %.3f um, %d degenerate, condition %.3g, %d iterations\n",
              name, r.lost ? 1 : 0, r.reason.empty() ? "" : (r.reason + " ").c_str(),
              (r.T_world_camera.translation() - truth.translation()).norm() * 1e6, degrees(error.angle_rad()),
              e.rms_m * 1e6, e.max_m * 1e6, r.inliers, r.live_pixels, r.residual_rms_m * 1e6,
              r.degenerate_directions, r.condition, r.iterations);
}

// The bound on the registration error: the model is the closed-form TSDF sampled at 50 um
// voxels and read back by trilinear interpolation and a regula-falsi raycast, which places
// the surface within a few hundredths of a voxel (caps of 0.7 mm radius bend over a voxel by
// h²/8R = 0.4 um); the association is to the nearest model pixel (37 um) on the model's
// tangent plane. So the live surface must land within 0.05 voxel (2.5 um) of the truth.
constexpr double kSurfaceBound = 0.05 * kVoxel;

TEST(Tracker, RegistersAKnownMotion) {
  const Model& m = bumpy_model();
  const Pose truth = m.T_world_model * test_motion();
  const Image32f live = test::exact_depth(m.scene, m.camera, truth);
  Tracker tracker(Device::cpu(), m.camera);
  const Pose guess = m.T_world_model;
  const TrackingResult r = tracker.track(live, m.raycast, m.T_world_model, guess);
  const test::SurfaceError before = test::surface_error(live, m.camera, guess, truth);
  const test::SurfaceError after = test::surface_error(live, m.camera, r.T_world_camera, truth);
  std::printf("[tracker] motion: %.3f mm, %.3f deg; surface moved %.1f um RMS (max %.1f um)\n",
              test_motion().translation().norm() * 1e3, degrees(test_motion().angle_rad()), before.rms_m * 1e6,
              before.max_m * 1e6);
  print("bumps", r, truth, after);
  EXPECT_FALSE(r.lost) << r.reason;
  EXPECT_TRUE(r.reason.empty());
  EXPECT_LT(after.rms_m, kSurfaceBound);
  EXPECT_LT(after.max_m, 2.0 * kSurfaceBound);
  // The same in pose terms: translation of the camera and its rotation. A rotation error ε
  // about a point of the surface moves the camera centre by 0.1 m · ε, so the bound on |dt|
  // follows from the surface bound over the field (±6 mm): 0.1 / 6e-3 · 2.5 um ≈ 40 um would
  // be the worst coupling; the measured figures sit far inside these bounds.
  const Pose error = truth.inverse() * r.T_world_camera;
  EXPECT_LT((r.T_world_camera.translation() - truth.translation()).norm(), 10e-6);
  EXPECT_LT(degrees(error.angle_rad()), 0.002);
  EXPECT_EQ(r.degenerate_directions, 0);
  EXPECT_GT(r.inlier_fraction, 0.8);
  EXPECT_LT(r.residual_rms_m, 0.02 * kVoxel);
  EXPECT_GT(r.iterations, 0);
  EXPECT_TRUE(std::isfinite(r.condition));
  EXPECT_EQ(r.live_pixels, static_cast<std::size_t>(m.camera.width * m.camera.height));
}

// A live camera wider than max_model_width: ICP runs on the live map halved (160 x 120)
// against a model raycast at that size, and still registers within the same surface bound.
// The live map's bottom 24 rows are empty, so the halved map has depth in its top 108 rows.
TEST(Tracker, HalvedLiveMapAgainstAHalfSizeModel) {
  const Model& m = bumpy_model();
  const Pose truth = m.T_world_model * test_motion();
  Image32f live = test::exact_depth(m.scene, m.camera, truth);
  for (int y = m.camera.height - 24; y < m.camera.height; ++y) {
    for (int x = 0; x < m.camera.width; ++x) live(x, y) = 0.0f;
  }
  TrackingOptions options;
  options.max_model_width = m.camera.width / 2;
  Tracker tracker(Device::cpu(), m.camera, options);
  ASSERT_EQ(tracker.model_camera().width, m.camera.width / 2);
  Raycaster raycaster(Device::cpu(), tracker.model_camera(), Model::raycast_options());
  const RaycastResult model = raycaster.raycast(m.volume, m.T_world_model);
  const TrackingResult r = tracker.track(live, model, m.T_world_model, m.T_world_model);
  const test::SurfaceError after = test::surface_error(live, m.camera, r.T_world_camera, truth);
  print("halved", r, truth, after);
  EXPECT_FALSE(r.lost) << r.reason;
  EXPECT_LT(after.rms_m, kSurfaceBound);
  EXPECT_EQ(r.live_pixels, static_cast<std::size_t>(m.camera.width / 2 * (m.camera.height - 24) / 2));
  // The full-size model is the wrong size for this tracker: a clear error.
  EXPECT_THROW(tracker.track(live, m.raycast, m.T_world_model, m.T_world_model), Error);
}

// Depth noise of σ = 5 um (a seventh of a pixel footprint): the live normals tilt by
// ~atan(σ√2 / 2 px) ≈ 5° rms, most pixels still pass the 30° test, and the registration
// averages the noise over ~10⁴ pixels: σ / √N ≈ 0.05 um times the geometry's lever (the caps'
// flanks carry the lateral directions), well inside the noise-free bound.
TEST(Tracker, NoisyLiveDepthStillRegisters) {
  const Model& m = bumpy_model();
  const Pose truth = m.T_world_model * test_motion();
  const Image32f exact = test::exact_depth(m.scene, m.camera, truth);
  Image32f live = exact;
  std::mt19937 generator(7);
  std::normal_distribution<double> noise(0.0, 5e-6);
  for (std::size_t i = 0; i < live.pixel_count(); ++i) {
    if (live.data()[i] > 0.0f) live.data()[i] += static_cast<float>(noise(generator));
  }
  Tracker tracker(Device::cpu(), m.camera);
  const TrackingResult r = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model);
  const test::SurfaceError e = test::surface_error(exact, m.camera, r.T_world_camera, truth);
  print("noise 5 um", r, truth, e);
  EXPECT_FALSE(r.lost) << r.reason;
  EXPECT_GT(r.inlier_fraction, 0.5);
  EXPECT_LT(e.rms_m, kSurfaceBound);
  EXPECT_NEAR(r.residual_rms_m, 5e-6, 1.5e-6);  // the noise, seen along the normals
}

// Robust weights (TrackingOptions::tukey_rms_factor, huber_rms_factor): every 4th pixel of
// every 4th row of the left third sits 120 µm behind the surface (a decoder's misplaced
// pixels, within the 200 µm association distance), the rest is exact. Sparse, so the good
// pixels around them keep their live normals (a coarse level blends them into a small bias).
// Least squares follows them; Huber's bounds their pull but still moves the pose; Tukey's
// biweight (the default) weighs them 0 once a reduction has measured the residuals' scale.
TEST(Tracker, TukeyWeightsIgnoreScatteredOutliers) {
  const Model& m = bumpy_model();
  const Pose truth = m.T_world_model * test_motion();
  const Image32f exact = test::exact_depth(m.scene, m.camera, truth);
  Image32f live = exact;
  for (int y = 0; y < live.height(); ++y) {
    for (int x = 0; x < live.width() / 3; ++x) {
      if (x % 4 == 0 && y % 4 == 0 && live(x, y) > 0.0f) live(x, y) += 120e-6f;
    }
  }
  auto run = [&](double tukey, double huber, const char* name) {
    TrackingOptions options;
    options.tukey_rms_factor = tukey;
    options.huber_rms_factor = huber;
    const TrackingResult r = Tracker(Device::cpu(), m.camera, options)
                                 .track(live, m.raycast, m.T_world_model, m.T_world_model);
    const test::SurfaceError e = test::surface_error(exact, m.camera, r.T_world_camera, truth);
    print(name, r, truth, e);
    EXPECT_FALSE(r.lost) << name << ": " << r.reason;
    return e.rms_m;
  };
  const double plain = run(0.0, 0.0, "outliers, least squares");
  const double huber = run(0.0, 2.0, "outliers, Huber");
  const double tukey = run(TrackingOptions{}.tukey_rms_factor, 2.0, "outliers, Tukey");
  EXPECT_GT(plain, kSurfaceBound);  // the outliers' pull is real
  EXPECT_LT(huber, plain);
  EXPECT_LT(tukey, kSurfaceBound);
  EXPECT_LT(tukey, 0.25 * huber);
}

TEST(TrackShared, RobustWeights) {
  EXPECT_EQ(robust_weight(5e-6f, 0.0f, 0.0f), 1.0f);                     // none
  EXPECT_EQ(robust_weight(5e-6f, 10e-6f, 0.0f), 1.0f);                   // Huber, within
  EXPECT_FLOAT_EQ(robust_weight(-40e-6f, 10e-6f, 0.0f), 0.25f);          // Huber, beyond
  EXPECT_FLOAT_EQ(robust_weight(-5e-6f, 10e-6f, 10e-6f), 0.5625f);       // Tukey: (1 - 0.25)²
  EXPECT_EQ(robust_weight(10e-6f, 10e-6f, 10e-6f), 0.0f);                // Tukey, at c and beyond
  EXPECT_EQ(robust_weight(std::nanf(""), 0.0f, 10e-6f), 0.0f);
}

TEST(Tracker, StaysPutWhenTheGuessIsRightAndIsDeterministic) {
  const Model& m = bumpy_model();
  const Image32f live = test::exact_depth(m.scene, m.camera, m.T_world_model);
  Tracker tracker(Device::cpu(), m.camera);
  const TrackingResult a = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model);
  const TrackingResult b = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model);
  const test::SurfaceError e = test::surface_error(live, m.camera, a.T_world_camera, m.T_world_model);
  print("no motion", a, m.T_world_model, e);
  EXPECT_FALSE(a.lost) << a.reason;
  EXPECT_LT(e.rms_m, kSurfaceBound);
  EXPECT_TRUE(test::same_pose(a.T_world_camera, b.T_world_camera));
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_EQ(a.iterations, b.iterations);
}

// Measurement weights (TrackingOptions::weight_by_confidence): a band of a third of the
// live pixels carries a systematic 20 µm depth error (a decoder's bias where it is least
// sure) and confidence 0.01, the rest confidence 1. Unweighted (robust weights alone), the
// band pulls the pose off; weighted by confidence it counts 1 % as much, and the trusted
// pixels land on the truth. All-ones confidence changes nothing; weights 0, negative or NaN leave the
// pixel out.
TEST(Tracker, ConfidenceWeightsDiscountTheDecodersDoubtfulPixels) {
  const Model& m = bumpy_model();
  const Pose truth = m.T_world_model * test_motion();
  const test::BiasedBand band = test::biased_band(test::exact_depth(m.scene, m.camera, truth), 20e-6f, 0.01f);
  const Image32f& live = band.live;
  const Image32f& confidence = band.confidence;
  const Image32f& trusted = band.trusted;
  Tracker tracker(Device::cpu(), m.camera);
  const TrackingResult equal = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model);
  const TrackingResult weighted =
      tracker.track(live, m.raycast, m.T_world_model, m.T_world_model, nullptr, &confidence);
  const test::SurfaceError e_equal = test::surface_error(trusted, m.camera, equal.T_world_camera, truth);
  const test::SurfaceError e_weighted = test::surface_error(trusted, m.camera, weighted.T_world_camera, truth);
  print("biased band, equal weights", equal, truth, e_equal);
  print("biased band, confidence weights", weighted, truth, e_weighted);
  ASSERT_FALSE(equal.lost) << equal.reason;
  ASSERT_FALSE(weighted.lost) << weighted.reason;
  EXPECT_GT(e_equal.rms_m, 3e-6);  // the band's pull is real: a sixth of its bias and more
  EXPECT_LT(e_weighted.rms_m, kSurfaceBound);
  EXPECT_LT(e_weighted.rms_m, 0.25 * e_equal.rms_m);

  // Weighting off: the confidence map is ignored.
  TrackingOptions off;
  off.weight_by_confidence = false;
  Tracker unweighted(Device::cpu(), m.camera, off);
  const TrackingResult ignored =
      unweighted.track(live, m.raycast, m.T_world_model, m.T_world_model, nullptr, &confidence);
  EXPECT_TRUE(test::same_pose(ignored.T_world_camera, equal.T_world_camera));

  // All ones: the same result as no map at all.
  Image32f ones(m.camera.width, m.camera.height);
  for (std::size_t i = 0; i < ones.pixel_count(); ++i) ones.data()[i] = 1.0f;
  const TrackingResult with_ones = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model, nullptr, &ones);
  EXPECT_TRUE(test::same_pose(with_ones.T_world_camera, equal.T_world_camera));
  EXPECT_EQ(with_ones.inliers, equal.inliers);

  // Weights that are no measurement (0, negative, NaN, infinite) leave their pixels out: the
  // band gone, the rest registers on the truth.
  Image32f broken = confidence;
  for (int y = 0; y < m.camera.height; ++y) {
    for (int x = 0; x < m.camera.width / 3; ++x) {
      const float values[4] = {0.0f, -1.0f, std::nanf(""), INFINITY};
      broken(x, y) = values[(x + y) % 4];
    }
  }
  const TrackingResult left_out =
      tracker.track(live, m.raycast, m.T_world_model, m.T_world_model, nullptr, &broken);
  const test::SurfaceError e_left_out = test::surface_error(trusted, m.camera, left_out.T_world_camera, truth);
  print("band left out", left_out, truth, e_left_out);
  ASSERT_FALSE(left_out.lost) << left_out.reason;
  EXPECT_LT(e_left_out.rms_m, kSurfaceBound);
  EXPECT_LT(left_out.inliers, weighted.inliers * 3 / 4);

  // A map of another size is a clear error.
  const Image32f small(m.camera.width / 2, m.camera.height);
  EXPECT_THROW(tracker.track(live, m.raycast, m.T_world_model, m.T_world_model, nullptr, &small), Error);
}

// A plane seen face on: sliding in it and turning about its normal change nothing, so three
// directions are degenerate and keep the guess; depth and tilt are registered.
TEST(Tracker, PlaneLeavesThreeDirectionsDegenerate) {
  const Model& m = plane_model();
  // Constrained motion (depth and tilt) plus motion along the degenerate directions.
  const Pose motion = test::camera_motion(Eigen::Vector3d(0.1e-3, 0.05e-3, 0.15e-3), Eigen::Vector3d(1.0, -0.5, 0.2), 0.8);
  const Pose truth = m.T_world_model * motion;
  const Image32f live = test::exact_depth(m.scene, m.camera, truth);
  Tracker tracker(Device::cpu(), m.camera);
  const TrackingResult r = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model);
  print("plane", r, truth, test::surface_error(live, m.camera, r.T_world_camera, truth));
  EXPECT_FALSE(r.lost) << r.reason;
  EXPECT_EQ(r.degenerate_directions, 3);
  EXPECT_GT(r.condition, 1e5);
  // The plane z = plane_z (world) seen from the estimate equals the one seen from the truth:
  // its normal and distance in the camera frame.
  auto plane_in_camera = [&](const Pose& T_world_camera) {
    const Eigen::Vector3d normal = T_world_camera.rotation().transpose() * Eigen::Vector3d::UnitZ();
    const double distance = m.scene.plane_z - T_world_camera.translation().z();
    return std::make_pair(normal, distance);
  };
  const auto [n_est, d_est] = plane_in_camera(r.T_world_camera);
  const auto [n_true, d_true] = plane_in_camera(truth);
  const double angle = std::acos(std::min(1.0, n_est.dot(n_true)));
  std::printf("[tracker] plane: normal off by %.5f deg, distance by %.3f um\n", degrees(angle), (d_est - d_true) * 1e6);
  EXPECT_LT(degrees(angle), 0.002);
  EXPECT_LT(std::fabs(d_est - d_true), 0.02 * kVoxel);  // a plane is exact in the model
  // The degenerate directions kept the guess: the camera did not turn about the plane's
  // normal (the guess has the model's roll).
  const Pose correction = m.T_world_model.inverse() * r.T_world_camera;
  const Eigen::Vector3d rotation_vector = correction.log().tail<3>();
  const Eigen::Vector3d normal_in_camera = m.T_world_model.rotation().transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(std::fabs(rotation_vector.dot(normal_in_camera)), 1e-6);
}

TEST(Tracker, UnrelatedGeometryIsLost) {
  const Model& m = bumpy_model();
  // A plane 20 mm behind the scene, tilted: nothing of it is near the model.
  test::BumpyScene far = test::plane_scene();
  far.plane_z += 20e-3;
  const Image32f live = test::exact_depth(far, m.camera, m.T_world_model * test_motion());
  Tracker tracker(Device::cpu(), m.camera);
  const Pose guess = m.T_world_model * test::camera_motion(Eigen::Vector3d(1e-5, 0, 0), Eigen::Vector3d::UnitZ(), 0.0);
  const TrackingResult r = tracker.track(live, m.raycast, m.T_world_model, guess);
  std::printf("[tracker] unrelated: %s\n", r.reason.c_str());
  EXPECT_TRUE(r.lost);
  EXPECT_NE(r.reason.find("match the model"), std::string::npos) << r.reason;
  EXPECT_TRUE(test::same_pose(r.T_world_camera, guess));
  EXPECT_EQ(r.inliers, 0u);
}

// A model volume that holds a small part of the view (a GPU memory budget's, issue 22): the
// live frame sees the whole scene, the model only what is inside the box. Counting every live
// pixel, the overlap test loses the frame; told the volume, it counts only the pixels the
// guess puts inside, and the frame registers to the surface there.
TEST(Tracker, AVolumeSmallerThanTheViewCountsOnlyThePixelsInsideIt) {
  const test::BumpyScene scene = test::bumpy_scene();
  const VolumeGeometry small = test::small_scene_volume(scene);
  const Model m(scene, test::tracker_camera(), &small);
  const Pose truth = m.T_world_model * test_motion();
  const Image32f live = test::exact_depth(m.scene, m.camera, truth);
  Tracker tracker(Device::cpu(), m.camera);
  const TrackingResult all = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model);
  std::printf("[tracker] small volume, every pixel counted: %s\n", all.reason.c_str());
  EXPECT_TRUE(all.lost);
  EXPECT_TRUE(all.too_little_overlap);
  EXPECT_EQ(all.live_pixels_outside_model, 0u);

  const TrackingResult r = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model, nullptr, nullptr,
                                         nullptr, &small);
  const test::SurfaceError after = test::surface_error(live, m.camera, r.T_world_camera, truth);
  print("small volume", r, truth, after);
  EXPECT_FALSE(r.lost) << r.reason;
  EXPECT_EQ(r.live_pixels + r.live_pixels_outside_model, all.live_pixels);
  const double inside = static_cast<double>(r.live_pixels) / static_cast<double>(all.live_pixels);
  EXPECT_GT(inside, 0.1);
  EXPECT_LT(inside, TrackingOptions{}.min_inlier_fraction);  // why counting every pixel loses it
  EXPECT_GT(r.inlier_fraction, 0.8);
  EXPECT_LT(after.rms_m, kSurfaceBound);

  // A guess that puts the whole view outside the volume: lost for overlap, and said so.
  const Pose away = m.T_world_model * test::camera_motion(Eigen::Vector3d(20e-3, 0.0, 0.0), Eigen::Vector3d::UnitZ(), 0.0);
  const TrackingResult outside =
      tracker.track(live, m.raycast, m.T_world_model, away, nullptr, nullptr, nullptr, &small);
  EXPECT_TRUE(outside.lost);
  EXPECT_TRUE(outside.too_little_overlap);
  EXPECT_NE(outside.reason.find("inside the model's volume"), std::string::npos) << outside.reason;
  EXPECT_TRUE(test::same_pose(outside.T_world_camera, away));
}

TEST(Tracker, EmptyLiveMapIsLost) {
  const Model& m = bumpy_model();
  Tracker tracker(Device::cpu(), m.camera);
  const TrackingResult r = tracker.track(Image32f(m.camera.width, m.camera.height, 0.0f), m.raycast, m.T_world_model,
                                         m.T_world_model);
  EXPECT_TRUE(r.lost);
  EXPECT_NE(r.reason.find("no valid depth"), std::string::npos) << r.reason;
  EXPECT_TRUE(test::same_pose(r.T_world_camera, m.T_world_model));
}

TEST(Tracker, ImplausibleCorrectionAndResidualAreLost) {
  const Model& m = bumpy_model();
  const Pose truth = m.T_world_model * test_motion();
  const Image32f live = test::exact_depth(m.scene, m.camera, truth);
  {
    TrackingOptions options;
    options.max_correction_m = 0.1e-3;  // the true correction is larger
    Tracker tracker(Device::cpu(), m.camera, options);
    const TrackingResult r = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model);
    std::printf("[tracker] correction: %s\n", r.reason.c_str());
    EXPECT_TRUE(r.lost);
    EXPECT_NE(r.reason.find("moves the view's centre"), std::string::npos) << r.reason;
    EXPECT_TRUE(test::same_pose(r.T_world_camera, m.T_world_model));
  }
  {
    TrackingOptions options;
    options.max_correction_deg = 0.5;  // the true rotation is 1.5°
    Tracker tracker(Device::cpu(), m.camera, options);
    const TrackingResult r = tracker.track(live, m.raycast, m.T_world_model, m.T_world_model);
    EXPECT_TRUE(r.lost);
    EXPECT_NE(r.reason.find("deg allowed"), std::string::npos) << r.reason;
  }
  {
    // Depth noise of 20 um against a residual limit of 5 um.
    Image32f noisy = live;
    std::uint32_t state = 12345u;
    for (std::size_t i = 0; i < noisy.pixel_count(); ++i) {
      if (!(noisy.data()[i] > 0.0f)) continue;
      state = state * 1664525u + 1013904223u;
      const double uniform = static_cast<double>(state >> 8) / 16777216.0 - 0.5;  // sigma 0.29
      noisy.data()[i] += static_cast<float>(uniform * 69e-6);                    // sigma 20 um
    }
    TrackingOptions options;
    options.max_residual_rms_m = 5e-6;
    Tracker tracker(Device::cpu(), m.camera, options);
    const TrackingResult r = tracker.track(noisy, m.raycast, m.T_world_model, m.T_world_model);
    std::printf("[tracker] residual: %s\n", r.reason.c_str());
    EXPECT_TRUE(r.lost);
    EXPECT_NE(r.reason.find("residual RMS"), std::string::npos) << r.reason;
    EXPECT_GT(r.residual_rms_m, 10e-6);
  }
}

TEST(Tracker, BadInputIsAClearError) {
  const Model& m = bumpy_model();
  Tracker tracker(Device::cpu(), m.camera);
  test::expect_invalid([&] { tracker.track(Image32f(100, 80), m.raycast, m.T_world_model, m.T_world_model); },
                 "live depth map is 100x80");
  RaycastResult small = m.raycast;
  small.points_camera.resize(10, 1);
  test::expect_invalid([&] { tracker.track(m.raycast.depth_m, small, m.T_world_model, m.T_world_model); }, "model maps");
  test::expect_invalid([&] { Tracker(Device::cpu(), test::tracker_camera(40, 30)); }, "too small");
  test::expect_invalid([&] { Tracker(Device::cpu(), test::tracker_camera(65536, 32768)); }, "too large");
  auto invalid_option = [&](auto change, const std::string& fragment) {
    TrackingOptions options;
    change(options);
    test::expect_invalid([&] { options.validate(); }, fragment);
    test::expect_invalid([&] { Tracker(Device::cpu(), m.camera, options); }, fragment);
  };
  TrackingOptions{}.validate();
  invalid_option([](TrackingOptions& o) { o.iterations.clear(); }, "pyramid levels");
  invalid_option([](TrackingOptions& o) { o.iterations = {0, 3}; }, "finest level");
  invalid_option([](TrackingOptions& o) { o.iterations = {3, -1}; }, "iterations at level 1");
  invalid_option([](TrackingOptions& o) { o.max_distance_m = 0.0; }, "max_distance_m");
  invalid_option([](TrackingOptions& o) { o.max_normal_angle_deg = 0.0; }, "max_normal_angle_deg");
  invalid_option([](TrackingOptions& o) { o.min_translation_step_m = -1.0; }, "minimum steps");
  invalid_option([](TrackingOptions& o) { o.degenerate_eigen_ratio = 1.0; }, "degenerate_eigen_ratio");
  invalid_option([](TrackingOptions& o) { o.min_inlier_fraction = 1.5; }, "min_inlier_fraction");
  invalid_option([](TrackingOptions& o) { o.max_residual_rms_m = std::nan(""); }, "max_residual_rms_m");
  invalid_option([](TrackingOptions& o) { o.max_correction_deg = -1.0; }, "max_correction");
#if !defined(SLS_HAVE_CUDA)
  try {
    Tracker cuda(Device::cuda(), m.camera);
    ADD_FAILURE() << "a CUDA tracker in a build without CUDA";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kUnsupported);
  }
#endif
}

// track_shared.h: the 2x2 block keeps the nearest surface across a depth step and averages
// the rest; live normals face the camera and are not formed across a step.
// The crease test on model maps: normals over the baseline from the points (baseline_normal),
// then near_crease. A 90 degree V ridge along a column (points at 0.1 m, 37 um pixels, so the
// 30 um baseline is one pixel): the two columns whose normals straddle the ridge and their
// neighbours are marked, no other; a cylinder of 2 mm radius marks none, nor does a plane seen
// at a slant; where the ridge's points are missing there are no normals beside it to compare.
TEST(TrackShared, CreasesOnTheModelMaps) {
  const int w = 12, h = 5;
  const float fx = 2700.0f, pixel = 0.1f / fx, baseline = 30e-6f, radius = 30e-6f;
  const float min_cos = std::cos(15.0f * static_cast<float>(M_PI) / 180.0f);
  std::vector<Vec3f> points(static_cast<std::size_t>(w * h)), normals(points.size());
  auto fill = [&](auto depth_of) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const float along = (static_cast<float>(x) - 6.0f) * pixel;
        points[static_cast<std::size_t>(y * w + x)] =
            Vec3f{along, (static_cast<float>(y) - 2.0f) * pixel, 0.1f + depth_of(along)};
      }
    }
  };
  auto marked = [&](int x, int y) {
    for (int yy = 0; yy < h; ++yy) {
      for (int xx = 0; xx < w; ++xx) {
        normals[static_cast<std::size_t>(yy * w + xx)] = baseline_normal(PointMap{points.data()}, w, h, fx, baseline, xx, yy);
      }
    }
    return near_crease(normals.data(), points.data(), w, h, fx, radius, min_cos, x, y);
  };
  auto ridge = [&](float along) { return std::fabs(along + 0.5f * pixel); };  // between columns 5 and 6
  fill(ridge);
  for (int x = 0; x < w; ++x) EXPECT_EQ(marked(x, 2), x >= 4 && x <= 7) << "ridge, column " << x;
  fill([&](float along) { return 2e-3f - std::sqrt(4e-6f - along * along); });
  for (int x = 0; x < w; ++x) EXPECT_FALSE(marked(x, 2)) << "cylinder, column " << x;
  fill([&](float along) { return 3.0f * along; });  // 72 degrees from face on
  for (int x = 0; x < w; ++x) EXPECT_FALSE(marked(x, 2)) << "slanted plane, column " << x;
  fill(ridge);
  for (int y = 0; y < h; ++y) {
    points[static_cast<std::size_t>(y * w + 5)] = points[static_cast<std::size_t>(y * w + 6)] = Vec3f{0, 0, 0};
  }
  for (int x = 0; x < w; ++x) EXPECT_FALSE(marked(x, 2)) << "ridge missing, column " << x;
}

TEST(TrackShared, PyramidAndNormals) {
  const float fx = 2700.0f;
  // A block on one surface (within 8 footprints = 0.3 mm at 0.1 m), and one across a 1 mm step.
  const float fine[8] = {0.1000f, 0.1001f, 0.1000f, 0.1010f,  //
                         0.1002f, 0.0f, 0.1000f, 0.1010f};
  EXPECT_NEAR(downsample_depth(fine, 4, 2, fx, 0, 0), (0.1000f + 0.1001f + 0.1002f) / 3.0f, 1e-7f);
  EXPECT_NEAR(downsample_depth(fine, 4, 2, fx, 1, 0), 0.1000f, 1e-7f);
  const float empty[4] = {0.0f, 0.0f, std::nanf(""), -1.0f};
  EXPECT_EQ(downsample_depth(empty, 2, 2, fx, 0, 0), 0.0f);
  // Weights: the mean of the depths kept (the step's far pixels and holes do not count).
  const float fine_weight[8] = {0.2f, 0.4f, 1.0f, 0.5f,  //
                                0.9f, 0.7f, 0.3f, 0.5f};
  float coarse_weight = -1.0f;
  EXPECT_NEAR(downsample_depth(fine, 4, 2, fx, 0, 0, fine_weight, &coarse_weight), (0.1000f + 0.1001f + 0.1002f) / 3.0f,
              1e-7f);
  EXPECT_NEAR(coarse_weight, (0.2f + 0.4f + 0.9f) / 3.0f, 1e-7f);
  downsample_depth(fine, 4, 2, fx, 1, 0, fine_weight, &coarse_weight);
  EXPECT_NEAR(coarse_weight, (1.0f + 0.3f) / 2.0f, 1e-7f);
  downsample_depth(empty, 2, 2, fx, 0, 0, fine_weight, &coarse_weight);
  EXPECT_EQ(coarse_weight, 0.0f);

  // A plane z = 0.1 + 0.5 x (tilted about y), on a pinhole ray map.
  const int w = 4, h = 3;
  Vec3f rays[w * h];
  float depth[w * h];
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const Vec3f ray{(static_cast<float>(x) - 1.5f) / fx, (static_cast<float>(y) - 1.0f) / fx, 1.0f};
      rays[y * w + x] = ray;
      depth[y * w + x] = 0.1f / (1.0f - 0.5f * ray.x);  // z = 0.1 + 0.5 (ray.x z)
    }
  }
  const Vec3f n = live_normal(depth, rays, w, h, fx, 0.0f, 1, 1);
  const float expected = 1.0f / std::sqrt(1.25f);  // (0.5, 0, -1) / |.|, facing the camera
  EXPECT_NEAR(n.x, 0.5f * expected, 1e-3f);
  EXPECT_NEAR(n.y, 0.0f, 1e-3f);
  EXPECT_NEAR(n.z, -expected, 1e-3f);
  const Vec3f n2 = live_normal(depth, rays, w, h, fx, 0.0f, 2, 1);
  EXPECT_NEAR(n2.x, n.x, 1e-3f);
  EXPECT_NEAR(n2.z, n.z, 1e-3f);
  EXPECT_EQ(norm(live_normal(depth, rays, w, h, fx, 0.0f, 3, 1)), 0.0f);  // border
  EXPECT_EQ(norm(live_normal(depth, rays, w, h, fx, 0.0f, 0, 1)), 0.0f);
  EXPECT_EQ(norm(live_normal(depth, rays, w, h, fx, 0.0f, 1, 0)), 0.0f);
  depth[1 * w + 2] += 1e-3f;  // a 1 mm step to the right of (1, 1)
  EXPECT_EQ(norm(live_normal(depth, rays, w, h, fx, 0.0f, 1, 1)), 0.0f);
  depth[1 * w + 2] = 0.0f;  // a hole
  EXPECT_EQ(norm(live_normal(depth, rays, w, h, fx, 0.0f, 1, 1)), 0.0f);
}

TEST(Tracker, MatchesOnCreasesAreSetAside) {
  const test::GroovedScrew screw;
  const CameraIntrinsics& camera = screw.camera;
  const test::TexturedFrame& live = screw.live;
  const test::TexturedModel& model = screw.model;
  const Pose& model_pose = screw.model_pose;
  std::printf("[tracker] screw turned 1 deg: %zu of %zu live pixels on the groove lines\n", screw.lines,
              live.depth_m.pixel_count());
  ASSERT_GT(screw.lines, 500u);

  TrackingOptions off;
  off.crease_angle_deg = 0.0;
  Tracker with_test(Device::cpu(), camera), without_test(Device::cpu(), camera, off);
  auto track = [&](Tracker& tracker, const Image32f& depth, const char* name) {
    const TrackingResult r = tracker.track(depth, model.raycast, model_pose, model_pose);
    print(name, r, live.T_world_camera, test::surface_error(screw.clean, camera, r.T_world_camera, live.T_world_camera));
    EXPECT_FALSE(r.lost) << name << ": " << r.reason;
    EXPECT_LT(test::surface_error(screw.clean, camera, r.T_world_camera, live.T_world_camera).rms_m, kSurfaceBound)
        << name;
    return r;
  };
  const TrackingResult on = track(with_test, screw.biased, "biased grooves, crease test");
  const TrackingResult on_exact = track(with_test, live.depth_m, "exact, crease test");
  const TrackingResult off_biased = track(without_test, screw.biased, "biased grooves, no crease test");
  const TrackingResult off_exact = track(without_test, live.depth_m, "exact, no crease test");
  EXPECT_GT(on.crease_pixels, screw.lines);  // the lines and the flanks' pixels next to them
  EXPECT_EQ(off_biased.crease_pixels, 0u);
  // How far the bias moves the registration (the surface in view, RMS).
  auto shift = [&](const TrackingResult& a, const TrackingResult& b) {
    return test::surface_error(screw.clean, camera, a.T_world_camera, b.T_world_camera).rms_m;
  };
  std::printf("[tracker] the bias moves the surface %.3f um with the crease test, %.3f um without\n",
              shift(on, on_exact) * 1e6, shift(off_biased, off_exact) * 1e6);
  EXPECT_LT(shift(on, on_exact), 0.05e-6);
  EXPECT_GT(shift(off_biased, off_exact), 0.2e-6);
}

}  // namespace
}  // namespace sls::fusion
