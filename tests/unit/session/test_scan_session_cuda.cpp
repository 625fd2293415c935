// The scan session on a CUDA GPU equals the CPU session (poses, moves); skips with no GPU.
#include <gtest/gtest.h>

#include "sdk/session/scan_session.h"
#include "tests/support/test_support.h"
#include "tests/unit/session/sim_frames.h"

namespace sls::session {
namespace {

TEST(ScanSessionCuda, EqualsTheCpuSession) {
  SLS_REQUIRE_CUDA_DEVICE();
  SimFrames sim("knurled-knob", 240);  // 1.5 degree steps: under half a knurl tooth
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

}  // namespace
}  // namespace sls::session
