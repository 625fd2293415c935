// Issue 20's acceptance for replay:// devices, in C++: a simulated recording captured through the
// replay camera, projector and turntable (session::capture_from_devices, what `sls scan
// --camera` and sls_scan_run_devices run) and scanned gives the very model of scanning the
// recording itself: the same cloud and mesh bytes, the same trajectory.
#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/session/frame_pipeline.h"
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

// A simulated ci-preset recording of the knurled knob at `folder`, `frames` a revolution, and
// the capture of it through the replay camera, projector and turntable.
session::DeviceCaptureRequest knob_through_replay(const std::string& folder, int frames) {
  sim::SimRecordingOptions simulated;
  simulated.object = "knurled-knob";
  simulated.rig.preset = "ci";
  simulated.rig.frames = frames;
  simulated.reference_spacing_m = 1e-3;  // ground truth is not what these tests read
  sim::write_sim_recording(folder, simulated, Device::cpu(), {});
  session::DeviceCaptureRequest request;
  request.camera_uri = request.projector_uri = request.turntable_uri = "replay://" + folder;
  request.calibration_path = folder + "/calibration.yml";
  request.frames = frames;
  return request;
}

TEST(ReplayScan, AScanThroughReplayDevicesIsBitIdenticalToScanningTheRecording) {
  test::TemporaryDirectory dir;
  const std::string original = dir.file("rec");
  const session::DeviceCaptureRequest request = knob_through_replay(original, 3);
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

// Fused while capturing (issue 18): each frame handed to the session as the replay devices'
// capture records it (session::captured_frames through run_pipeline), the session made at the
// first frame, gives the very model of scanning the finished recording, and a cancel while
// fusing ends the capture after the frame it recorded, keeping a valid recording.
TEST(ReplayScan, FusingWhileCapturingIsBitIdenticalToScanningTheRecording) {
  test::TemporaryDirectory dir;
  const std::string original = dir.file("rec");
  const session::DeviceCaptureRequest request = knob_through_replay(original, 4);
  session::ScanSessionOptions options;
  options.device = Device::cpu();
  options.turntable_prior = true;

  const std::string live_folder = dir.file("live");
  std::optional<RecordingReader> recording;
  std::optional<session::ScanSession> session;
  const auto make_session = [&]() -> session::ScanSession& {
    recording.emplace(session::open_recording_for_scan(live_folder));
    session.emplace(session::make_recording_session(*recording, options));
    return *session;
  };
  int recorded_when_made = -1;
  const session::PipelineOutcome outcome = session::run_pipeline(
      [&]() -> session::ScanSession& {
        session::ScanSession& made = make_session();
        recorded_when_made = static_cast<int>(recording->frame_count());
        return made;
      },
      session::captured_frames(live_folder,
                               [&](const session::RecordedFrame& recorded) {
                                 session::capture_from_devices(live_folder, request, {}, recorded);
                               }),
      session::PipelineOptions{});
  EXPECT_FALSE(outcome.interrupted) << outcome.interruption;
  EXPECT_EQ(outcome.delivered, 4u);
  // Made at the first frame from the recording the capture had created (its description and
  // calibration; the frame itself may still be with the recording's writer thread).
  EXPECT_GE(recorded_when_made, 0);
  EXPECT_LE(recorded_when_made, 4);
  ASSERT_TRUE(session.has_value());
  EXPECT_EQ(session->fused_count(), 4u);
  const fusion::ExtractedSurface surface = session->final_surface();
  const Model direct = scan(original);
  EXPECT_TRUE(direct.cloud == encode_ply(surface.cloud)) << "cloud bytes differ";
  EXPECT_TRUE(direct.mesh == encode_ply(surface.mesh)) << "mesh bytes differ";
  const std::vector<StampedPose> trajectory = session->trajectory();
  ASSERT_EQ(direct.trajectory.size(), trajectory.size());
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    EXPECT_TRUE(direct.trajectory[i].T_world_camera.matrix() == trajectory[i].T_world_camera.matrix());
  }

  // A cancel while fusing: the capture stops after the frame it had recorded when told (with a
  // queue of one: frame 1 queued, frame 2 waiting to be handed over).
  session::PipelineOptions one_frame_queue;
  one_frame_queue.queue_frames = 1;
  const std::string cancelled_folder = dir.file("cancelled");
  std::optional<session::ScanSession> cancelled;
  const session::PipelineOutcome stopped = session::run_pipeline(
      [&]() -> session::ScanSession& {
        cancelled.emplace(session::make_recording_session(session::open_recording_for_scan(cancelled_folder), options));
        return *cancelled;
      },
      session::captured_frames(cancelled_folder,
                               [&](const session::RecordedFrame& recorded) {
                                 session::capture_from_devices(cancelled_folder, request, {}, recorded);
                               }),
      one_frame_queue, {}, [](const ProgressUpdate& update) { return update.done < 1; });
  EXPECT_TRUE(stopped.interrupted);
  ASSERT_TRUE(cancelled.has_value());
  EXPECT_EQ(cancelled->fused_count(), 1u);
  const RecordingReader kept = RecordingReader::open(cancelled_folder);
  EXPECT_GE(kept.frame_count(), 1u);
  EXPECT_LE(kept.frame_count(), 3u);  // the capture did not run on to the end
}

}  // namespace
}  // namespace sls
