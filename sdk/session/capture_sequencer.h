// The capture sequencer (issue #7): drives a projector, one or more cameras and an optional
// turntable through a turntable scan, one pattern stack per turntable position, and appends each
// stack to a recording as it arrives. It knows the devices only through the driver interfaces of
// drivers/interfaces, so the simulated scanner, the DLPC350 + Aravis + head-controller hardware and
// any OEM driver run the same loop.
//
//   CaptureSequencer sequencer(*projector, {camera.get()}, turntable.get(), patterns, options);
//   RecordingWriter writer = RecordingWriter::create(folder, make_recording_info(...), calibration);
//   CaptureStatistics stats = sequencer.run({&writer}, on_frame, progress);
//
// What run() does:
//  1. loads the pattern set into the projector, sets every camera's trigger source (and exposure
//     when asked), homes the turntable and starts the cameras;
//  2. per frame k: moves the turntable to start + 360° k / frames_per_revolution, then per pattern
//     shows it and triggers the cameras (software trigger, or the projector's trigger output on
//     the cameras' hardware line) and collects one image per camera;
//  3. checks every image: a frame the transport could not complete (CapturedImage::complete ==
//     false), an image lost entirely (no image in time, or a frame-id gap), or an image that
//     belongs to another trigger are never used. Such a stack is re-captured whole, up to
//     max_retries times; when the retries run out the frame is written marked incomplete, with the
//     whole images it has (always the first ones of the sequence) and a note saying why;
//  4. hands the stack to each camera's recording (flushed per frame by RecordingWriter), with
//     the frame's capture counters (CapturedFrame::counters), then calls the per-frame callback,
//     then the progress callback. The recordings are written on a writer thread
//     (sdk/core/recording_writer_thread.h, CaptureOptions::write_queue_frames): the next stack is
//     captured, and the callback fuses this one, while it is written; the stack is shared with
//     the callback (CameraStack::shared_images), not copied. run() returns once every stack
//     captured is written, and a capture ended by an error, a cancel or a callback's exception
//     still writes every stack it captured before it rethrows.
//
// Per-frame counters: the attempts, and the images that were incomplete, lost or stale while
// this frame was captured (they sum to CaptureStatistics' counts), and, from the cameras that
// report transport statistics (drivers::Camera::transport_statistics), the packets resent and
// missing since the previous frame ended (or the acquisition started: the turntable's move is
// part of a frame's span), summed over the cameras, and the deepest output queue behind any
// image taken for the frame.
//
// Which trigger an image answers: every camera numbers its frames (frame_id), and a trigger it
// acted on uses one number whether or not the image arrives. The sequencer counts the triggers it
// issued per camera and follows the camera's numbering through CapturedImage::frames_missed, so
// an image that arrives late (after its wait timed out) is recognised as stale and dropped
// instead of being filed under the next pattern.
//
// Errors: a device that stops answering ends the scan with sls::Error naming the device (its
// role and URI, plus the driver's own message) and the frame and pattern; the code is the
// driver's (kTimeout, kDevice, ...). A camera counts as not answering when every attempt at a
// stack timed out waiting for it; a projector or turntable error ends the scan at once (their
// drivers retry themselves). Frames appended before the error stay in the recording, which
// reads back as a valid recording of those frames. A write that fails (a full disk, an
// unwritable folder) ends the scan with the write's sls::Error naming the recording's folder and
// the frame (RecordingWriterThread); the frames before it stay listed. The progress callback returning false ends
// the scan with kCancelled after the current frame, which is kept; an exception from the
// per-frame callback ends it the same way and propagates unchanged.
//
// Not thread-safe: run() drives the devices from the calling thread; the callbacks are called on
// it. The sequencer does not own the devices or the recordings; they must outlive run().
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/projector.h"
#include "drivers/interfaces/turntable.h"
#include "sdk/core/image.h"
#include "sdk/core/progress.h"
#include "sdk/core/recording.h"
#include "sdk/core/recording_writer_thread.h"
#include "sdk/decode/pattern_set.h"

