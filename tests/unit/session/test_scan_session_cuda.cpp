// The scan session on a CUDA GPU equals the CPU session (poses, moves); skips with no GPU.
#include <gtest/gtest.h>


#include "fusion/integrator.h"
#include "fusion/moving_volume.h"
#include "fusion/raycaster.h"
#include "fusion/tracker.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_session.h"
#include "tests/support/test_support.h"
#include "tests/unit/session/sim_frames.h"

namespace sls::session {
namespace {

// The session's stages one by one on both backends (what EqualsTheCpuSession chains): the
// model raycast after one frame, then the tracker on it, host maps and device maps.
class ScanSessionStagesCuda : public ::testing::TestWithParam<Eigen::Vector3i> {};

TEST_P(ScanSessionStagesCuda, EqualTheCpuOnes) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Eigen::Vector3i counts = GetParam();
  SimFrames sim("knurled-knob", 360);
  const ScannerCalibration calibration = sim.calibration();
  const CameraIntrinsics& camera = calibration.camera;
  const ScanFrame first = sim.frame(0), second = sim.frame(1);
  fusion::MovingVolumeOptions moving;
  moving.focus_distance_m = 0.1;
  const double voxel = 12e-3 / counts.x();
  fusion::MovingVolume cpu_volume(counts.x(), counts.y(), counts.z(), voxel, fusion::VoxelFormat::kCompact,
                                  Device::cpu(), moving, fusion::AverageStorage::kSeparate);
  fusion::MovingVolume gpu_volume(counts.x(), counts.y(), counts.z(), voxel, fusion::VoxelFormat::kCompact,
                                  Device::cuda(), moving, fusion::AverageStorage::kSeparate);
  cpu_volume.place(Pose());
  gpu_volume.place(Pose());
  fusion::Integrator cpu_integrator(Device::cpu(), fusion::IntegrationOptions::gtsdf());
  fusion::Integrator gpu_integrator(Device::cuda(), fusion::IntegrationOptions::gtsdf());
  cpu_integrator.integrate(cpu_volume.volume(), *first.depth_m, camera, Pose());
  gpu_integrator.integrate(gpu_volume.volume(), *first.depth_m, camera, Pose());
  fusion::RaycastOptions raycast_options;
  raycast_options.min_depth_m = 1e-3;
  fusion::Raycaster cpu_raycaster(Device::cpu(), camera, raycast_options);
  fusion::Raycaster gpu_raycaster(Device::cuda(), camera, raycast_options);
  const fusion::RaycastResult cpu_model = cpu_raycaster.raycast(cpu_volume.volume(), Pose());
  const fusion::RaycastResult gpu_model = gpu_raycaster.raycast(gpu_volume.volume(), Pose());
  std::size_t cpu_hits = 0, gpu_hits = 0, both = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < cpu_model.depth_m.pixel_count(); ++i) {
    const float a = cpu_model.depth_m.data()[i], b = gpu_model.depth_m.data()[i];
    cpu_hits += a > 0.0f;
    gpu_hits += b > 0.0f;
    if (a > 0.0f && b > 0.0f) {
      ++both;
      worst = std::max(worst, static_cast<double>(std::fabs(a - b)));
    }
  }
  std::printf("[ measured ] model raycast: cpu %zu hits, cuda %zu, both %zu, worst |dz| %.3f um\n", cpu_hits,
              gpu_hits, both, worst * 1e6);
  EXPECT_NEAR(static_cast<double>(gpu_hits), static_cast<double>(cpu_hits), 1e-3 * static_cast<double>(cpu_hits));
  EXPECT_LT(worst, 0.25 * voxel);  // GTSDF sweeps in float on both, in another order of work

