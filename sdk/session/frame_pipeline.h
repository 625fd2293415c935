// Fusing frames as a source delivers them (issue 18; DESIGN.md section 1). The source — a
// recording read ahead, a capture through the devices, the simulator rendering — runs on a
// thread of its own and hands each frame over through a bounded queue; the calling thread fuses
// them through the scan session in the order they were delivered. The same frames reach
// ScanSession::add_frame() in the same order as in a sequential run, so the model is the same
// bit for bit; what changes is that reading or capturing the next frame overlaps fusing this one.
//
//   PipelineOutcome outcome = run_pipeline(session, [&](const FrameDelivery& deliver) {
//     for (...) if (!deliver(std::move(frame))) return;   // false: the pipeline has stopped
//   }, options, on_frame, progress);
//
// Back-pressure is explicit: while the queue is full the source waits in deliver() — a capture
// loses nothing by it (its frames are handed to its recording's writer thread before they are
// delivered, sdk/core/recording_writer_thread.h, and that thread has its own bounded queue and
// counted waits) — and the waits are counted (PipelineOutcome::waits, wait_s, each frame's waited_s). No frame is
// dropped.
//
// How it ends:
//  - the source returns: every frame it delivered is fused;
//  - the source throws sls::Error(kCancelled) (a capture stopped by its own progress callback,
//    e.g. SIGINT): the frames delivered are fused, and the outcome is interrupted with that
//    message;
//  - the source throws anything else (a device stopped answering, a disk): the frames
//    delivered before are fused, then its exception is rethrown unchanged (the session keeps
//    what was fused);
//  - `progress` asks to stop (kCancelled) or `on_frame` throws: the source is stopped (its
//    deliver() returns false from then on) and joined; frames still queued are not fused (a
//    recording or a capture has them on disk). A cancel is an interrupted outcome; an exception
//    from on_frame is rethrown;
//  - add_frame throws (a fault of the machine: memory, the GPU): the source is stopped and
//    joined, and the exception rethrown.
// Progress: ("scan", frames fused, expected_frames) before each frame is taken from the queue
// and once when the source is done (not after an interruption); a cancel leaves the next frame
// queued, so a capture is told while it waits to hand over the one after.
//
// Threads: run_pipeline drives the session and calls on_frame and progress on the calling
// thread; the source runs on a thread it starts and always joins before returning or throwing.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "sdk/core/memory_type.h"
#include "sdk/core/progress.h"
#include "sdk/core/recording.h"
#include "sdk/core/stopwatch.h"
#include "sdk/core/trajectory.h"
#include "sdk/session/scan_session.h"

