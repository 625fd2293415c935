// Scripted in-memory devices for the capture sequencer's tests (test_capture_sequencer.cpp,
// test_capture_resume.cpp): a camera, a projector and a turntable sharing one stage, every
// transport fault on demand (incomplete, lost, late and ignored frames, silent and failing
// devices), a scene whose every pixel, pattern and frame differ, and a Bench holding them with a
// recording folder.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/session/capture_sequencer.h"
#include "tests/support/test_support.h"

namespace sls::session::capture_test {

using drivers::TriggerSource;
using std::chrono::milliseconds;

constexpr int kWidth = 8;
constexpr int kHeight = 6;
constexpr int kFramesPerRevolution = 4;

// What the scripted camera sees of pattern `pattern` at turntable frame `frame`: every pixel,
// pattern and frame differ, so a misfiled image shows.
inline std::uint16_t scene_value(int frame, int pattern, int x, int y) {
  return static_cast<std::uint16_t>(1000 * frame + 20 * pattern + x + kWidth * y + 1);
}
inline Image16u scene_image(int frame, int pattern) {
  Image16u image(kWidth, kHeight);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) image(x, y) = scene_value(frame, pattern, x, y);
  }
  return image;
}

inline PatternSet test_patterns() {
  GrayPhaseOptions options;
  options.phase_steps = 3;
  return make_gray_phase_pattern_set(options);  // 2 references + 12 Gray + 3 phase = 17
}

// What the devices share: the pattern on the "DMD" and the turntable's angle.
struct Stage {
  int shown = -1;
  double angle_deg = 0.0;
  int frame() const { return static_cast<int>(std::lround(angle_deg / (360.0 / kFramesPerRevolution))); }
};

// What a camera does with one trigger (numbered from 0 since start()).
enum class Fault {
  kNone,
  kIncomplete,  // arrives, but the transport lost part of it
  kLost,        // the camera numbers it, it never arrives
  kLate,        // arrives only after the wait for it timed out
  kIgnored,     // the camera never acts on the trigger (uses no frame number)
  kLostThenExtra,  // the camera numbers two frames, only the second (a spurious one) arrives
};

class ScriptedCamera final : public drivers::Camera {
 public:
  ScriptedCamera(Stage& stage, std::string uri) : stage_(stage), uri_(std::move(uri)) {}

  std::map<std::uint64_t, Fault> faults;  // by trigger number
  // Frames whose every attempt loses pattern `pattern` (incomplete image).
  std::map<int, int> always_incomplete;   // frame -> pattern
  int silent_from_frame = -1;             // from this turntable frame on, nothing comes back
  // Transport statistics as a GigE Vision camera keeps them (none: like the simulator's): each
  // incomplete image delivered counts 10 missing packets; the queue depth is what is still
  // ready behind the image wait_image() took.
  std::optional<drivers::TransportStatistics> transport;
  bool gone = false;                      // kDevice on every call

  int width = kWidth, height = kHeight;  // what info() says
  drivers::CameraInfo info() const override { return {uri_, "scripted camera", "SC-1", width, height, 16}; }
  void set_exposure_us(double exposure_us) override { exposure_ = exposure_us; }
  double exposure_us() const override { return exposure_; }
  void set_trigger_source(TriggerSource source) override { source_ = source; }
  void start() override {
    started_ = true;
    ++starts;
  }
  void stop() override {
    started_ = false;
    ++stops;
  }
  void software_trigger() override {
    check();
    if (source_ != TriggerSource::kSoftware) throw Error(ErrorCode::kInvalidArgument, "software trigger in hardware mode");
    ++software_triggers;
    trigger();
  }
  // The projector's trigger output, wired to this camera's line.
  void line_pulse() {
    if (started_ && source_ == TriggerSource::kHardwareLine) trigger();
  }
  drivers::CapturedImage wait_image(milliseconds timeout) override {
    check();
    if (!started_) throw Error(ErrorCode::kInvalidArgument, "wait_image before start");
    if (ready_.empty()) {
      // A late image turns up just after its wait gave up.
      if (!late_.empty()) {
        ready_.push_back(late_.front());
        late_.pop_front();
      }
      throw_error(ErrorCode::kTimeout, "{}: no image within {} ms", uri_, timeout.count());
    }
    drivers::CapturedImage image = std::move(ready_.front());
    ready_.pop_front();
    if (transport) {
      if (!image.complete) transport->missing_packets += 10;
      transport->output_queue_depth = ready_.size();
    }
    if (have_delivered_ && image.frame_id > last_delivered_) image.frames_missed = image.frame_id - last_delivered_ - 1;
    have_delivered_ = true;
    last_delivered_ = image.frame_id;
    return image;
  }

  std::optional<drivers::TransportStatistics> transport_statistics() const override { return transport; }

  TriggerSource source() const { return source_; }
  int software_triggers = 0;
  int starts = 0;
  int stops = 0;

