// Capturing for `sls sim` and `sls scan` (--sim, --camera): a SIGINT or SIGTERM stops a
// capture after the current frame, keeping a valid recording, and a capture that was cut
// off (a signal, kill -9, a device error) is resumed into the same recording.
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sdk/core/device.h"
#include "sdk/core/progress.h"
#include "sdk/core/recording.h"
#include "sdk/core/recording_writer_thread.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_setup.h"

namespace sls::cli {

// While alive, the first SIGINT or SIGTERM asks the work to stop after the current frame (a
// second one ends the process at once, as without it: every frame is flushed as it is
// written, so the recording stays valid and resumable). Restores the previous handlers.
class StopOnSignal {
 public:
  StopOnSignal();
  ~StopOnSignal();
  StopOnSignal(const StopOnSignal&) = delete;
  StopOnSignal& operator=(const StopOnSignal&) = delete;

  bool requested() const;
  // "SIGINT" or "SIGTERM", once requested().
  std::string signal_name() const;
  // `display` (may be empty), returning false once a signal came: the work then ends with
  // kCancelled after its current unit.
  ProgressCallback wrap(const ProgressCallback& display) const;
};

// What a capture into a recording did.
struct CaptureOutcome {
  std::string recording;   // the folder
  std::string source;      // the simulator's or the camera's URI
  int frames = 0;          // in the recording now
  int planned = 0;         // in the recording once complete
  int resumed_from = 0;    // frames it held before this run (0: a new recording)
  int images_per_frame = 0;
  bool interrupted = false;  // a signal stopped it; the recording holds `frames` frames
  bool calibrated = true;    // the recording holds a calibration (a scan can decode it)
  session::CaptureStatistics statistics;  // devices: of this run, when it was not interrupted
  // The recording's writer thread (sdk/core/recording_writer_thread.h): also when interrupted;
  // nothing written with --no-record.
  RecordingWriteStatistics writes;
};

// Whether a capture writes its recording (`sls scan --no-record`: not; nothing of it touches
// the disk), and who hears, before its first frame, what the recording holds or would hold (the
// scan session is made from that when there is no recording to open).
struct LiveRecording {
  bool record = true;
  std::function<void(const RecordingInfo& info, const std::optional<ScannerCalibration>& calibration)> described;
};

// The simulator's capture for `sls scan --sim` (empty preset with `resume`: the one the
// recording's manifest names; object and frames likewise when not given).
struct SimCaptureRequest {
  std::string preset;
  std::string object;  // empty: knurled-screw, or the recording's when resuming
  int frames = 0;      // 0: the preset's, or the recording's when resuming
};

// Simulates the capture into `folder` (a new recording, or with `resume` the rest of the one
// there). A signal (`stop`) ends it after the current frame with outcome.interrupted.
// Throws sls::Error: kInvalidArgument when `folder` holds a recording and `resume` is not
// set, or `resume` is set and it holds none or one of other options (the message says which).
// `on_recorded`, when given: each frame once recorded, as a scan session takes it (fusing while
// capturing: session::captured_frames), on the capturing thread.
CaptureOutcome capture_sim(const std::string& folder, const SimCaptureRequest& request, bool resume,
                           const Device& device, const ProgressCallback& display, const StopOnSignal& stop,
                           const session::RecordedFrame& on_recorded = {}, const LiveRecording& live = {});

// Captures one revolution from devices by URI into `folder` (session::capture_from_devices),
// or with `resume` the frames the recording there lacks: the devices must be those it was
// made with (projector URI, camera size and depth, pattern set) and the frame count must fit
// its turntable angles; the turntable goes on from the first missing frame's angle.
// `on_recorded` as capture_sim's.
CaptureOutcome capture_devices(const std::string& folder, const session::DeviceCaptureRequest& request, bool resume,
                               const ProgressCallback& display, const StopOnSignal& stop,
                               const session::RecordedFrame& on_recorded = {}, const LiveRecording& live = {});

// `sls scan --sim/--camera` fused while it records (cmd_scan.cpp): the capture as a frame
// source (session::captured_frames over capture_sim or capture_devices, given `stop`), and its
// outcome, written on the source's thread before the source returns (read it once the pipeline
// has returned). A SIGINT or SIGTERM stops the capture after the frame it is taking; what it
// recorded is still fused. Not movable (StopOnSignal): make it in place.
struct LiveCapture {
  StopOnSignal stop;
  CaptureOutcome outcome;
  session::FrameSource frames;
  std::string resume_command;  // what continues the capture when it was cut off
  // The frames the capture will hold once complete, as its progress says (0 until it does):
  // the scan's progress total.
  std::atomic<std::size_t> planned_frames{0};
  // --no-record: nothing is written; the session is made from what the capture described before
  // its first frame (written on the source's thread before it delivers that frame, read once the
  // pipeline has it), and the frames' turntable angles are kept here as they are captured (read
  // once the pipeline has returned).
  bool record = true;
  std::optional<RecordingInfo> info;
  std::optional<ScannerCalibration> calibration;
  std::vector<std::optional<double>> turntable_angles;
};

}  // namespace sls::cli