namespace sls::session {

struct CaptureOptions {
  // Stacks to capture, one per turntable position; 0: one revolution (frames_per_revolution).
  int frames = 0;
  // Stack k is taken at start_angle_deg + 360° k / frames_per_revolution (angles past 360° go on
  // into the next revolution).
  int frames_per_revolution = 36;
  double start_angle_deg = 0.0;
  // Resuming a capture that was cut off: the first stack to capture (0 .. frames); stacks
  // before it are in the recordings already, which must hold exactly that many frames. The
  // turntable goes on to where stack first_frame is taken, as in an uninterrupted run.
  int first_frame = 0;
  bool home_turntable = true;  // home before the first stack (ignored without a turntable)
  // > 0: set on every camera before capturing; 0 leaves the cameras' exposure as it is.
  double exposure_us = 0.0;
  // HDR (sdk/decode/hdr_fusion.h): capture the whole stack at each of these exposure times,
  // relative to the base exposure (exposure_us, or each camera's own when the capture starts),
  // setting every camera's exposure before each pass; a frame then holds patterns x exposures
  // images, exposure-major (recordings: RecordingInfo::exposures). 1..4 finite positive
  // distinct scales; empty: one exposure, as set. The base is restored when the capture ends.
  std::vector<double> exposures;
  // kSoftware: the sequencer triggers each camera after the projector shows a pattern.
  // kHardwareLine: the cameras wait for the projector's trigger output (show_pattern fires it
  // once per pattern, per the Projector interface); the sequencer only shows patterns. The line
  // must carry exactly that one pulse: a spurious pulse cannot be told from a real one by frame
  // numbers (a projector that keeps pulsing while a pattern stays on does not fit this mode).
  drivers::TriggerSource trigger = drivers::TriggerSource::kSoftware;
  // How long one image may take to arrive after its trigger.
  std::chrono::milliseconds image_timeout{2000};
  // How long a turntable move (or homing) may take.
  std::chrono::milliseconds turntable_timeout{10000};
  // Re-captures of a stack that had a dropped, incomplete or timed-out image.
  int max_retries = 2;
  // Stacks captured and waiting to be written to the recordings, at most (the writer thread's
  // queue, sdk/core/recording_writer_thread.h); a full queue holds the capture back (counted:
  // CaptureStatistics::writes). Each holds its stack (~0.5 GB at 12 MP) until written.
  // 0: each stack is written on the capturing thread before the callback sees it (the capture
  // as it was before the writer thread).
  std::size_t write_queue_frames = 2;
  // Stacks the per-frame callback may keep after it returns, at most (a live scan: the frames
  // waiting to be fused and the one being fused). With the writer's, they set the memory run()
  // admits before anything moves: 1 + max(writer, callback) stacks, the writer holding
  // write_queue_frames + 1 (the one being written) when there are recordings. Both hold the most
  // recent frames, so a frame they share counts once.
  std::size_t callback_holds_frames = 0;

  // Throws sls::Error(kInvalidArgument) naming the first bad value.
  void validate() const;
};

// What a camera said about one image of a stack.
struct ImageMetadata {
  int pattern = 0;                // index in the pattern set
  std::int64_t timestamp_ns = 0;  // the camera's clock at the start of the exposure
  std::uint64_t frame_id = 0;     // the camera's frame number
  int exposure = 0;               // index in CaptureOptions::exposures (0 without HDR)
};

// One camera's stack: images and their metadata, parallel, in pattern order (HDR: the whole
// stack per exposure in turn). Complete: one per pattern (and exposure); incomplete: the first
// images of the sequence only.
struct CameraStack {
  std::vector<Image16u> images;
  // With recordings: the images, moved here and shared read-only with the recording's writer
  // thread (`images` is then empty). Release it when done: the stack's memory goes once both are.
  std::shared_ptr<const std::vector<Image16u>> shared_images;
  std::vector<ImageMetadata> metadata;
};

struct CapturedFrame {
  int index = 0;  // frame of the scan, first_frame .. frames − 1
  std::optional<double> turntable_angle_deg;  // as the turntable reports it; none without one
  int attempts = 1;                           // 1 + re-captures
  bool complete = true;
  // Why the frame is incomplete, or what made a complete frame need re-capturing; empty when
  // the first attempt succeeded.
  std::string note;
  std::vector<CameraStack> cameras;  // per camera, in the order given to the sequencer
  // What each camera's recording got as its index for this frame (empty without recordings).
  std::vector<int> recording_indices;
  // What capturing it took (what the recordings store with the frame).
  FrameCaptureCounters counters;