 private:
  void check() const {
    if (gone) throw_error(ErrorCode::kDevice, "{}: camera gone", uri_);
  }
  void trigger() {
    const std::uint64_t number = triggers_++;
    const auto fault_it = faults.find(number);
    const Fault fault = fault_it == faults.end() ? Fault::kNone : fault_it->second;
    if (fault == Fault::kIgnored) return;
    if (silent_from_frame >= 0 && stage_.frame() >= silent_from_frame) return;
    drivers::CapturedImage image;
    image.frame_id = next_id_++;
    image.timestamp_ns = static_cast<std::int64_t>(image.frame_id) * 1000;
    image.image = scene_image(stage_.frame(), stage_.shown);
    const auto always = always_incomplete.find(stage_.frame());
    if (fault == Fault::kIncomplete || (always != always_incomplete.end() && always->second == stage_.shown)) {
      image.complete = false;
      image.problem = uri_ + ": frame " + std::to_string(image.frame_id) + " is not whole";
      image.image = Image16u();
    }
    if (fault == Fault::kLost) return;
    if (fault == Fault::kLate) {
      late_.push_back(std::move(image));
      return;
    }
    if (fault == Fault::kLostThenExtra) {
      image.frame_id = next_id_++;  // the first of the two numbers never arrives
      image.timestamp_ns = static_cast<std::int64_t>(image.frame_id) * 1000;
    }
    ready_.push_back(std::move(image));
  }

  Stage& stage_;
  std::string uri_;
  double exposure_ = 5000.0;
  TriggerSource source_ = TriggerSource::kSoftware;
  bool started_ = false;
  std::uint64_t triggers_ = 0;
  std::uint64_t next_id_ = 100;
  bool have_delivered_ = false;
  std::uint64_t last_delivered_ = 0;
  std::deque<drivers::CapturedImage> ready_;
  std::deque<drivers::CapturedImage> late_;
};

class ScriptedProjector final : public drivers::Projector {
 public:
  explicit ScriptedProjector(Stage& stage) : stage_(stage) {}

  std::vector<ScriptedCamera*> wired;  // cameras whose trigger line this projector drives
  int fail_at_frame = -1;              // show_pattern of (fail_at_frame, fail_at_pattern) throws kDevice
  int fail_at_pattern = 0;
  int go_dark_calls = 0;

  drivers::ProjectorInfo info() const override { return {"test://projector", "scripted projector", "1.0", 912, 1140}; }
  void load_patterns(const PatternSet& patterns) override { patterns_ = patterns; }
  const PatternSet& patterns() const override { return patterns_; }
  void show_pattern(int index) override {
    if (stage_.frame() == fail_at_frame && index == fail_at_pattern) {
      throw Error(ErrorCode::kDevice, "test projector: endpoint stalled");
    }
    stage_.shown = index;
    for (ScriptedCamera* camera : wired) camera->line_pulse();
  }
  int current_pattern() const override { return stage_.shown; }
  void go_dark() override {
    ++go_dark_calls;
    stage_.shown = -1;
  }

 private:
  Stage& stage_;
  PatternSet patterns_;
};

class ScriptedTurntable final : public drivers::Turntable {
 public:
  explicit ScriptedTurntable(Stage& stage) : stage_(stage) {}
  int fail_at_frame = -1;
  int homes = 0;

  void home(milliseconds) override {
    ++homes;
    stage_.angle_deg = 0.0;
  }
  void move_to_deg(double angle_deg, milliseconds timeout) override {
    if (std::lround(angle_deg / (360.0 / kFramesPerRevolution)) == fail_at_frame) {
      throw_error(ErrorCode::kTimeout, "test turntable: not at {} deg within {} ms", angle_deg, timeout.count());
    }
    stage_.angle_deg = angle_deg;
  }
  double position_deg() const override { return stage_.angle_deg; }
  int steps_per_revolution() const override { return 3600; }

 private:
  Stage& stage_;
};

// A stage, the three devices and a recording folder.
struct Bench {
  Stage stage;
  ScriptedProjector projector{stage};
  ScriptedCamera camera{stage, "test://camera0"};
  ScriptedTurntable turntable{stage};
  PatternSet patterns = test_patterns();
  test::TemporaryDirectory dir;

  CaptureOptions options(int frames) const {
    CaptureOptions o;
    o.frames = frames;
    o.frames_per_revolution = kFramesPerRevolution;
    o.image_timeout = milliseconds(50);
    return o;
  }
  RecordingWriter writer(const std::string& name = "rec") const {
    RecordingWriterOptions writer_options;
    writer_options.sync = false;
    return RecordingWriter::create(dir.file(name), make_recording_info(projector, camera, patterns), std::nullopt,
                                   writer_options);
  }
};

// Every frame of the recording holds exactly what the scene showed for its patterns.
inline void expect_recording_shows_the_scene(const std::string& folder, int frames) {
  const RecordingReader reader = RecordingReader::open(folder);
  ASSERT_EQ(reader.frame_count(), static_cast<std::size_t>(frames));
  for (std::size_t f = 0; f < reader.frame_count(); ++f) {
    const FrameInfo& frame = reader.frame(f);
    ASSERT_TRUE(frame.turntable_angle_deg.has_value());
    const int position = static_cast<int>(std::lround(*frame.turntable_angle_deg / 90.0));
    const std::vector<Image16u> images = reader.load_images(f);
    if (frame.complete) {
      EXPECT_EQ(images.size(), static_cast<std::size_t>(reader.info().images_per_frame));
    }
    for (std::size_t k = 0; k < images.size(); ++k) {
      EXPECT_TRUE(images[k] == scene_image(position, static_cast<int>(k))) << "frame " << f << " image " << k;
    }
  }
}

template <typename F>
Error expect_error(F&& f, ErrorCode code) {
  try {
    f();
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), code) << error.what();
    return error;
  }
  ADD_FAILURE() << "no sls::Error";
  return Error(ErrorCode::kInternal, "");
}

}  // namespace sls::session::capture_test
