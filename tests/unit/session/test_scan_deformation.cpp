// Online deformation and loop closure in the scan session (sdk/session/scan_deformation.h,
// ScanSession::close_loop) against the simulator's truth: a full turntable revolution of the
// knurled knob at the ci preset (36 depth maps of 400 x 300, the decoder's noise model,
// tracked with the turntable prior) closes to a fraction of its drift, the map and poses are
// deformed by the nodes of their own time, and the errors a caller can cause are clear.
#include <cmath>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/session/scan_deformation.h"
#include "sdk/session/scan_session.h"
#include "tests/unit/session/sim_frames.h"

namespace sls::session {
namespace {

ScanSessionOptions revolution_options(const Device& device) {
  ScanSessionOptions options = small_options(device);
  options.turntable_prior = true;  // the ci preset's 10° steps alias with the knurl from depth alone
  return options;
}

// The error of the first-to-last motion (the loop) of a trajectory against the truth.
RelativeError loop_error(const std::vector<StampedPose>& trajectory, const SimFrames& sim, std::size_t last) {
  return relative_error(trajectory.front().T_world_camera, trajectory.back().T_world_camera, sim.truth(0),
                        sim.truth(last));
}

// RMS over frames of the camera position error relative to frame 0.
double relative_rms_m(const std::vector<StampedPose>& trajectory, const SimFrames& sim) {
  double sum = 0.0;
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const RelativeError e =
        relative_error(trajectory.front().T_world_camera, trajectory[i].T_world_camera, sim.truth(0), sim.truth(i));
    sum += e.translation_m * e.translation_m;
  }
  return std::sqrt(sum / static_cast<double>(trajectory.size()));
}

TEST(ScanDeformation, ClosesATurntableRevolution) {
  SimFrames sim("knurled-knob", 36);
  ScanSession session(sim.calibration(), nullptr, revolution_options(Device::cpu()));
  std::size_t keyframes = 0;
  for (int k = 0; k < 36; ++k) {
    const FrameReport report = session.add_frame(sim.frame(k));
    ASSERT_EQ(report.status, FrameStatus::kFused) << "frame " << k << ": " << report.reason;
    keyframes += report.deformation.keyframe;
  }
  EXPECT_GT(keyframes, 20u);  // 10° steps: every frame turns past the 5° node angle
  const LoopClosureReport loop = session.close_loop();
  EXPECT_EQ(loop.first_frame, 0);
  EXPECT_EQ(loop.last_frame, 35);
  EXPECT_FALSE(loop.registration.lost);
  // The default two last frames were each tried: the newest registers.
  ASSERT_FALSE(loop.registered_frames.empty());
  EXPECT_EQ(loop.registered_frames.front(), 35);
  EXPECT_EQ(loop.registered_frames.size() + loop.unregistered.size(), 2u);
  EXPECT_GT(loop.constraints, 500u);
  EXPECT_GE(loop.solve.iterations, 1);
  EXPECT_LT(loop.solve.after.total(), loop.solve.before.total());
  ASSERT_TRUE(session.loop_closure().has_value());

  const std::vector<StampedPose> tracked = session.trajectory_undeformed();
  const std::vector<StampedPose> closed = session.trajectory();
  ASSERT_EQ(tracked.size(), 36u);
  ASSERT_EQ(closed.size(), 36u);
  const RelativeError before = loop_error(tracked, sim, 35);
  const RelativeError after = loop_error(closed, sim, 35);
  std::printf("[ measured ] loop %.1f um / %.4f deg -> %.1f um / %.4f deg; relative RMS %.1f -> %.1f um\n",
              before.translation_m * 1e6, before.rotation_deg, after.translation_m * 1e6, after.rotation_deg,
              relative_rms_m(tracked, sim) * 1e6, relative_rms_m(closed, sim) * 1e6);
  EXPECT_LT(after.translation_m, 0.25 * before.translation_m);
  EXPECT_LT(after.rotation_deg, 0.25 * before.rotation_deg);
  EXPECT_LT(relative_rms_m(closed, sim), relative_rms_m(tracked, sim));
  // The first frame holds the world: its nodes are pinned, so its pose moves only by the
  // share of the next (free) nodes it is bound to, far less than the loop's correction.
  const Pose first_moved = tracked.front().T_world_camera.inverse() * closed.front().T_world_camera;
  EXPECT_LT(first_moved.translation().norm(), 0.05 * before.translation_m);

  // The map: deformed part by part, each point's move in "correction", the first parts
  // (bound to the pinned nodes) barely moved, the last ones by about the loop's correction.
  const fusion::ExtractedSurface model = session.final_surface();
  const fusion::ExtractedSurface as_tracked = session.final_surface_undeformed();
  ASSERT_EQ(model.cloud.size(), as_tracked.cloud.size());
  const PointProperty* correction = model.cloud.find_property("correction");
  ASSERT_NE(correction, nullptr);
  ASSERT_EQ(correction->values.size(), model.cloud.size());
  EXPECT_EQ(as_tracked.cloud.find_property("correction"), nullptr);
  EXPECT_LT(correction->values.front(), 5e-6f);
  double largest = 0.0;
  for (float v : correction->values) largest = std::max(largest, static_cast<double>(v));
  EXPECT_GT(largest, 10e-6);
  EXPECT_EQ(model.mesh.vertices.size(), as_tracked.mesh.vertices.size());
  // Deformed as it was joined: every point is the tracked one moved by its correction (none
  // left unwritten), the mesh's vertices likewise within the largest, and everything else
  // (confidence, properties, triangles) the tracked model's.
  for (std::size_t i = 0; i < model.cloud.size(); ++i) {
    const float moved = (model.cloud.positions[i] - as_tracked.cloud.positions[i]).norm();
    ASSERT_NEAR(moved, correction->values[i], 1e-6f + 1e-3f * correction->values[i]) << "point " << i;
    ASSERT_NEAR(model.cloud.normals[i].norm(), 1.0f, 1e-4f) << "point " << i;
  }
  for (std::size_t i = 0; i < model.mesh.vertices.size(); ++i) {
    ASSERT_LE((model.mesh.vertices.positions[i] - as_tracked.mesh.vertices.positions[i]).norm(), 1.01 * largest + 1e-7)
        << "vertex " << i;
  }
  EXPECT_EQ(model.cloud.confidence, as_tracked.cloud.confidence);
  EXPECT_EQ(model.mesh.faces, as_tracked.mesh.faces);
  for (const PointProperty& property : as_tracked.cloud.properties) {
    const PointProperty* kept = model.cloud.find_property(property.name);
    ASSERT_NE(kept, nullptr) << property.name;
    EXPECT_EQ(kept->values, property.values) << property.name;
  }

  const ScanSession::GraphSummary graph = session.graph_summary();
  EXPECT_EQ(graph.nodes, keyframes);
  EXPECT_GE(graph.links, graph.nodes - 1);
  EXPECT_GE(graph.analyses, 1u);
  EXPECT_GT(graph.factorizations, graph.analyses);
  const DeformationStatus status = session.deformation_status(true);
  EXPECT_EQ(status.pending, 0u);
  EXPECT_TRUE(status.error.empty()) << status.error;
  EXPECT_EQ(session.keyframe_solves().size(), keyframes);
}

// The frames' tracking, the keyframes' poses in the graph and the loop closure's
// registrations take the turntable's motion as a pose prior when the calibration knows the
// table's repeatability (the simulator's: its jitter, 0.002°, and no wobble), and as a start
// only when it does not; the report says which.
TEST(ScanDeformation, LoopClosureWeighsTheTurntablesAngleByItsSigma) {
  SimFrames sim("knurled-knob", 36);
  std::vector<ScanFrame> frames;
  for (int k = 0; k < 36; ++k) frames.push_back(sim.frame(k));
  const ScannerCalibration with_sigma = sim.calibration();
  ASSERT_TRUE(with_sigma.turntable && with_sigma.turntable->angle_sigma_deg);
  EXPECT_EQ(*with_sigma.turntable->angle_sigma_deg, sim.rig().turntable.angle_jitter_deg);
  EXPECT_EQ(with_sigma.turntable->tilt_sigma_deg, 0.0);
  ScannerCalibration without_sigma = with_sigma;
  without_sigma.turntable->angle_sigma_deg.reset();
  without_sigma.turntable->tilt_sigma_deg.reset();
  std::vector<double> loop_deg;
  for (const ScannerCalibration& calibration : {with_sigma, without_sigma}) {
    ScanSession session(calibration, nullptr, revolution_options(Device::cpu()));
    const bool prior = calibration.turntable->angle_sigma_deg.has_value();
    for (const ScanFrame& frame : frames) {
      const FrameReport report = session.add_frame(frame);
      ASSERT_EQ(report.status, FrameStatus::kFused) << "frame " << frame.index << ": " << report.reason;
      // Every tracked frame weighs the table's motion since the last one, when its σ is known.
      if (report.tracking) {
        EXPECT_EQ(report.tracking->prior, prior) << "frame " << frame.index;
      }
    }
    // Each fused frame's pose carries the table's rotation since the first frame into the graph.
    const ScanSession::GraphSummary graph = session.graph_summary();
    EXPECT_EQ(graph.rotation_priors, prior ? frames.size() : 0u);
    const LoopClosureReport loop = session.close_loop();
    ASSERT_EQ(loop.turntable_sigma_deg.has_value(), prior);
    EXPECT_EQ(loop.registration.prior, prior);
    const RelativeError after = loop_error(session.trajectory(), sim, 35);
    const fusion::TrackingResult& r = loop.registration;
    std::printf("[ measured ] loop closure %s the table's sigma: %.2f um / %.4f deg; the registration moved %.2f um / "
                "%.4f deg from the table's pose, ends %.5f deg about its axis and %.5f deg across it from it (the "
                "prior's sigma %.4f / %.2g deg, the surface's %.4f / %.4f deg)\n",
                prior ? "with" : "without", after.translation_m * 1e6, after.rotation_deg, loop.guess_moved_m * 1e6,
                loop.guess_moved_deg, r.prior_offset_deg, r.prior_tilt_offset_deg, r.prior_sigma_deg,
                r.prior_tilt_sigma_deg, r.prior_surface_sigma_deg, r.prior_surface_tilt_sigma_deg);
    if (prior) {
      EXPECT_EQ(*loop.turntable_sigma_deg, 0.002);
      EXPECT_EQ(*loop.turntable_tilt_sigma_deg, 0.0);
      EXPECT_NEAR(r.prior_sigma_deg, std::sqrt(2.0) * 0.002, 1e-12);
      EXPECT_NEAR(r.prior_tilt_sigma_deg, std::sqrt(2.0) * 1e-6, 1e-15);  // 0 is taken as 1e-6°
      EXPECT_GT(r.prior_surface_sigma_deg, 0.0);
      // An exact axis and no wobble: the table decides the tilt. About the axis the surface
      // (its σ, the pixels taken as independent, below the prior's) has the larger say: here it
      // ends 0.03° off the table's angle, ten times the σ it claims (the ci preset's coarse
      // knurl, 10° steps).
      EXPECT_LT(r.prior_tilt_offset_deg, 1e-4);
      EXPECT_LT(r.prior_surface_sigma_deg, r.prior_sigma_deg);
    } else {
      EXPECT_FALSE(loop.registration.prior);
    }
    EXPECT_LT(after.rotation_deg, 0.05);
    // With σ every frame's table angle holds its pose in the graph too: the loop closes to
    // within the σ of two table angles (√2 · 0.002°), though the registration ended 0.03° off.
    if (prior) {
      EXPECT_LT(after.rotation_deg, std::sqrt(2.0) * 0.002);
    }
    loop_deg.push_back(after.rotation_deg);
  }
  EXPECT_LE(loop_deg[0], loop_deg[1]);  // measured 0.0002° with the priors, 0.038° without
}

TEST(ScanDeformation, RefusesALoopClosureBeforeAnyFrame) {
  SimFrames sim("knurled-knob", 36);
  ScanSession session(sim.calibration(), nullptr, revolution_options(Device::cpu()));
  try {
    session.close_loop();
    FAIL() << "closed a loop with no frame";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("before any frame"), std::string::npos) << error.what();
  }
}