  fusion::Tracker cpu_tracker(Device::cpu(), camera);
  fusion::Tracker gpu_tracker(Device::cuda(), camera);
  const fusion::TrackingResult a = cpu_tracker.track(*second.depth_m, cpu_model, Pose(), Pose());
  const fusion::TrackingResult b = gpu_tracker.track(*second.depth_m, gpu_model, Pose(), Pose());
  fusion::RaycastResult device_model(MemoryType::kDevice);
  gpu_raycaster.raycast(gpu_volume.volume(), Pose(), device_model);
  const Image32f live = second.depth_m->copy_to(MemoryType::kDevice);
  gpu_raycaster.synchronize();
  const fusion::TrackingResult c = gpu_tracker.track(live, device_model, Pose(), Pose());
  for (const auto* r : {&a, &b, &c}) {
    std::printf("[ measured ] %s: lost %d (%s) inliers %zu rms %.2f um it %d\n",
                r == &a ? "cpu" : (r == &b ? "cuda, host maps" : "cuda, device maps"), r->lost ? 1 : 0,
                r->reason.c_str(), r->inliers, r->residual_rms_m * 1e6, r->iterations);
  }
  EXPECT_FALSE(a.lost);
  EXPECT_EQ(a.lost, b.lost);
  EXPECT_EQ(a.lost, c.lost);
  EXPECT_LT((a.T_world_camera.inverse() * b.T_world_camera).translation().norm(), 2e-6);
  EXPECT_LT((a.T_world_camera.inverse() * c.T_world_camera).translation().norm(), 2e-6);
}

// Whole bricks of 8 voxels, and partial ones at the far faces.
INSTANTIATE_TEST_SUITE_P(Volumes, ScanSessionStagesCuda,
                         ::testing::Values(Eigen::Vector3i(240, 180, 120), Eigen::Vector3i(200, 150, 100)));

TEST(ScanSessionCuda, EqualsTheCpuSession) {
  SLS_REQUIRE_CUDA_DEVICE();
  SimFrames sim("knurled-knob", 360);  // 1 degree steps: under a third of a knurl tooth
  ScanSession cpu(sim.calibration(), nullptr, small_options(Device::cpu()));
  ScanSession cuda(sim.calibration(), nullptr, small_options(Device::cuda()));
  for (int k = 0; k < 6; ++k) {
    const ScanFrame frame = sim.frame(k);
    const FrameReport a = cpu.add_frame(frame);
    const FrameReport b = cuda.add_frame(frame);
    ASSERT_EQ(a.status, b.status) << "frame " << k << ": " << a.reason << " / " << b.reason;
    const Pose difference = a.T_world_camera.inverse() * b.T_world_camera;
    EXPECT_LT(difference.translation().norm(), 2e-6) << "frame " << k;
    EXPECT_LT(difference.angle_rad(), 2e-5) << "frame " << k;
  }
  EXPECT_EQ(cpu.moves(), cuda.moves());
}

// The photometric term in a CUDA session (the texture uploaded once, the reference frames on
// the GPU) equals the CPU session's: the sliding chessboard from pattern stacks.
TEST(ScanSessionCuda, PhotometricEqualsTheCpuSession) {
  SLS_REQUIRE_CUDA_DEVICE();
  const SlidingChessboard board;
  ScanSessionOptions options = small_options(Device::cpu());
  options.tracking.photometric_weight = 0.1;
  ScanSession cpu(board.rig.calibration(), &board.rig.patterns, options);
  options.device = Device::cuda();
  ScanSession cuda(board.rig.calibration(), &board.rig.patterns, options);
  for (int k = 0; k < 3; ++k) {
    const ScanFrame frame = board.stack(k);
    const FrameReport a = cpu.add_frame(frame);
    const FrameReport b = cuda.add_frame(frame);
    ASSERT_EQ(a.status, b.status) << "frame " << k << ": " << a.reason << " / " << b.reason;
    ASSERT_EQ(b.status, FrameStatus::kFused) << b.reason;
    if (k > 0) {
      EXPECT_TRUE(b.tracking->photometric) << b.tracking->photometric_skipped;
      EXPECT_EQ(a.tracking->photometric, b.tracking->photometric);
    }
    const Pose difference = a.T_world_camera.inverse() * b.T_world_camera;
    EXPECT_LT(difference.translation().norm(), 2e-6) << "frame " << k;
    EXPECT_LT(difference.angle_rad(), 2e-5) << "frame " << k;
  }
}

