// Recorded sessions as devices (issue 20): a camera, a projector and a turntable that play a
// recording (sdk/core/recording.h, as `sls sim` and `sls scan` write it) back as if live,
// behind the driver interfaces of drivers/interfaces/, so the capture sequencer and every
// front end run the same code on a recording as on hardware. Opened by URI:
//   replay://PATH                  the recording folder PATH (relative or absolute:
//   replay:///data/rec?timing=recorded      replay:///abs/path); '%', '+' and '?' in PATH
//                                  percent-encoded
//   timing=fast (default)          images come as fast as they are read: a replay is a test
//                                  or a re-run of a scan, where waiting buys nothing
//   timing=recorded                the first image of each frame comes no earlier than its
//                                  recorded timestamp after the first frame played (the
//                                  recording keeps one timestamp per frame, so the images of a
//                                  stack come at once); the recorded pace wins over a wait's
//                                  timeout, as those frames did arrive
//
// Playback:
//  - the projector holds the recorded pattern set only: load_patterns() of another set is
//    kInvalidArgument naming both; show_pattern(k) picks image k of the frame played;
//  - the turntable answers the recorded angles: move_to_deg(a) selects the recorded frame at
//    angle a (within half the smallest step between recorded angles, at most 0.5° so another
//    frame count is refused; the first such frame after the one played, so a revolution
//    recorded twice plays in order) and position_deg() is that
//    frame's recorded angle. A move to an angle the recording has no frame at is kNotFound
//    naming the angle and the recorded range. Opening it for a recording made without a
//    turntable (no angles) is kUnsupported;
//  - the camera gives, per trigger (software, or each show_pattern on kHardwareLine), the
//    recorded image of the pattern shown, of the frame the turntable selected; without a
//    turntable frames play in order from the first, the next one when a stack starts again at a
//    pattern it has played (so a capture resumed part-way needs the turntable to start at its
//    frame, and a stack restarted after an incomplete frame is kUnsupported: a re-capture cannot
//    be told from the next frame). The image carries the frame's recorded timestamp and the
//    camera's own frame ids.
//    A pattern an incomplete frame lacks comes as an incomplete image (complete = false, with
//    the recorded note), as the transport's loss did live, so the sequencer re-captures and
//    records the frame incomplete again. Past the last frame: kNotFound "end of the recording".
//    An image that cannot be read: the reader's kNotFound / kFormat naming the file.
//  - what a capture through them re-records is the same recording: pixels, frame timestamps,
//    angles, complete flags, the pattern set, camera size and bit depth, the device's serial and
//    model (a capture's "projector + camera"; a model without " + ", as the simulator's, is
//    taken by both and comes back joined); it differs in device.uri (replay://PATH: what it was
//    captured from), created_utc, the capture counters and notes (the sequencer's of this
//    capture) and in calibration.yml, which the capture stores only when given (the devices
//    alone carry none; session::capture_from_devices, behind `sls scan --camera replay://` and
//    sls_scan_run_devices, gives the replayed recording's unless told another).
//
// Devices opened from one URI (the registry, drivers/device_registry.h) share one
// ReplayRecording while any of them is open, as sim:// devices share their scanner.
// Thread safety: the devices of one recording may be used from several threads (one lock);
// each device object from one thread at a time, as the interfaces assume.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/projector.h"
#include "drivers/interfaces/turntable.h"
#include "sdk/core/recording.h"
#include "sdk/decode/pattern_set.h"

namespace sls::replay {

class ReplayCamera;

enum class ReplayTiming { kFast, kRecorded };

// Where timing=recorded waits: the steady clock, or a test's clock.
class ReplayClock {
 public:
  using TimePoint = std::chrono::steady_clock::time_point;
  virtual ~ReplayClock() = default;
  virtual TimePoint now() const { return std::chrono::steady_clock::now(); }
  virtual void sleep_until(TimePoint when);
};

class ReplayRecording : public std::enable_shared_from_this<ReplayRecording> {
 public:
  // Opens the recording a replay:// URI names. Throws sls::Error naming the URI:
  // kInvalidArgument (not replay://, no path, an unknown key or timing value), the recording
  // reader's kNotFound / kFormat / kVersionMismatch (missing or corrupt recording), kUnsupported
  // for a depth-only recording (no pattern images to replay) or one with no frames.
  static std::shared_ptr<ReplayRecording> open(const std::string& uri, std::shared_ptr<ReplayClock> clock = nullptr);

  const std::string& uri() const { return uri_; }
  const RecordingReader& recording() const { return reader_; }
  const PatternSet& patterns() const { return patterns_; }
  ReplayTiming timing() const { return timing_; }
  bool has_angles() const { return !angles_.empty(); }

  std::unique_ptr<drivers::Camera> camera();
  std::unique_ptr<drivers::Projector> projector();
  // Throws kUnsupported when the recording has no turntable angles.
  std::unique_ptr<drivers::Turntable> turntable();

 private:
  friend class ReplayCamera;
  friend class ReplayProjector;
  friend class ReplayTurntable;
  ReplayRecording(std::string uri, RecordingReader reader) : uri_(std::move(uri)), reader_(std::move(reader)) {}

  // The recorded device model before and after " + " (projector, camera), as
  // session::make_recording_info joined them.
  std::string projector_model() const;
  std::string camera_model() const;

  // Under the lock: the turntable's frame for angle `angle_deg` (see the file comment).
  std::size_t frame_at_angle_locked(double angle_deg) const;
  // Under the lock: waits (timing=recorded) until frame `frame` is due; the first frame
  // played sets the pace's origin.
  void pace_locked(std::size_t frame, std::unique_lock<std::mutex>& lock);

  std::string uri_;
  RecordingReader reader_;
  PatternSet patterns_;
  ReplayTiming timing_ = ReplayTiming::kFast;
  std::shared_ptr<ReplayClock> clock_;
  std::vector<double> angles_;  // per frame, when every frame has one; else empty
  double angle_tolerance_deg_ = 0.5;
  int steps_per_revolution_ = 0;

  mutable std::mutex mutex_;
  int pattern_ = -1;                     // on the DMD; -1 = dark
  std::uint64_t pulses_ = 0;             // show_pattern calls: the projector's trigger output
  bool homed_ = false;
  std::optional<std::size_t> table_frame_;  // the frame the turntable selected; none before a move
  bool table_driven_ = false;               // a turntable was homed: it selects the frames
  std::optional<std::size_t> last_paced_;   // the frame pace_locked last waited for
  std::optional<std::pair<std::int64_t, ReplayClock::TimePoint>> pace_origin_;  // timestamp, when
  std::set<ReplayCamera*> hardware_cameras_;  // started on kHardwareLine: show_pattern triggers them
};

}  // namespace sls::replay
