// Issue 20's acceptance for replay:// devices, in C++: a simulated recording captured through the
// replay camera, projector and turntable (session::capture_from_devices, what `sls scan
// --camera` and sls_scan_run_devices run) and scanned gives the very model of scanning the
// recording itself: the same cloud and mesh bytes, the same trajectory.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/session/scan_session.h"
#include "sdk/session/scan_setup.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

struct Model {
  std::string cloud;
  std::string mesh;
  std::vector<StampedPose> trajectory;
};

Model scan(const std::string& folder) {
  const RecordingReader recording = session::open_recording_for_scan(folder);
  session::ScanSessionOptions options;
  options.device = Device::cpu();
  options.turntable_prior = true;  // depth alone cannot follow the knob's 120 degree steps
  session::ScanSession session = session::make_recording_session(recording, options);
  const session::ReplayOutcome outcome = session::run_recording(session, recording);
  EXPECT_FALSE(outcome.interrupted) << outcome.interruption;
  EXPECT_EQ(session.fused_count(), recording.frame_count());
  const fusion::ExtractedSurface surface = session.final_surface();
  return {encode_ply(surface.cloud), encode_ply(surface.mesh), session.trajectory()};
}

TEST(ReplayScan, AScanThroughReplayDevicesIsBitIdenticalToScanningTheRecording) {
  test::TemporaryDirectory dir;
  const std::string original = dir.file("rec");
  sim::SimRecordingOptions simulated;
  simulated.object = "knurled-knob";
  simulated.rig.preset = "ci";
  simulated.rig.frames = 3;
  simulated.reference_spacing_m = 1e-3;  // ground truth is not what this test reads
  sim::write_sim_recording(original, simulated, Device::cpu(), {});

  session::DeviceCaptureRequest request;
  request.camera_uri = request.projector_uri = request.turntable_uri = "replay://" + original;
  request.calibration_path = original + "/calibration.yml";
  request.frames = 3;
  const session::DeviceCapture captured = session::capture_from_devices(dir.file("copy"), request);
  EXPECT_EQ(captured.statistics.frames, 3);
  EXPECT_EQ(captured.statistics.retries, 0);
  EXPECT_TRUE(captured.calibrated);

  const Model direct = scan(original);
  const Model replayed = scan(dir.file("copy"));
  EXPECT_GT(direct.cloud.size(), 1000u);
  EXPECT_TRUE(direct.cloud == replayed.cloud) << "cloud bytes differ";
  EXPECT_TRUE(direct.mesh == replayed.mesh) << "mesh bytes differ";
  ASSERT_EQ(direct.trajectory.size(), replayed.trajectory.size());
  for (std::size_t i = 0; i < direct.trajectory.size(); ++i) {
    EXPECT_EQ(direct.trajectory[i].timestamp_s, replayed.trajectory[i].timestamp_s);
    EXPECT_TRUE(direct.trajectory[i].T_world_camera.matrix() == replayed.trajectory[i].T_world_camera.matrix());
  }
}

}  // namespace
}  // namespace sls