namespace sls::session {

struct PipelineOptions {
  // Frames delivered and not yet fused, at most (1 or more). Each holds its pattern stack:
  // ~0.5 GB at 12 MP (recordings admit a stack's memory before reading it).
  std::size_t queue_frames = 2;
  // Throws sls::Error(kInvalidArgument) naming the bad value.
  void validate() const;
};

// When a frame went through, in seconds since run_pipeline started.
struct FrameTiming {
  int index = 0;             // ScanFrame::index
  double delivered_s = 0.0;  // the source handed it over (captured, or read)
  double fused_s = 0.0;      // the session had fused it (add_frame returned)
  double waited_s = 0.0;     // the source waited this long for room in the queue to hand it over
};

struct PipelineOutcome {
  bool interrupted = false;
  std::string interruption;          // what stopped it
  std::vector<FrameTiming> timings;  // one per frame fused, in order
  std::size_t delivered = 0;         // frames the source handed over
  std::size_t waits = 0;             // of those, handed over only after waiting for room
  double wait_s = 0.0;               // the waits summed
  std::size_t deepest_queue = 0;     // the most frames waiting to be fused at once
  double source_s = 0.0;             // the source's run, from its start to its return
  SteadyClock::time_point started;   // what the seconds above count from
};

// Hands a frame to the pipeline, waiting while the queue is full; false when the pipeline has
// stopped (the frame was not taken; the source should return). Call it from the source's
// thread only.
using FrameDelivery = std::function<bool(ScanFrame&& frame)>;
// Delivers the frames in order; runs on the pipeline's source thread.
using FrameSource = std::function<void(const FrameDelivery& deliver)>;

// Runs `source` on a thread of its own and fuses what it delivers (see the file comment).
// Throws sls::Error(kInvalidArgument) for bad options, before the source starts.
PipelineOutcome run_pipeline(ScanSession& session, const FrameSource& source, const PipelineOptions& options,
                             const std::function<void(const FrameReport&)>& on_frame = {},
                             const ProgressCallback& progress = {}, std::size_t expected_frames = 0);

// The same with the session made once the first frame has arrived: `session` is called once,
// on the calling thread, before that frame is fused, and never when no frame arrives. For a
// capture, whose recording (the camera, the patterns, the calibration a session is made from)
// exists once its first frame does. An exception from it stops the source and is rethrown.
using SessionProvider = std::function<ScanSession&()>;
PipelineOutcome run_pipeline(const SessionProvider& session, const FrameSource& source, const PipelineOptions& options,
                             const std::function<void(const FrameReport&)>& on_frame = {},
                             const ProgressCallback& progress = {}, std::size_t expected_frames = 0);

// Frame `position` of a recording as the session takes it: its images (HDR stacks fused,
// hdr_frame.h) or depth map, or, when it cannot be read or is incomplete, ScanFrame::problem
// (the session reports and skips it); the known pose when given (one per recording frame);
// the read time in ScanFrame::read_ms. Throws what reading throws beyond a frame's own
// problems (is_frame_problem: a full machine, say).
// `image_memory`: where the pattern images are read into (capture_memory_for(device): page-locked
// for a session on a GPU, as a camera delivers them).
ScanFrame read_recording_frame(const RecordingReader& recording, std::size_t position,
                               const std::vector<StampedPose>* known_poses = nullptr,
                               MemoryType image_memory = MemoryType::kHost);

// A recording as a frame source: its frames read in order (an unreadable or incomplete one
// passed on with ScanFrame::problem, so the session reports and skips it), HDR stacks fused
// (hdr_frame.h), with known poses when given (one per recording frame), each frame's read time
// in ScanFrame::read_ms. `recording` and `known_poses` must outlive the source. Throws
// kInvalidArgument when the known poses are not one per frame.
FrameSource recording_frames(const RecordingReader& recording, const std::vector<StampedPose>* known_poses = nullptr,
                             MemoryType image_memory = MemoryType::kHost);

// A capture into the recording at `folder` as a frame source: fusing while capturing.
// `capture` runs on the source thread; it records frames into `folder` (a new recording, or the
// rest of one cut off) on a writer thread of its own and hands each to `recorded` as soon as it
// has handed it to that writer (the stack shared, ScanFrame::shared_images), with
// ScanFrame::index its position there; it returns (or throws) only once every frame it captured
// is written. An empty `folder`: the capture records nothing (`--no-record`), and nothing is read
// back. Frames the recording held before (a resumed capture),
// and any the capture recorded without handing over, are read back from the recording
// (read_recording_frame), so the session sees every frame of the recording once, in order.
// When the pipeline stops taking frames (a cancel or a fault while fusing), `recorded` throws
// sls::Error(kCancelled): the capture then ends after the frame it has just recorded, which
// stays in the recording.
using RecordedFrame = std::function<void(ScanFrame&& frame)>;
FrameSource captured_frames(const std::string& folder, std::function<void(const RecordedFrame& recorded)> capture);

// Replays a recording through a session: run_pipeline over recording_frames(), the next frames
// read while the current one is fused (options.queue_frames ahead), page-locked where the
// session uploads stacks to a GPU (ScanSession::uploads_ahead). A cancel from `progress`
// stops after the current frame: the outcome says so and the session keeps everything fused.
using ReplayOutcome = PipelineOutcome;
ReplayOutcome run_recording(ScanSession& session, const RecordingReader& recording,
                            const std::vector<StampedPose>* known_poses = nullptr,
                            const std::function<void(const FrameReport&)>& on_frame = {},
                            const ProgressCallback& progress = {}, const PipelineOptions& options = {});

}  // namespace sls::session