// Fusing through the pipeline on a GPU uploads each next stack while the frame before is fused
// (ScanSession::prefetch on a thread of its own): the same poses and model as frames added one
// by one, each uploading its own stack. A stale or foreign stack would move a pose by far more
// than the GPU's rounding.
TEST(ScanSessionCuda, UploadsAheadThroughThePipelineGiveTheSequentialRun) {
  SLS_REQUIRE_CUDA_DEVICE();
  const SlidingChessboard board;
  std::vector<ScanFrame> frames;
  for (int k = 0; k < 5; ++k) frames.push_back(board.stack(k));
  ScanSession sequential(board.rig.calibration(), &board.rig.patterns, small_options(Device::cuda()));
  for (const ScanFrame& frame : frames) ASSERT_EQ(sequential.add_frame(frame).status, FrameStatus::kFused);
  ScanSession piped(board.rig.calibration(), &board.rig.patterns, small_options(Device::cuda()));
  EXPECT_TRUE(piped.uploads_ahead());
  const PipelineOutcome outcome = run_pipeline(piped, [&frames](const FrameDelivery& deliver) {
    for (const ScanFrame& frame : frames) {
      ScanFrame copy = frame;
      if (!deliver(std::move(copy))) return;
    }
  }, PipelineOptions{});
  ASSERT_FALSE(outcome.interrupted) << outcome.interruption;
  ASSERT_EQ(piped.frames().size(), frames.size());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const FrameReport& a = sequential.frames()[k];
    const FrameReport& b = piped.frames()[k];
    ASSERT_EQ(b.status, FrameStatus::kFused) << b.reason;
    EXPECT_EQ(a.depth_pixels, b.depth_pixels) << "frame " << k;
    const Pose difference = a.T_world_camera.inverse() * b.T_world_camera;
    EXPECT_LT(difference.translation().norm(), 1e-9) << "frame " << k;
    EXPECT_LT(difference.angle_rad(), 1e-9) << "frame " << k;
  }
  EXPECT_EQ(piped.final_surface().cloud.size(), sequential.final_surface().cloud.size());
  // A CPU session has nothing to upload ahead.
  ScanSession cpu(board.rig.calibration(), &board.rig.patterns, small_options(Device::cpu()));
  EXPECT_FALSE(cpu.uploads_ahead());
  EXPECT_FALSE(cpu.prefetch(frames[0]));
}

// A GPU memory budget (ScanSessionOptions::max_gpu_bytes) sizes the moving volume: a given voxel
// size is kept and the extent shrinks, so that everything slscan allocates stays within it; a
// budget with no room for 64 voxels a side is refused at the first frame, saying so.
TEST(ScanSessionCuda, AGpuMemoryBudgetSizesTheVolumeToFit) {
  SLS_REQUIRE_CUDA_DEVICE();
  SimFrames sim("knurled-knob", 360);
  std::vector<ScanFrame> frames;
  for (int k = 0; k < 4; ++k) frames.push_back(sim.frame(k));
  ScanSessionOptions options = small_options(Device::cuda());
  options.voxel_size_m = 30e-6;
  options.volume_size_m = Eigen::Vector3d(0.012, 0.009, 0.006);  // 400 x 300 x 200 voxels
  const auto run = [&frames](const ScanSessionOptions& o, const ScannerCalibration& calibration) {
    ScanSession session(calibration, nullptr, o);
    for (const ScanFrame& frame : frames) EXPECT_EQ(session.add_frame(frame).status, FrameStatus::kFused);
    return std::make_pair(session.volume_bytes(), session.volume_geometry());
  };
  const std::size_t held = gpu_allocations().in_use_bytes;
  reset_gpu_allocation_peak();
  const auto [free_bytes, free_geometry] = run(options, sim.calibration());
  const std::size_t free_peak = gpu_allocations().peak_bytes;
  ASSERT_EQ(free_geometry.nx, 400);

  // Half the volume's memory taken from what the unconstrained scan allocated at most.
  options.max_gpu_bytes = static_cast<double>(free_peak - free_bytes / 2);
  reset_gpu_allocation_peak();
  const auto [budget_bytes, budget_geometry] = run(options, sim.calibration());
  const std::size_t budget_peak = gpu_allocations().peak_bytes;
  std::printf("[ measured ] held before %.1f MB; unconstrained: volume %.1f MB, peak %.1f MB; budget %.1f MB: "
              "volume %.1f MB (%dx%dx%d), peak %.1f MB\n",
              static_cast<double>(held) * 1e-6, static_cast<double>(free_bytes) * 1e-6,
              static_cast<double>(free_peak) * 1e-6, options.max_gpu_bytes * 1e-6,
              static_cast<double>(budget_bytes) * 1e-6, budget_geometry.nx, budget_geometry.ny, budget_geometry.nz,
              static_cast<double>(budget_peak) * 1e-6);
  EXPECT_EQ(budget_geometry.voxel_size_m, 30e-6);
  EXPECT_LT(budget_geometry.nx, 400);
  EXPECT_LT(budget_bytes, free_bytes);
  EXPECT_GT(budget_bytes, free_bytes / 10);  // not shrunk beyond need
  EXPECT_LE(static_cast<double>(budget_peak), options.max_gpu_bytes);

  options.max_gpu_bytes = static_cast<double>(held) + 1e6;
  ScanSession starved(sim.calibration(), nullptr, options);
  try {
    starved.add_frame(frames[0]);
    ADD_FAILURE() << "a scan with no room for its volume started";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kOutOfMemory) << e.what();
    EXPECT_NE(std::string(e.what()).find("GPU memory budget of"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("64 a side"), std::string::npos) << e.what();
  }
}