  // The first camera's first image's timestamp (what the recording stores), 0 when it has none.
  std::int64_t timestamp_ns() const;
};

struct CaptureStatistics {
  int frames = 0;             // stacks appended
  int incomplete_frames = 0;  // of those, marked incomplete after the retries ran out
  int retries = 0;            // stacks re-captured, over all frames
  int images = 0;             // images received, stale and broken ones included
  int incomplete_images = 0;  // transport could not complete them (complete == false)
  int lost_images = 0;        // never arrived: frame-id gaps and timeouts
  int timeouts = 0;           // waits for an image that ran out (counted in lost_images too)
  int stale_images = 0;       // arrived late for an earlier trigger and were dropped
  // Packets resent and missing over the frames captured (the per-frame counts summed; queue
  // depth: the deepest); none when no camera reports transport statistics.
  std::optional<FrameTransportCounters> transport;
  double seconds = 0.0;          // wall time of run(), setup included
  double capture_seconds = 0.0;  // capturing stacks: turntable moves and recording excluded
  double projector_seconds = 0.0;  // of that, in show_pattern
  double camera_seconds = 0.0;     // of that, triggering cameras and waiting for their images
  RecordingWriteStatistics writes;  // the recordings' writer thread (none without recordings)
};

// Called with each frame once it is handed to the recordings (being written, or written with
// write_queue_frames 0). It may take the frame's images (move them out, or share
// shared_images: a live scan fuses them without a copy); the sequencer does not use the frame
// afterwards.
using FrameCallback = std::function<void(CapturedFrame& frame)>;

// A recording's description for camera `camera` of a projector and pattern set: device from the
// projector, camera size and bit depth from the camera, the pattern set, images per frame
// (patterns x exposures) and, for HDR (2..4 exposures: CaptureOptions::exposures), the exposures.
RecordingInfo make_recording_info(const drivers::Projector& projector, const drivers::Camera& camera,
                                  const PatternSet& patterns, const std::vector<double>& exposures = {});

class CaptureSequencer {
 public:
  // `cameras` must be non-empty and hold no null; `turntable` may be null (all stacks at one
  // position). Throws sls::Error(kInvalidArgument) for bad options or an invalid pattern set.
  CaptureSequencer(drivers::Projector& projector, std::vector<drivers::Camera*> cameras,
                   drivers::Turntable* turntable, PatternSet patterns, CaptureOptions options);

  // Captures the scan (see the file comment). `recordings` is empty (callbacks only) or holds one
  // writer per camera, each with images_per_frame = the set's size (x exposures), the
  // exposures of the options (HDR), the camera's image size and
  // options.first_frame frames (kInvalidArgument otherwise, before any device is touched). With
  // first_frame = the frame count there is nothing to capture and no device is touched. Returns what happened; throws
  // sls::Error as the file comment says. Cameras are stopped and the projector goes dark before
  // it returns or throws (a device that just failed is left alone).
  CaptureStatistics run(const std::vector<RecordingWriter*>& recordings, const FrameCallback& on_frame = {},
                        const ProgressCallback& progress = {});

  const CaptureOptions& options() const { return options_; }
  // What the last run() did, also when it threw (the frames written before an error, say).
  const CaptureStatistics& statistics() const { return statistics_; }
  const PatternSet& patterns() const { return patterns_; }
  // How many stacks run() captures.
  int frame_count() const;
  // The turntable angle run() commands for frame `frame`.
  double commanded_angle_deg(int frame) const;

 private:
  // Which trigger a camera's next image answers (see the file comment).
  struct CameraTrack {
    std::uint64_t triggers = 0;                // triggers issued since start(); the next one is number `triggers`
    std::optional<std::uint64_t> last_answer;  // the trigger the last image received answered
  };
  struct Attempt;

  void prepare();
  void finish(bool after_error);
  CapturedFrame capture_frame(int frame);
  FrameCaptureCounters frame_counters(const CaptureStatistics& before, int attempts);
  std::optional<drivers::TransportStatistics> transport_sample() const;
  Attempt capture_attempt(int frame);
  bool collect_image(std::size_t camera, int frame, int pattern, Attempt& attempt);
  std::string camera_name(std::size_t camera) const;
  std::string where(int frame, int pattern) const;
  [[noreturn]] void fail(const std::string& device, const std::string& context, const Error& error);

  drivers::Projector& projector_;
  std::vector<drivers::Camera*> cameras_;
  drivers::Turntable* turntable_;
  const PatternSet patterns_;
  const CaptureOptions options_;
  std::string projector_name_;
  std::vector<std::string> camera_names_;
  std::vector<CameraTrack> tracks_;
  std::string failed_device_;  // the device whose error ended the scan, left alone in cleanup
  CaptureStatistics statistics_;
  std::optional<double> angle_deg_;
  // HDR: each camera's exposure (µs) per pass, and the base to restore at the end.
  std::vector<std::vector<double>> exposure_us_;
  std::vector<double> base_exposure_us_;
  std::size_t exposure_count() const { return options_.exposures.empty() ? 1 : options_.exposures.size(); }
  // The cameras' transport counters (summed) when the previous frame ended, and the deepest
  // output queue seen during the current frame.
  std::optional<drivers::TransportStatistics> transport_mark_;
  std::uint64_t queue_depth_ = 0;
};

}  // namespace sls::session
