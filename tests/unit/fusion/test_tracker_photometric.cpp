// The tracker's photometric term (photometric_shared.h) on frames the simulator renders: a
// chessboard sliding in its own plane, a textured knurled screw turned by a tooth and slid
// along its axis, bad input; and the term's per-pixel math (Jacobian by finite differences,
// pyramid, bilinear sampling). The geometric ICP is in test_tracker.cpp.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/scene.h"
#include "fusion/photometric_shared.h"
#include "fusion/track_shared.h"
#include "fusion/tracker.h"
#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"
#include "tests/unit/fusion/photometric_test_scenes.h"
#include "tests/unit/fusion/tracker_test_scenes.h"

namespace sls::fusion {
namespace {

using test::bumpy_model;
using test::degrees;
using test::kVoxel;
using test::Model;

// ---------------------------------------------------------------------------------------
// The photometric term (photometric_shared.h), on frames the simulator renders.

const sim::Scene& chessboard_scene() {
  static const sim::Scene scene = sim::make_chessboard_scene();
  return scene;
}

// Where a registration puts the live frame's surface against where it is.
test::SurfaceError frame_error(const test::TexturedFrame& live, const CameraIntrinsics& camera, const Pose& estimate) {
  return test::surface_error(live.depth_m, camera, estimate, live.T_world_camera);
}

void print_photometric(const char* name, const TrackingResult& r, const test::SurfaceError& e) {
  std::printf("[tracker] %s: lost=%d %s| surface RMS %.3f um max %.3f um; %d degenerate, %d iterations; "
              "photometric %d%s%s, %zu px, rms %.4f, gain %.4f\n",
              name, r.lost ? 1 : 0, r.reason.empty() ? "" : (r.reason + " ").c_str(), e.rms_m * 1e6, e.max_m * 1e6,
              r.degenerate_directions, r.iterations, r.photometric ? 1 : 0,
              r.photometric_skipped.empty() ? "" : " skipped: ", r.photometric_skipped.c_str(), r.photometric_pixels,
              r.photometric_rms, r.photometric_gain);
}

// The chessboard's two frames: the reference, and the board slid in its plane.
struct ChessboardSlide {
  sim::SimRig rig = test::textured_rig(chessboard_scene());
  test::TexturedFrame reference = test::render_textured_frame(rig, chessboard_scene(), 0);
  test::TexturedFrame live = test::render_textured_frame(
      test::moved_rig(rig, test::chessboard_slide(), rig.noise_seed + 1), chessboard_scene(), 0);
};

const ChessboardSlide& chessboard_slide() {
  static const ChessboardSlide frames;
  return frames;
}

// The chessboard (1.2 mm squares: 32 pixels) slides 0.25 mm and turns 1° in its own plane
// between two frames. Depth alone sees the same plane in both: sliding and turning about the
// normal are degenerate and keep the guess, the surface stays 0.26 mm off. With the texture
// (white − black, which the sim shades by the projector moving with the camera and adds
// noise to) the slide is recovered to a small fraction of the 37.5 um pixel, also with the
// live map halved (max_model_width) and at Kintinuous' weight 0.1 or at 1.
TEST(TrackerPhotometric, TexturedPlaneSlidingInItselfIsRecovered) {
  const ChessboardSlide& f = chessboard_slide();
  const CameraIntrinsics& camera = f.rig.camera;
  const double pixel_m = 0.1 / camera.fx;
  const test::TexturedModel model(test::chessboard_volume(), f.reference, camera, camera);
  const test::SurfaceError before = frame_error(f.live, camera, f.reference.T_world_camera);
  std::printf("[tracker] chessboard slide: the guess is off by %.1f um RMS (max %.1f um), pixels of %.1f um\n",
              before.rms_m * 1e6, before.max_m * 1e6, pixel_m * 1e6);
  ASSERT_GT(before.rms_m, 200e-6);

  Tracker depth_only(Device::cpu(), camera);
  const TrackingResult a = depth_only.track(f.live.depth_m, model.raycast, f.reference.T_world_camera,
                                            f.reference.T_world_camera, &f.live.texture);
  const test::SurfaceError ea = frame_error(f.live, camera, a.T_world_camera);
  print_photometric("chessboard, depth only", a, ea);
  EXPECT_FALSE(a.lost) << a.reason;
  EXPECT_EQ(a.degenerate_directions, 3);
  EXPECT_GT(ea.rms_m, 0.9 * before.rms_m);  // the slide kept the guess
  EXPECT_FALSE(a.photometric);
  EXPECT_TRUE(a.photometric_skipped.empty()) << a.photometric_skipped;  // weight 0: not asked for
  EXPECT_FALSE(depth_only.has_reference_frame());

  for (const double weight : {0.1, 1.0}) {
    TrackingOptions options;
    options.photometric_weight = weight;
    Tracker tracker(Device::cpu(), camera, options);
    tracker.set_reference_frame(f.reference.depth_m, f.reference.texture, f.reference.T_world_camera);
    ASSERT_TRUE(tracker.has_reference_frame());
    const TrackingResult b = tracker.track(f.live.depth_m, model.raycast, f.reference.T_world_camera,
                                           f.reference.T_world_camera, &f.live.texture);
    const test::SurfaceError eb = frame_error(f.live, camera, b.T_world_camera);
    print_photometric(weight < 0.5 ? "chessboard, w 0.1" : "chessboard, w 1", b, eb);
    EXPECT_FALSE(b.lost) << b.reason;
    EXPECT_TRUE(b.photometric) << b.photometric_skipped;
    EXPECT_EQ(b.degenerate_directions, 0);
    EXPECT_GT(b.photometric_pixels, 10000u);
    EXPECT_NEAR(b.photometric_gain, 1.0, 0.02);  // the board's light changes little over the slide
    // A twentieth of a pixel (measured: 0.6 um, 0.016 px).
    EXPECT_LT(eb.rms_m, 0.05 * pixel_m);
    EXPECT_LT(eb.max_m, 0.1 * pixel_m);
    // Depth and tilt as well registered as by depth alone (the plane is in the model).
    EXPECT_NEAR(b.residual_rms_m, a.residual_rms_m, 0.1 * a.residual_rms_m);
  }

  // ICP on the live map halved (160 x 120, 75 um pixels): the texture pyramid is halved too.
  TrackingOptions halved;
  halved.photometric_weight = 0.1;
  halved.max_model_width = camera.width / 2;
  Tracker tracker(Device::cpu(), camera, halved);
  const test::TexturedModel half_model(test::chessboard_volume(), f.reference, camera, tracker.model_camera());
  tracker.set_reference_frame(f.reference.depth_m, f.reference.texture, f.reference.T_world_camera);
  const TrackingResult c = tracker.track(f.live.depth_m, half_model.raycast, f.reference.T_world_camera,
                                         f.reference.T_world_camera, &f.live.texture);
  const test::SurfaceError ec = frame_error(f.live, camera, c.T_world_camera);
  print_photometric("chessboard, halved, w 0.1", c, ec);
  EXPECT_FALSE(c.lost) << c.reason;
  EXPECT_TRUE(c.photometric);
  EXPECT_LT(ec.rms_m, 0.1 * pixel_m);
}

// The reference frame: set, kept after a registered frame, not replaced by a lost one; the
// term off (and saying why) without a texture or a reference; weight 0 ignores textures.
TEST(TrackerPhotometric, ReferenceFramesAndMissingTextures) {
  const ChessboardSlide& f = chessboard_slide();
  const CameraIntrinsics& camera = f.rig.camera;
  const test::TexturedModel model(test::chessboard_volume(), f.reference, camera, camera);
  const Pose& model_pose = f.reference.T_world_camera;
  TrackingOptions options;
  options.photometric_weight = 0.1;
  Tracker tracker(Device::cpu(), camera, options);
  Tracker depth_only(Device::cpu(), camera);
  const TrackingResult plain = depth_only.track(f.live.depth_m, model.raycast, model_pose, model_pose);

  // No texture: the term is off for the frame, the result is depth alone's, bit for bit.
  const TrackingResult no_texture = tracker.track(f.live.depth_m, model.raycast, model_pose, model_pose);
  EXPECT_FALSE(no_texture.photometric);
  EXPECT_EQ(no_texture.photometric_skipped, "no live texture");
  EXPECT_TRUE(test::same_pose(no_texture.T_world_camera, plain.T_world_camera));
  EXPECT_EQ(no_texture.inliers, plain.inliers);
  EXPECT_FALSE(tracker.has_reference_frame());

  // A texture but no reference yet: depth alone; the frame becomes the reference.
  const TrackingResult first = tracker.track(f.reference.depth_m, model.raycast, model_pose, model_pose,
                                             &f.reference.texture);
  EXPECT_FALSE(first.lost) << first.reason;
  EXPECT_FALSE(first.photometric);
  EXPECT_NE(first.photometric_skipped.find("no reference frame"), std::string::npos) << first.photometric_skipped;
  EXPECT_TRUE(tracker.has_reference_frame());

  // The next frame uses it (the reference's pose is where `first` registered it).
  const TrackingResult second = tracker.track(f.live.depth_m, model.raycast, model_pose, model_pose, &f.live.texture);
  print_photometric("chessboard after a tracked reference", second, frame_error(f.live, camera, second.T_world_camera));
  EXPECT_TRUE(second.photometric) << second.photometric_skipped;
  EXPECT_LT(frame_error(f.live, camera, second.T_world_camera).rms_m, 2e-6);

  // A lost frame (an empty depth map) leaves the reference as it was.
  const TrackingResult lost = tracker.track(Image32f(camera.width, camera.height, 0.0f), model.raycast, model_pose,
                                            model_pose, &f.live.texture);
  EXPECT_TRUE(lost.lost);
  EXPECT_TRUE(tracker.has_reference_frame());
  tracker.clear_reference_frame();
  EXPECT_FALSE(tracker.has_reference_frame());

  // A dark texture sets no reference; weight 0 keeps none and ignores the texture.
  tracker.set_reference_frame(f.reference.depth_m, Image32f(camera.width, camera.height, 0.0f), model_pose);
  EXPECT_FALSE(tracker.has_reference_frame());
  depth_only.set_reference_frame(f.reference.depth_m, f.reference.texture, model_pose);
  EXPECT_FALSE(depth_only.has_reference_frame());
  const TrackingResult ignored =
      depth_only.track(f.live.depth_m, model.raycast, model_pose, model_pose, &f.live.texture);
  EXPECT_TRUE(test::same_pose(ignored.T_world_camera, plain.T_world_camera));
}

TEST(TrackerPhotometric, BadInputIsAClearError) {
  const Model& m = bumpy_model();
  TrackingOptions options;
  options.photometric_weight = 0.1;
  Tracker tracker(Device::cpu(), m.camera, options);
  const Image32f live = test::exact_depth(m.scene, m.camera, m.T_world_model);
  const Image32f texture(m.camera.width, m.camera.height, 100.0f);
  const Image32f small(100, 80, 100.0f);
  test::expect_invalid([&] { tracker.track(live, m.raycast, m.T_world_model, m.T_world_model, &small); },
                       "live texture is 100x80, the camera 320x240");
  test::expect_invalid([&] { tracker.set_reference_frame(live, small, m.T_world_model); },
                       "reference texture is 100x80");
  test::expect_invalid([&] { tracker.set_reference_frame(small, texture, m.T_world_model); },
                       "reference depth map is 100x80");
  // Also when the term is off: a wrong size is a wrong size.
  Tracker depth_only(Device::cpu(), m.camera);
  test::expect_invalid([&] { depth_only.track(live, m.raycast, m.T_world_model, m.T_world_model, &small); },
                       "live texture");
  auto invalid_option = [&](auto change, const std::string& fragment) {
    TrackingOptions o;
    change(o);
    test::expect_invalid([&] { o.validate(); }, fragment);
  };
  invalid_option([](TrackingOptions& o) { o.photometric_weight = -0.1; }, "photometric_weight");
  invalid_option([](TrackingOptions& o) { o.photometric_weight = std::nan(""); }, "photometric_weight");
  invalid_option([](TrackingOptions& o) { o.photometric_min_gradient = -1.0; }, "photometric_min_gradient");
  invalid_option([](TrackingOptions& o) { o.photometric_min_gradient = INFINITY; }, "photometric_min_gradient");
}

// The straight-knurled screw (101 teeth: one every 3.564°) with a solid texture 4 teeth
// long (AlbedoT{0.5, 0.3, 4 mm}), turned by exactly one tooth between two frames, guessed
// with no motion (a first step has no velocity). Depth alone aliases: the turned knurl is the
// same surface, it keeps the guess, the surface 0.99 mm off. What the photometric term does,
// measured: it does NOT recover the turn from that guess (at w = 1 and w = 10, and with texture
// periods of 1, 2, 4 and 8 mm; 5 pyramid levels once reached it, at 4 mm only). The texture
// tells the teeth apart, its residual is 2.7x lower at the true pose, but the white image is
// dominated by the knurl's flank shading, lit by the projector that moves with the camera:
// that shading repeats with the teeth and holds still under a one-tooth turn, so the
// photometric cost has its own minimum at the alias. Started at the truth it stays there, but
// 2.6 um off (depth alone: 0.5 um): turning changes the flanks' light (the gain it measures
// is 0.965), which brightness constancy does not model.
TEST(TrackerPhotometric, KnurledScrewTurnedByOneTooth) {
  sim::KnurledScrewParameters parameters;
  parameters.albedo = {0.5, 0.3, 4e-3};
  const sim::Scene scene = sim::make_knurled_screw_scene(parameters);
  const int teeth = sim::knurl_teeth(parameters.diameter, parameters.nominal_pitch);
  const double tooth_deg = 360.0 / teeth;
  const sim::SimRig rig = test::textured_rig(scene, teeth);  // frame 1: one tooth on
  const test::TexturedFrame reference = test::render_textured_frame(rig, scene, 0);
  const test::TexturedFrame live = test::render_textured_frame(rig, scene, 1);
  const CameraIntrinsics& camera = rig.camera;
  // Around the surface in view: the ridges at 16.1 mm from the axis, 7.4 mm up.
  const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d(15.3e-3, 0.0, 7.4e-3), 52, 280, 200, kVoxel);
  const test::TexturedModel model(geometry, reference, camera, camera);
  const Pose& model_pose = reference.T_world_camera;
  auto turned_deg = [&](const Pose& estimate) { return degrees((model_pose.inverse() * estimate).angle_rad()); };
  std::printf("[tracker] screw: %d teeth, turned %.4f deg; the guess is off by %.1f um RMS\n", teeth,
              turned_deg(live.T_world_camera), frame_error(live, camera, model_pose).rms_m * 1e6);
  ASSERT_NEAR(turned_deg(live.T_world_camera), tooth_deg, 1e-6);