// Online deformation and the loop closure on a CUDA session (the last frame kept on the GPU,
// the first frame's surface raycast by a raycaster of its own, the registration on device
// maps) against the CPU session: a turntable revolution of the knob at the ci preset.
TEST(ScanSessionCuda, LoopClosureEqualsTheCpuSession) {
  SLS_REQUIRE_CUDA_DEVICE();
  SimFrames sim("knurled-knob", 36);
  ScanSessionOptions options = small_options(Device::cpu());
  options.turntable_prior = true;
  ScanSession cpu(sim.calibration(), nullptr, options);
  options.device = Device::cuda();
  ScanSession cuda(sim.calibration(), nullptr, options);
  for (int k = 0; k < 36; ++k) {
    const ScanFrame frame = sim.frame(k);
    ASSERT_EQ(cpu.add_frame(frame).status, FrameStatus::kFused) << "frame " << k;
    ASSERT_EQ(cuda.add_frame(frame).status, FrameStatus::kFused) << "frame " << k;
  }
  const LoopClosureReport a = cpu.close_loop();
  const LoopClosureReport b = cuda.close_loop();
  std::printf("[ measured ] registration cpu %zu inliers, cuda %zu; last pose correction %.2f / %.2f um\n",
              a.registration.inliers, b.registration.inliers, a.correction_m * 1e6, b.correction_m * 1e6);
  // The tracked revolutions differ by what CPU and CUDA arithmetic leave after 36 frames
  // (micrometres): the closed last poses agree to that, far below the loop's correction.
  const Pose tracked_difference =
      cpu.trajectory_undeformed().back().T_world_camera.inverse() * cuda.trajectory_undeformed().back().T_world_camera;
  const Pose registered_difference = a.registration.T_world_camera.inverse() * b.registration.T_world_camera;
  const Pose closed_difference = cpu.trajectory().back().T_world_camera.inverse() * cuda.trajectory().back().T_world_camera;
  std::printf("[ measured ] cpu vs cuda: tracked last pose %.2f um, registered %.2f um, closed %.2f um\n",
              tracked_difference.translation().norm() * 1e6, registered_difference.translation().norm() * 1e6,
              closed_difference.translation().norm() * 1e6);
  EXPECT_EQ(a.constraints > 0, b.constraints > 0);
  EXPECT_LT(registered_difference.translation().norm(), 5e-6);
  EXPECT_LT(closed_difference.translation().norm(), 0.1 * a.correction_m);
  // The volume's own surface was found beside the loop closure (MovingVolume::
  // prepare_final_surface): the model is the one found when asked again, bit for bit.
  ModelTimes beside, asked_times;
  const fusion::ExtractedSurface prepared = cuda.final_surface(&beside);
  const fusion::ExtractedSurface asked = cuda.final_surface(&asked_times);
  EXPECT_TRUE(beside.volume.prepared);
  EXPECT_FALSE(asked_times.volume.prepared);
  EXPECT_NE(prepared.cloud.find_property("correction"), nullptr);
  EXPECT_GT(prepared.cloud.size(), 1000u);
  EXPECT_EQ(prepared.cloud.positions, asked.cloud.positions);
  EXPECT_EQ(prepared.cloud.normals, asked.cloud.normals);
  EXPECT_EQ(prepared.mesh.faces, asked.mesh.faces);
}

}  // namespace
}  // namespace sls::session