TEST(ScanDeformation, RefusesALoopClosureWithDeformationOffAndKeepsTheModel) {
  SimFrames sim("knurled-knob", 36);
  ScanSessionOptions options = revolution_options(Device::cpu());
  options.deformation.enabled = false;
  ScanSession session(sim.calibration(), nullptr, options);
  for (int k = 0; k < 3; ++k) ASSERT_EQ(session.add_frame(sim.frame(k)).status, FrameStatus::kFused);
  EXPECT_FALSE(session.deformation_enabled());
  const std::size_t points = session.final_surface().cloud.size();
  try {
    session.close_loop();
    FAIL() << "closed a loop without deformation";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("deformation"), std::string::npos) << error.what();
  }
  EXPECT_EQ(session.final_surface().cloud.size(), points);
  EXPECT_EQ(session.final_surface().cloud.find_property("correction"), nullptr);
}

// A quarter turn is no loop: the last frame does not see the first frame's surface. The
// error says so, and the model and trajectory stay as online deformation left them.
TEST(ScanDeformation, RefusesAnOpenPathAndKeepsTheModel) {
  SimFrames sim("knurled-knob", 36);
  ScanSession session(sim.calibration(), nullptr, revolution_options(Device::cpu()));
  for (int k = 0; k < 10; ++k) ASSERT_EQ(session.add_frame(sim.frame(k)).status, FrameStatus::kFused);
  const std::vector<StampedPose> before = session.trajectory();
  const std::size_t points = session.final_surface().cloud.size();
  try {
    session.close_loop();
    FAIL() << "closed a quarter turn";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("does not register"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("nor do the 1 kept frames before it"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("model is kept"), std::string::npos) << error.what();
  }
  EXPECT_FALSE(session.loop_closure().has_value());
  const std::vector<StampedPose> after = session.trajectory();
  ASSERT_EQ(after.size(), before.size());
  for (std::size_t i = 0; i < after.size(); ++i) {
    EXPECT_TRUE(after[i].T_world_camera.is_approx(before[i].T_world_camera, 1e-12)) << i;
  }
  EXPECT_EQ(session.final_surface().cloud.size(), points);
}

// Samples of a tilted plane lie on it with its normal, through a lens without distortion and
// with it (the sampler's rays are the lens model's).
TEST(ScanDeformation, SamplesADepthMapWithNormalsTowardsTheCamera) {
  for (const double k1 : {0.0, -0.2}) {
    CameraIntrinsics camera;
    camera.width = 64;
    camera.height = 48;
    camera.fx = camera.fy = 100.0;
    camera.cx = 31.5;
    camera.cy = 23.5;
    camera.k1 = k1;
    // A plane tilted about y: z = 0.1 + 0.5 x, seen along each pixel's ray.
    Image32f depth(64, 48, 0.0f);
    for (int y = 0; y < 48; ++y) {
      for (int x = 0; x < 64; ++x) {
        Vec3T<double> ray;
        ASSERT_TRUE(unproject(camera, Vec2T<double>{static_cast<double>(x), static_cast<double>(y)}, &ray));
        depth(x, y) = static_cast<float>(0.1 / (1.0 - 0.5 * ray.x / ray.z));
      }
    }
    for (int y = 0; y < 48; ++y) depth(40, y) = 0.0f;  // a column without depth
    const SurfaceSamples samples = sample_depth_map(depth, camera, 100, 1e-2);  // 1 mm pixels
    ASSERT_GT(samples.points.size(), 40u) << k1;
    ASSERT_EQ(samples.points.size(), samples.normals.size());
    const Eigen::Vector3f expected = Eigen::Vector3f(0.5f, 0.0f, -1.0f).normalized();
    for (std::size_t i = 0; i < samples.points.size(); ++i) {
      const Eigen::Vector3f& p = samples.points[i];
      EXPECT_NEAR(p.z(), 0.1f + 0.5f * p.x(), 1e-6f) << k1;
      EXPECT_GT(samples.normals[i].dot(expected), 0.9999f) << i << ", " << k1;
    }
    EXPECT_TRUE(sample_depth_map(Image32f(3, 3, 0.1f), camera, 100, 1e-2).points.empty());
  }
}

// A GPU's map comes to the host only in the rows the samples read, gathered one set after
// another: those rows alone give the same samples as the whole map, bit for bit, whatever the
// size and count; and a map with only those rows (the others NaN) gives them too, so the
// sampler reads no other row.
TEST(ScanDeformation, SamplesReadOnlyTheRowsTheyName) {
  for (const auto& [width, height, count] :
       {std::tuple{64, 48, 100}, std::tuple{64, 48, 5000}, std::tuple{97, 61, 37}, std::tuple{5, 5, 1},
        std::tuple{400, 300, 2048}, std::tuple{7, 200, 64}}) {
    CameraIntrinsics camera;
    camera.width = width;
    camera.height = height;
    camera.fx = camera.fy = 100.0;
    camera.cx = 0.5 * (width - 1);
    camera.cy = 0.5 * (height - 1);
    camera.k1 = -0.1;  // rays through the lens model, as a real camera's
    // A bumpy surface, so that every row and column differs.
    Image32f depth(width, height, 0.0f);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        depth(x, y) = static_cast<float>(0.1 + 1e-3 * std::sin(0.3 * x) * std::cos(0.2 * y) + 1e-4 * x);
      }
    }
    const DepthMapSampler sampler(camera, count);
    const std::vector<RowSet>& rows = sampler.rows();
    Image32f gathered;
    gathered.gather_rows_from(depth, rows);
    int copied = 0;
    for (const RowSet& set : rows) copied += set.count;
    EXPECT_EQ(gathered.height(), copied);
    EXPECT_LE(copied, 3 * (height / 3 + 1)) << width << "x" << height;
    // Only those rows in place in a map of NaN.
    Image32f only_rows(width, height, std::numeric_limits<float>::quiet_NaN());
    int row = 0;
    for (const RowSet& set : rows) {
      for (int k = 0; k < set.count; ++k, ++row) {
        for (int x = 0; x < width; ++x) only_rows(x, set.first + k * set.step) = gathered(x, row);
      }
    }
    const SurfaceSamples all = sample_depth_map(depth, camera, count, 1e-2);
    EXPECT_FALSE(all.points.empty()) << width << "x" << height << ", " << count;
    for (const SurfaceSamples& some :
         {sampler.sample(depth, 1e-2), sampler.sample_gathered(gathered, 1e-2), sampler.sample(only_rows, 1e-2)}) {
      ASSERT_EQ(all.points.size(), some.points.size()) << width << "x" << height << ", " << count;
      for (std::size_t i = 0; i < all.points.size(); ++i) {
        EXPECT_EQ(all.points[i], some.points[i]);
        EXPECT_EQ(all.normals[i], some.normals[i]);
      }
    }
    // A map or rows of another size are refused, naming it.
    EXPECT_THROW(sampler.sample(Image32f(width + 1, height, 0.1f), 1e-2), Error);
    EXPECT_THROW(sampler.sample_gathered(depth, 1e-2), Error);
  }
  const auto rows_of = [](int width, int height, int count) {
    CameraIntrinsics camera;
    camera.width = width;
    camera.height = height;
    camera.fx = camera.fy = 100.0;
    return DepthMapSampler(camera, count).rows();
  };
  EXPECT_TRUE(rows_of(4, 48, 100).empty());
  EXPECT_TRUE(rows_of(64, 48, 0).empty());
}

}  // namespace
}  // namespace sls::session
