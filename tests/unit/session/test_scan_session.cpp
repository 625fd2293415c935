// The scan session against the simulated scanner's ground truth: tracked poses against the
// true ones, the turntable prior's sign and axis, the photometric term on the stacks' textures,
// bad frames reported and skipped, an interrupted replay keeping a valid model (CPU against
// CUDA: test_scan_session_cuda.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/core/recording.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_session.h"
#include "tests/support/test_support.h"
#include "tests/unit/session/sim_frames.h"

namespace sls::session {
namespace {

TEST(TurntableMotion, MatchesTheSimulatorsTrueRelativePoses) {
  sim::RigOptions rig_options;
  rig_options.preset = "ci";
  rig_options.frames = 36;
  rig_options.mount_tilt_deg = 0.0;
  rig_options.mount_offset_m = 0.0;
  rig_options.angle_jitter_deg = 0.0;
  const std::shared_ptr<sim::SimScanner> scanner = sim::SimScanner::create("knurled-screw", rig_options, Device::cpu());
  const sim::SimRig& rig = scanner->rig();
  const ScannerCalibration calibration = rig.calibration();
  ASSERT_TRUE(calibration.turntable.has_value());
  for (int k : {1, 5, 20}) {
    const Pose truth = rig.T_object_camera(0).inverse() * rig.T_object_camera(k);
    const Pose predicted = turntable_camera_motion(*calibration.turntable, rig.commanded_angle_deg(k) -
                                                                              rig.commanded_angle_deg(0));
    const Pose error = truth.inverse() * predicted;
    EXPECT_LT(error.translation().norm(), 1e-9) << "frame " << k;
    EXPECT_LT(error.angle_rad(), 1e-9) << "frame " << k;
  }
}

// Depth alone, 1 degree steps (0.3 mm on the knurled knob's 1 mm tooth pitch: well inside the
// half tooth beyond which the first step, guessed with no velocity, locks onto the wrong
// tooth): every frame registers, and the tracked motion matches the true one.
TEST(ScanSession, TracksATurntableScanFromDepthAlone) {
  SimFrames sim("knurled-knob", 360);
  ScanSession session(sim.calibration(), nullptr, small_options(Device::cpu()));
  const int frames = 8;
  for (int k = 0; k < frames; ++k) {
    const FrameReport report = session.add_frame(sim.frame(k));
    ASSERT_EQ(report.status, FrameStatus::kFused) << "frame " << k << ": " << report.reason;
    if (k > 0) {
      ASSERT_TRUE(report.tracking.has_value());
      EXPECT_GT(report.tracking->inlier_fraction, 0.5) << "frame " << k;
    }
  }
  const std::vector<StampedPose> trajectory = session.trajectory();
  ASSERT_EQ(trajectory.size(), static_cast<std::size_t>(frames));
  EXPECT_TRUE(trajectory[0].T_world_camera.is_approx(Pose::identity()));
  double worst_surface = 0.0;
  for (int k = 1; k < frames; ++k) {
    const std::size_t i = static_cast<std::size_t>(k);
    worst_surface = std::max(worst_surface, relative_error(trajectory[0].T_world_camera, trajectory[i].T_world_camera,
                                                           sim.truth(0), sim.truth(i))
                                                .surface_m);
  }
  std::printf("[ measured ] knob, 7 tracked steps of 1 deg: worst error of the surface in view %.2f um\n",
              worst_surface * 1e6);
  // A third of a 30 µm pixel.
  EXPECT_LT(worst_surface, 10e-6);
  const fusion::ExtractedSurface model = session.final_surface();
  EXPECT_GT(model.cloud.size(), 5000u);
  EXPECT_FALSE(model.mesh.faces.empty());
}

TEST(ScanSession, BadFramesAreReportedAndTheScanGoesOn) {
  SimFrames sim("knurled-knob", 1440);  // quarter-degree steps
  ScanSession session(sim.calibration(), nullptr, small_options(Device::cpu()));
  EXPECT_EQ(session.add_frame(sim.frame(0)).status, FrameStatus::kFused);

  ScanFrame unreadable = sim.frame(1);
  unreadable.depth_m.reset();
  unreadable.problem = "cannot read: frames/000001/depth.png: truncated";
  FrameReport report = session.add_frame(unreadable);
  EXPECT_EQ(report.status, FrameStatus::kSkipped);
  EXPECT_NE(report.reason.find("truncated"), std::string::npos);

  ScanFrame wrong_size = sim.frame(2);
  wrong_size.depth_m = Image32f(10, 10);
  report = session.add_frame(wrong_size);
  EXPECT_EQ(report.status, FrameStatus::kSkipped);
  EXPECT_NE(report.reason.find("10x10"), std::string::npos) << report.reason;

  ScanFrame empty = sim.frame(3);
  std::fill(empty.depth_m->data(), empty.depth_m->data() + empty.depth_m->pixel_count(), 0.0f);
  report = session.add_frame(empty);
  EXPECT_EQ(report.status, FrameStatus::kSkipped);

  // A view of something else entirely (the surface 3 mm nearer, tilted): the tracker cannot
  // register it, the frame is lost and the model is not touched.
  ScanFrame alien = sim.frame(4);
  for (int y = 0; y < alien.depth_m->height(); ++y) {
    for (int x = 0; x < alien.depth_m->width(); ++x) {
      float& z = (*alien.depth_m)(x, y);
      if (z > 0.0f) z = 0.097f + 2e-5f * static_cast<float>(x);
    }
  }
  report = session.add_frame(alien);
  EXPECT_EQ(report.status, FrameStatus::kLost);
  EXPECT_FALSE(report.reason.empty());

  // The scan goes on: frame 5 registers (1.25 degrees past the last fused frame, guessed
  // with no velocity yet: under half a tooth of the knurl).
  report = session.add_frame(sim.frame(5));
  EXPECT_EQ(report.status, FrameStatus::kFused) << report.reason;
  EXPECT_EQ(session.fused_count(), 2u);
  EXPECT_EQ(session.frames().size(), 6u);
  const std::vector<StampedPose> trajectory = session.trajectory();
  ASSERT_EQ(trajectory.size(), 2u);
  EXPECT_LT(relative_error(trajectory[0].T_world_camera, trajectory[1].T_world_camera, sim.truth(0), sim.truth(5))
                .surface_m,
            10e-6);
}

TEST(ScanSession, TurntablePriorGuessesTheMotion) {
  // 10 degree steps: 2.8 of the screw's 3.56 degree teeth, which depth alone cannot tell apart
  // from -0.7 of one; the turntable's angle guesses the motion.
  SimFrames sim("knurled-screw", 36);
  ScanSessionOptions options = small_options(Device::cpu());
  options.turntable_prior = true;
  ScanSession session(sim.calibration(), nullptr, options);
  for (int k = 0; k < 3; ++k) {
    const FrameReport report = session.add_frame(sim.frame(k));
    ASSERT_EQ(report.status, FrameStatus::kFused) << "frame " << k << ": " << report.reason;
  }
  const std::vector<StampedPose> trajectory = session.trajectory();
  const RelativeError error =
      relative_error(trajectory[0].T_world_camera, trajectory[2].T_world_camera, sim.truth(0), sim.truth(2));
  std::printf("[ measured ] screw, 2 steps of 10 deg with the turntable prior: surface in view off by %.2f um\n",
              error.surface_m * 1e6);
  // One 30 µm pixel over two steps that each move the volume (a resampling each).
  EXPECT_LT(error.surface_m, 30e-6);
}

// Issue 19 item 11: at 15 degree steps depth alone cannot see the screw turn about its own axis;
// ICP converges with the rotation left at the guess. The turntable's angles expose it: the
// frame is lost with the figures, never fused at a wrong pose.
TEST(ScanSession, TrackingThatDisagreesWithTheTurntableIsLostNotFused) {
  SimFrames sim("knurled-screw", 24);
  ScanSession session(sim.calibration(), nullptr, small_options(Device::cpu()));
  ASSERT_EQ(session.add_frame(sim.frame(0)).status, FrameStatus::kFused);
  int disagreeing = 0;
  for (int k = 1; k < 4; ++k) {
    const FrameReport report = session.add_frame(sim.frame(k));
    if (report.status == FrameStatus::kLost && report.reason.find("disagrees with the turntable") != std::string::npos) {
      ++disagreeing;
      EXPECT_NE(report.reason.find("--turntable-prior"), std::string::npos) << report.reason;
    }
    // Whatever is fused is fused where the object is: the screw turned by the turntable.
    if (report.status == FrameStatus::kFused) {
      const std::vector<StampedPose> trajectory = session.trajectory();
      EXPECT_LT(relative_error(trajectory.front().T_world_camera, trajectory.back().T_world_camera, sim.truth(0),
                               sim.truth(static_cast<std::size_t>(k)))
                    .surface_m,
                100e-6)
          << "frame " << k;
    }
  }
  EXPECT_GT(disagreeing, 0);
}

// Issue 19 item 12: with the turntable prior, frames missing from a revolution (two skipped
// here: the next view is 45 degrees from the last fused one) must not lose the rest of the
// scan. The view too little overlapped to verify is fused at the prior and flagged; tracking
// verifies the views after it again.
TEST(ScanSession, AViewTooLittleOverlappedIsFusedAtThePriorFlaggedAndTheScanGoesOn) {
  SimFrames sim("knurled-screw", 24);
  ScanSessionOptions options = small_options(Device::cpu());
  options.turntable_prior = true;
  ScanSession session(sim.calibration(), nullptr, options);
  ASSERT_EQ(session.add_frame(sim.frame(0)).status, FrameStatus::kFused);
  ASSERT_EQ(session.add_frame(sim.frame(1)).status, FrameStatus::kFused);
  for (int k : {2, 3}) {
    ScanFrame stuck = sim.frame(k);
    stuck.depth_m.reset();
    stuck.problem = "pattern 17 stuck";
    ASSERT_EQ(session.add_frame(stuck).status, FrameStatus::kSkipped);
  }
  std::vector<bool> unverified;
  for (int k = 4; k < 8; ++k) {
    const FrameReport report = session.add_frame(sim.frame(k));
    ASSERT_EQ(report.status, FrameStatus::kFused) << "frame " << k << ": " << report.reason;
    unverified.push_back(report.unverified);
    if (report.unverified) {
      EXPECT_NE(report.reason.find("fused at the turntable prior"), std::string::npos) << report.reason;
    }
  }
  EXPECT_TRUE(unverified.front()) << "the view 45 degrees on";
  // At 15 degree steps on the ci camera a view overlaps the model by about a quarter, the least
  // tracking accepts: some later views still fall just short (23-25 %) and are flagged too.
  EXPECT_GT(std::count(unverified.begin() + 1, unverified.end(), false), 0) << "tracking verifies views again";
  const std::vector<StampedPose> trajectory = session.trajectory();
  ASSERT_EQ(trajectory.size(), 6u);
  EXPECT_LT(relative_error(trajectory.front().T_world_camera, trajectory.back().T_world_camera, sim.truth(0),
                           sim.truth(7))
                .surface_m,
            100e-6);
}

TEST(ScanSession, KnownPosesFuseIntoAFixedVolume) {
  SimFrames sim("knurled-screw", 36);
  ScanSessionOptions options = small_options(Device::cpu());
  options.fixed_volume = fusion::VolumeGeometry::centred(Eigen::Vector3d(16e-3, 0.0, 7.4e-3), 120, 300, 200, 50e-6);
  ScanSession session(sim.calibration(), nullptr, options);
  for (int k = 0; k < 2; ++k) {
    ScanFrame frame = sim.frame(k);
    frame.known_T_world_camera = sim.truth(static_cast<std::size_t>(k));
    const FrameReport report = session.add_frame(frame);
    ASSERT_EQ(report.status, FrameStatus::kFused) << report.reason;
    EXPECT_FALSE(report.tracking.has_value());
    EXPECT_TRUE(report.T_world_camera.is_approx(sim.truth(static_cast<std::size_t>(k))));
  }
  EXPECT_EQ(session.moves(), 0u);
  const fusion::ExtractedSurface model = session.final_surface();
  ASSERT_GT(model.cloud.size(), 1000u);
  // The screw's ridges lie on a 16.1 mm radius about the object's z axis.
  for (std::size_t i = 0; i < model.cloud.size(); i += 97) {
    const Eigen::Vector3f& p = model.cloud.positions[i];
    EXPECT_NEAR(std::hypot(p.x(), p.y()), 16.0e-3, 0.6e-3);
  }
}

TEST(ScanSession, AnInterruptedReplayKeepsAValidModel) {
  test::TemporaryDirectory dir;
  sim::SimRecordingOptions sim_options;
  sim_options.object = "knurled-knob";
  sim_options.rig.preset = "ci";
  sim_options.rig.frames = 180;
  sim_options.depth_mode = true;
  int captured = 0;
  try {
    sim::write_sim_recording(dir.file("rec"), sim_options, Device::cpu(), [&](const ProgressUpdate& update) {
      captured = static_cast<int>(update.done);
      return update.done < 4;
    });
  } catch (const Error& error) {
    ASSERT_EQ(error.code(), ErrorCode::kCancelled) << error.what();
  }
  const RecordingReader recording = RecordingReader::open(dir.file("rec"));
  ASSERT_EQ(recording.frame_count(), 4u);
  // The turntable's guess: depth alone turns the knob 3° wrong here, and the session then (rightly)
  // loses the frame for disagreeing with the turntable.
  ScanSessionOptions options = small_options(Device::cpu());
  options.turntable_prior = true;
  ScanSession session(recording.calibration(), nullptr, options);
  std::vector<FrameReport> seen;
  const ReplayOutcome outcome = run_recording(
      session, recording, nullptr, [&](const FrameReport& report) { seen.push_back(report); },
      [&](const ProgressUpdate& update) { return update.done < 2; });
  EXPECT_TRUE(outcome.interrupted);
  EXPECT_NE(outcome.interruption.find("cancelled"), std::string::npos) << outcome.interruption;
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(session.fused_count(), 2u) << seen[1].reason;
  EXPECT_GT(seen[1].times.read_ms, 0.0);
  const fusion::ExtractedSurface model = session.final_surface();
  EXPECT_GT(model.cloud.size(), 1000u);
  model.mesh.validate();
}

// The sliding chessboard (sim_frames.h) captured as pattern stacks: depth alone registers
// the plane but not the slide (it keeps the guess, and the constant-velocity prior learns
// nothing); with the photometric term on the texture the session derives from each stack
// (white − black) the slide is tracked. Frame 0 is the first reference (fused untracked:
// set_reference_frame), later ones the tracker keeps.
TEST(ScanSession, PhotometricTermTracksATexturedPlaneSlidingInItself) {
  const SlidingChessboard board;
  const ScannerCalibration calibration = board.rig.calibration();
  ScanSessionOptions options = small_options(Device::cpu());
  ScanSession depth_only(calibration, &board.rig.patterns, options);
  options.tracking.photometric_weight = 0.1;
  ScanSession textured(calibration, &board.rig.patterns, options);
  const int frames = 3;
  for (int k = 0; k < frames; ++k) {
    const ScanFrame frame = board.stack(k);
    const FrameReport a = depth_only.add_frame(frame);
    const FrameReport b = textured.add_frame(frame);
    ASSERT_EQ(a.status, FrameStatus::kFused) << "frame " << k << ": " << a.reason;
    ASSERT_EQ(b.status, FrameStatus::kFused) << "frame " << k << ": " << b.reason;
    if (k == 0) continue;
    ASSERT_TRUE(b.tracking.has_value());
    EXPECT_TRUE(b.tracking->photometric) << "frame " << k << ": " << b.tracking->photometric_skipped;
    EXPECT_EQ(b.tracking->degenerate_directions, 0) << "frame " << k;
    EXPECT_EQ(a.tracking->degenerate_directions, 3) << "frame " << k;
    EXPECT_FALSE(a.tracking->photometric);
  }
  const std::vector<StampedPose> a = depth_only.trajectory(), b = textured.trajectory();
  for (int k = 1; k < frames; ++k) {
    const std::size_t i = static_cast<std::size_t>(k);
    const double error_a =
        relative_error(a[0].T_world_camera, a[i].T_world_camera, board.truth(0), board.truth(k)).surface_m;
    const double error_b =
        relative_error(b[0].T_world_camera, b[i].T_world_camera, board.truth(0), board.truth(k)).surface_m;
    std::printf("[ measured ] chessboard slide, frame %d: surface in view off by %.2f um (depth alone: %.1f um)\n", k,
                error_b * 1e6, error_a * 1e6);
    EXPECT_GT(error_a, 80e-6 * k);  // the slide kept the guess
    EXPECT_LT(error_b, 5e-6);       // a seventh of a 37.5 um pixel
  }
}

// Depth-map frames: the texture comes with the frame (ScanFrame::texture); without one the
// term is off for that frame and the report says so; a texture of another size skips it.
TEST(ScanSession, PhotometricTermOnDepthFramesWithTextures) {
  const SlidingChessboard board;
  ScanSessionOptions options = small_options(Device::cpu());
  options.tracking.photometric_weight = 0.1;
  ScanSession session(board.rig.calibration(), nullptr, options);
  auto depth_frame = [&](int k, bool with_texture) {
    sim::Renderer renderer(board.rig_at(k), board.scene, Device::cpu());
    renderer.set_frame(0);
    ScanFrame frame;
    frame.index = k;
    frame.depth_m = renderer.render_depth();
    if (with_texture) {
      const Image16u white = renderer.render_pattern(0), black = renderer.render_pattern(1);  // the set's references
      Image32f texture(white.width(), white.height(), 0.0f);
      for (std::size_t i = 0; i < texture.pixel_count(); ++i) {
        texture.data()[i] = static_cast<float>(white.data()[i]) - static_cast<float>(black.data()[i]);
      }
      frame.texture = std::move(texture);
    }
    return frame;
  };
  ASSERT_EQ(board.rig.patterns.patterns[0].kind, PatternKind::kWhite);
  ASSERT_EQ(board.rig.patterns.patterns[1].kind, PatternKind::kBlack);
  EXPECT_EQ(session.add_frame(depth_frame(0, true)).status, FrameStatus::kFused);
  ScanFrame wrong = depth_frame(1, false);
  wrong.texture = Image32f(10, 10, 1.0f);
  FrameReport report = session.add_frame(wrong);
  EXPECT_EQ(report.status, FrameStatus::kSkipped);
  EXPECT_NE(report.reason.find("texture of 10x10"), std::string::npos) << report.reason;
  report = session.add_frame(depth_frame(1, true));
  ASSERT_EQ(report.status, FrameStatus::kFused) << report.reason;
  EXPECT_TRUE(report.tracking->photometric) << report.tracking->photometric_skipped;
  const std::vector<StampedPose> trajectory = session.trajectory();
  EXPECT_LT(relative_error(trajectory[0].T_world_camera, trajectory[1].T_world_camera, board.truth(0), board.truth(1))
                .surface_m,
            5e-6);
  report = session.add_frame(depth_frame(2, false));
  ASSERT_EQ(report.status, FrameStatus::kFused) << report.reason;
  EXPECT_FALSE(report.tracking->photometric);
  EXPECT_EQ(report.tracking->photometric_skipped, "no live texture");
}

TEST(ScanSession, OptionsAreChecked) {
  SimFrames sim("knurled-knob", 36);
  ScanSessionOptions options = small_options(Device::cpu());
  options.voxel_size_m = -1.0;
  EXPECT_THROW(ScanSession(sim.calibration(), nullptr, options), Error);
  options = small_options(Device::cpu());
  options.volume_size_m = Eigen::Vector3d(1e-3, -1.0, 1e-3);
  EXPECT_THROW(ScanSession(sim.calibration(), nullptr, options), Error);
  options = small_options(Device::cpu());
  options.tracking.photometric_weight = -1.0;
  EXPECT_THROW(ScanSession(sim.calibration(), nullptr, options), Error);
  // The turntable prior with a calibration that has no axis: refused, not silently off.
  options = small_options(Device::cpu());
  options.turntable_prior = true;
  ScannerCalibration no_axis = sim.calibration();
  no_axis.turntable.reset();
  try {
    ScanSession session(no_axis, nullptr, options);
    ADD_FAILURE() << "a prior without an axis was accepted";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("turntable axis"), std::string::npos) << error.what();
  }
  EXPECT_NO_THROW(ScanSession(sim.calibration(), nullptr, options));
}

// What a GPU memory budget leaves room for (sizing the moving volume under max_gpu_bytes): two
// buffers of compact GTSDF voxels (5 bytes each: U, W and the running average) and the
// integrator's lists, 32 bytes a voxel up to 2^25 voxels, then no more.
TEST(GpuBudget, LeavesRoomForBothBuffersAndTheIntegratorsLists) {
  ScanSessionOptions options;
  options.device = Device::cuda();
  EXPECT_TRUE(std::isinf(gpu_budget_voxels(options, 0.0, 0.0)));  // no budget
  options.max_gpu_bytes = 1e9;
  // 1 GB less 100 MB held and 100 MB to come: 800 MB for 10 + 32 bytes a voxel.
  EXPECT_NEAR(gpu_budget_voxels(options, 100e6, 100e6), 800e6 / 42.0, 1.0);
  // Past 2^25 voxels the lists stop growing.
  options.max_gpu_bytes = 20e9;
  const double lists = 32.0 * static_cast<double>(std::size_t{1} << 25);
  EXPECT_NEAR(gpu_budget_voxels(options, 1e9, 1e9), (18e9 - lists) / 10.0, 1.0);
  // TSDF keeps no lists and no separate average: 3 bytes a voxel, two buffers.
  options.integration = fusion::IntegrationOptions::tsdf();
  EXPECT_NEAR(gpu_budget_voxels(options, 1e9, 1e9), 18e9 / 6.0, 1.0);
  // Nothing left: no voxels. On the CPU the budget does not apply.
  EXPECT_EQ(gpu_budget_voxels(options, 19e9, 2e9), 0.0);
  options.device = Device::cpu();
  EXPECT_TRUE(std::isinf(gpu_budget_voxels(options, 19e9, 2e9)));
  // A budget must be 0 (none) or positive and finite.
  options.max_gpu_bytes = -1.0;
  EXPECT_THROW(options.validate(), Error);
}

}  // namespace
}  // namespace sls::session