  Tracker depth_only(Device::cpu(), camera);
  const TrackingResult a = depth_only.track(live.depth_m, model.raycast, model_pose, model_pose);
  print_photometric("screw, depth only", a, frame_error(live, camera, a.T_world_camera));
  std::printf("    turned %.4f deg\n", turned_deg(a.T_world_camera));
  EXPECT_FALSE(a.lost) << a.reason;
  EXPECT_LT(turned_deg(a.T_world_camera), 0.05 * tooth_deg);  // aliased onto the guess's tooth

  TrackingOptions options;
  options.photometric_weight = 1.0;
  auto photometric = [&](const Pose& guess, const char* name) {
    Tracker tracker(Device::cpu(), camera, options);
    tracker.set_reference_frame(reference.depth_m, reference.texture, model_pose);
    const TrackingResult r = tracker.track(live.depth_m, model.raycast, model_pose, guess, &live.texture);
    print_photometric(name, r, frame_error(live, camera, r.T_world_camera));
    std::printf("    turned %.4f deg\n", turned_deg(r.T_world_camera));
    EXPECT_FALSE(r.lost) << r.reason;
    EXPECT_TRUE(r.photometric) << r.photometric_skipped;
    return r;
  };
  const TrackingResult from_guess = photometric(model_pose, "screw, texture, from the guess");
  const TrackingResult from_truth = photometric(live.T_world_camera, "screw, texture, from the truth");
  // The measured limitation (above): from the guess it stays on the wrong tooth. Should this
  // start failing, the term now escapes the alias: update the comment and the report.
  EXPECT_LT(turned_deg(from_guess.T_world_camera), 0.05 * tooth_deg);
  // The texture tells the teeth apart: a far smaller residual at the true turn.
  EXPECT_LT(from_truth.photometric_rms, 0.5 * from_guess.photometric_rms);
  // From the truth it stays within a few um (the shading bias).
  EXPECT_NEAR(turned_deg(from_truth.T_world_camera), tooth_deg, 0.03);
  EXPECT_LT(frame_error(live, camera, from_truth.T_world_camera).rms_m, 6e-6);
}

// Matches on creases (TrackingOptions::crease_angle_deg, crease_radius_m): the knurled screw
// turned by 1 degree with a decoder's errors along its grooves (crease_test_scene.h), against
// a model of the previous frame. The model's creases are found on its own surface, so the
// biased pixels are set aside: the registration is the one of the unbiased frame. With the
// test off they pull it off. Both land within a fraction of a voxel of the truth.
// What the texture does pin on the knurl: sliding along the axis, which the straight knurl
// leaves free (one degenerate direction: the guess is kept). The screw slides 0.15 mm up its
// axis and turns 0.5°; its texture (the default 1 mm period, amplitude 0.3) varies along z.
TEST(TrackerPhotometric, KnurledScrewSlidingAlongItsAxis) {
  sim::KnurledScrewParameters parameters;
  parameters.albedo = {0.5, 0.3, 1e-3};
  const sim::Scene scene = sim::make_knurled_screw_scene(parameters);
  const sim::SimRig rig = test::textured_rig(scene);
  const Pose motion(Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * M_PI / 180.0, Eigen::Vector3d::UnitZ())),
                    Eigen::Vector3d(0.0, 0.0, 0.15e-3));
  const test::TexturedFrame reference = test::render_textured_frame(rig, scene, 0);
  const test::TexturedFrame live =
      test::render_textured_frame(test::moved_rig(rig, motion, rig.noise_seed + 1), scene, 0);
  const CameraIntrinsics& camera = rig.camera;
  const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d(15.3e-3, 0.0, 7.4e-3), 52, 280, 200, kVoxel);
  const test::TexturedModel model(geometry, reference, camera, camera);
  const Pose& model_pose = reference.T_world_camera;
  const test::SurfaceError before = frame_error(live, camera, model_pose);
  Tracker depth_only(Device::cpu(), camera);
  const TrackingResult a = depth_only.track(live.depth_m, model.raycast, model_pose, model_pose);
  const test::SurfaceError ea = frame_error(live, camera, a.T_world_camera);
  print_photometric("screw slide, depth only", a, ea);
  TrackingOptions options;
  options.photometric_weight = 1.0;
  Tracker tracker(Device::cpu(), camera, options);
  tracker.set_reference_frame(reference.depth_m, reference.texture, model_pose);
  const TrackingResult b = tracker.track(live.depth_m, model.raycast, model_pose, model_pose, &live.texture);
  const test::SurfaceError eb = frame_error(live, camera, b.T_world_camera);
  print_photometric("screw slide, texture", b, eb);
  std::printf("[tracker] screw slide: the guess is off by %.1f um RMS\n", before.rms_m * 1e6);
  EXPECT_FALSE(a.lost) << a.reason;
  EXPECT_FALSE(b.lost) << b.reason;
  EXPECT_EQ(a.degenerate_directions, 1);
  EXPECT_GT(ea.rms_m, 100e-6);  // the slide along the axis kept the guess
  EXPECT_EQ(b.degenerate_directions, 0);
  EXPECT_LT(eb.rms_m, 10e-6);
}

// photometric_shared.h: the Jacobian is the derivative of the residual in the ICP's
// parameterisation (a texture linear in the pixel coordinates, so the bilinear samples and
// central differences are exact: only float rounding separates the two), through the lens
// distortion and a turned, shifted estimate.
TEST(PhotometricShared, JacobianMatchesFiniteDifferences) {
  const CameraIntrinsics camera = test::tracker_camera(64, 48);
  const RayMap rays = compute_ray_map(camera);
  const int w = camera.width, h = camera.height;
  std::vector<float> ref_texture(static_cast<std::size_t>(w * h)), live_texture(ref_texture.size());
  std::vector<float> ref_depth(ref_texture.size()), live_depth(ref_texture.size(), 0.1f);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y * w + x);
      ref_texture[i] = 50.0f + 3.0f * static_cast<float>(x) - 1.0f * static_cast<float>(y);
      live_texture[i] = 40.0f + 2.0f * static_cast<float>(x) + 2.5f * static_cast<float>(y);
      ref_depth[i] = 0.1f + 2e-4f * static_cast<float>(x);
    }
  }
  PhotometricLevelView ref{ref_texture.data(), ref_depth.data(), rays.rays.data(), w, h};
  PhotometricLevelView live{live_texture.data(), live_depth.data(), rays.rays.data(), w, h};
  Vector6d twist;
  twist << 1e-4, -0.5e-4, 0.2e-4, 0.002, -0.001, 0.003;
  const Pose T_model_live = Pose::exp(twist);
  const Pose T_model_ref = Pose::exp(Vector6d::Constant(2e-4));
  const Eigen::Vector3d centre(0.001, -0.0005, 0.1);
  const double scale = 0.004;
  auto params_at = [&](const Pose& estimate) {
    PhotometricParams p;
    p.T_live_ref = (estimate.inverse() * T_model_ref).to_rigid3f();
    p.T_model_ref = T_model_ref.to_rigid3f();
    p.R_model_live = estimate.to_rigid3f().rotation;
    p.camera = camera.cast<float>();
    p.centre = Vec3f{static_cast<float>(centre.x()), static_cast<float>(centre.y()), static_cast<float>(centre.z())};
    p.inverse_scale = static_cast<float>(1.0 / scale);
    p.gain = 1.1f;
    p.inverse_mean = 0.01f;
    p.min_gradient = 0.0f;
    p.max_depth_difference_m = 1e-2f;
    return p;
  };
  // δT = Tr(c) · exp([ρ, ω'/L]) · Tr(−c) (track_shared.h).
  auto stepped = [&](const Vector6d& step) {
    Vector6d scaled = step;
    scaled.tail<3>() /= scale;
    return Pose(Eigen::Quaterniond::Identity(), centre) * Pose::exp(scaled) *
           Pose(Eigen::Quaterniond::Identity(), -centre) * T_model_live;
  };
  int checked = 0;
  for (const auto& [x, y] : {std::pair<int, int>{20, 15}, {32, 24}, {45, 30}, {12, 36}}) {
    float jacobian[6], residual = 0.0f, lv = 0.0f, rv = 0.0f;
    ASSERT_EQ(photometric_pixel(ref, live, params_at(T_model_live), x, y, jacobian, &residual, &lv, &rv),
              kPhotometricRow);
    EXPECT_NEAR(residual, (1.1f * lv - rv) * 0.01f, 1e-5f);
    for (int k = 0; k < 6; ++k) {
      const double delta = 1e-6;  // metres (ρ) and metres of arc at L (ω')
      Vector6d step = Vector6d::Zero();
      step(k) = delta;
      float jp[6], jm[6], rp = 0.0f, rm = 0.0f, unused = 0.0f;
      ASSERT_EQ(photometric_pixel(ref, live, params_at(stepped(step)), x, y, jp, &rp, &unused, &unused),
                kPhotometricRow);
      ASSERT_EQ(photometric_pixel(ref, live, params_at(stepped(-step)), x, y, jm, &rm, &unused, &unused),
                kPhotometricRow);
      const double numeric = (static_cast<double>(rp) - static_cast<double>(rm)) / (2.0 * delta);
      EXPECT_NEAR(jacobian[k], numeric, 0.003 * std::fabs(numeric) + 0.15)
          << "pixel " << x << "," << y << " column " << k;
      ++checked;
    }
  }
  EXPECT_EQ(checked, 24);
  // The gradient test: a flat reference matches (for the gain) but gives no row.
  std::fill(ref_texture.begin(), ref_texture.end(), 80.0f);
  float jacobian[6], residual = 0.0f, lv = 0.0f, rv = 0.0f;
  PhotometricParams flat = params_at(T_model_live);
  flat.min_gradient = 1e-3f;
  EXPECT_EQ(photometric_pixel(ref, live, flat, 30, 20, jacobian, &residual, &lv, &rv), kPhotometricMatched);
  EXPECT_EQ(rv, 80.0f);
  // Occluded (the live surface 1 cm nearer) and off the image: no match.
  flat.max_depth_difference_m = 1e-3f;
  std::fill(live_depth.begin(), live_depth.end(), 0.09f);
  EXPECT_EQ(photometric_pixel(ref, live, flat, 30, 20, jacobian, &residual, &lv, &rv), kPhotometricNone);
  EXPECT_EQ(photometric_pixel(ref, live, flat, 0, 20, jacobian, &residual, &lv, &rv), kPhotometricNone);
}

TEST(PhotometricShared, PyramidAndBilinear) {
  const float fine[6] = {1.0f, 3.0f, 5.0f,  //
                         5.0f, 7.0f, 9.0f};
  EXPECT_FLOAT_EQ(downsample_texture(fine, 3, 2, 0, 0), 4.0f);
  EXPECT_FLOAT_EQ(downsample_texture(fine, 3, 2, 1, 0), 7.0f);  // the block's column inside the image
  EXPECT_FLOAT_EQ(sample_bilinear(fine, 3, 0.5f, 0.5f), 4.0f);
  EXPECT_FLOAT_EQ(sample_bilinear(fine, 3, 1.25f, 0.0f), 3.5f);
  EXPECT_FLOAT_EQ(sample_bilinear(fine, 3, 1.0f, 0.75f), 6.0f);
  double sums[kTextureSums] = {};
  accumulate_texture_statistics(10.0f, 0.1f, sums);
  accumulate_texture_statistics(99.0f, 0.0f, sums);  // no depth: not counted
  EXPECT_EQ(sums[0], 10.0);
  EXPECT_EQ(sums[1], 1.0);
}

}  // namespace
}  // namespace sls::fusion
