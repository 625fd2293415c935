// The capture sequencer against scripted in-memory devices (every transport fault on demand:
// incomplete, lost, late and ignored frames, silent and failing devices) and against the
// simulated scanner, whose direct recording path it must reproduce image for image.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/session/capture_sequencer.h"
#include "tests/support/process_memory.h"
#include "tests/support/test_support.h"

namespace sls::session {
namespace {

using drivers::TriggerSource;
using std::chrono::milliseconds;

constexpr int kWidth = 8;
constexpr int kHeight = 6;
constexpr int kFramesPerRevolution = 4;

// What the scripted camera sees of pattern `pattern` at turntable frame `frame`: every pixel,
// pattern and frame differ, so a misfiled image shows.
std::uint16_t scene_value(int frame, int pattern, int x, int y) {
  return static_cast<std::uint16_t>(1000 * frame + 20 * pattern + x + kWidth * y + 1);
}
Image16u scene_image(int frame, int pattern) {
  Image16u image(kWidth, kHeight);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) image(x, y) = scene_value(frame, pattern, x, y);
  }
  return image;
}

PatternSet test_patterns() {
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
void expect_recording_shows_the_scene(const std::string& folder, int frames) {
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

TEST(CaptureSequencer, SoftwareTriggeredScanRecordsEveryStackWithItsMetadata) {
  Bench bench;
  RecordingWriter writer = bench.writer();
  CaptureOptions options = bench.options(0);  // one revolution
  options.exposure_us = 1234.0;
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, options);
  EXPECT_EQ(sequencer.frame_count(), kFramesPerRevolution);

  std::vector<CapturedFrame> seen;
  std::vector<std::size_t> progress;
  const CaptureStatistics stats = sequencer.run(
      {&writer}, [&](const CapturedFrame& frame) { seen.push_back(frame); },
      [&](const ProgressUpdate& update) {
        EXPECT_EQ(update.stage, "capture");
        EXPECT_EQ(update.total, 4u);
        progress.push_back(update.done);
        return true;
      });
  EXPECT_EQ(stats.frames, 4);
  EXPECT_EQ(stats.retries, 0);
  EXPECT_EQ(stats.images, 4 * 17);
  EXPECT_EQ(stats.lost_images + stats.incomplete_images + stats.stale_images, 0);
  EXPECT_EQ(progress, (std::vector<std::size_t>{1, 2, 3, 4}));
  EXPECT_DOUBLE_EQ(bench.camera.exposure_us(), 1234.0);
  EXPECT_EQ(bench.camera.software_triggers, 4 * 17);
  EXPECT_EQ(bench.turntable.homes, 1);
  EXPECT_EQ(bench.camera.stops, 1);
  EXPECT_EQ(bench.projector.current_pattern(), -1) << "the projector goes dark at the end";

  // Per-image metadata: pattern order, the camera's consecutive frame numbers and timestamps.
  ASSERT_EQ(seen.size(), 4u);
  std::uint64_t next_id = 100;
  for (int f = 0; f < 4; ++f) {
    const CapturedFrame& frame = seen[static_cast<std::size_t>(f)];
    EXPECT_EQ(frame.index, f);
    EXPECT_TRUE(frame.complete);
    EXPECT_EQ(frame.attempts, 1);
    EXPECT_TRUE(frame.note.empty());
    EXPECT_DOUBLE_EQ(*frame.turntable_angle_deg, 90.0 * f);
    EXPECT_EQ(frame.recording_indices, std::vector<int>{f});
    ASSERT_EQ(frame.cameras.size(), 1u);
    const CameraStack& stack = frame.cameras[0];
    // Recorded: the stack is shared with the writer thread, not copied.
    EXPECT_TRUE(stack.images.empty());
    ASSERT_NE(stack.shared_images, nullptr);
    ASSERT_EQ(stack.shared_images->size(), 17u);
    for (int k = 0; k < 17; ++k) {
      const ImageMetadata& meta = stack.metadata[static_cast<std::size_t>(k)];
      EXPECT_EQ(meta.pattern, k);
      EXPECT_EQ(meta.frame_id, next_id);
      EXPECT_EQ(meta.timestamp_ns, static_cast<std::int64_t>(next_id) * 1000);
      ++next_id;
    }
    EXPECT_EQ(frame.timestamp_ns(), stack.metadata[0].timestamp_ns);
  }

  expect_recording_shows_the_scene(bench.dir.file("rec"), 4);
  const RecordingReader reader = RecordingReader::open(bench.dir.file("rec"));
  EXPECT_EQ(reader.frame(2).timestamp_ns, seen[2].timestamp_ns());
  EXPECT_EQ(reader.info().camera.bit_depth, 16);
  EXPECT_EQ(pattern_set_from_json(reader.info().pattern_set_json), bench.patterns);
}

TEST(CaptureSequencer, HardwareTriggerTakesTheProjectorsPulsesOnly) {
  Bench bench;
  bench.projector.wired = {&bench.camera};
  RecordingWriter writer = bench.writer();
  CaptureOptions options = bench.options(3);
  options.trigger = TriggerSource::kHardwareLine;
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, options);
  const CaptureStatistics stats = sequencer.run({&writer});
  EXPECT_EQ(bench.camera.source(), TriggerSource::kHardwareLine);
  EXPECT_EQ(bench.camera.software_triggers, 0);
  EXPECT_EQ(stats.frames, 3);
  EXPECT_EQ(stats.retries, 0);
  expect_recording_shows_the_scene(bench.dir.file("rec"), 3);
}

TEST(CaptureSequencer, AnIncompleteImageMakesTheWholeStackBeCapturedAgain) {
  Bench bench;
  bench.camera.faults[17 + 5] = Fault::kIncomplete;  // frame 1, pattern 5
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(3));
  std::vector<CapturedFrame> seen;
  const CaptureStatistics stats = sequencer.run({&writer}, [&](const CapturedFrame& frame) { seen.push_back(frame); });
  EXPECT_EQ(stats.retries, 1);
  EXPECT_EQ(stats.incomplete_images, 1);
  EXPECT_EQ(stats.incomplete_frames, 0);
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_EQ(seen[1].attempts, 2);
  EXPECT_TRUE(seen[1].complete);
  EXPECT_NE(seen[1].note.find("re-captured 1 time(s)"), std::string::npos) << seen[1].note;
  EXPECT_NE(seen[1].note.find("is not whole"), std::string::npos) << seen[1].note;
  expect_recording_shows_the_scene(bench.dir.file("rec"), 3);
  const RecordingReader reader = RecordingReader::open(bench.dir.file("rec"));
  EXPECT_TRUE(reader.frame(1).complete);
  EXPECT_EQ(reader.frame(1).note, seen[1].note);
}

// Issue 19: each frame carries the counts of its own capture (what CaptureStatistics sums), and
// the recording keeps them; packets and queue depth only from a camera whose transport counts.
TEST(CaptureSequencer, EachFrameCarriesItsOwnCaptureCountersIntoTheRecording) {
  for (const bool transport : {false, true}) {
    SCOPED_TRACE(transport ? "a camera reporting its transport" : "a camera without transport statistics");
    Bench bench;
    if (transport) bench.camera.transport = drivers::TransportStatistics{4, 2, 0};  // counted before the scan
    bench.camera.faults[17 + 5] = Fault::kIncomplete;  // frame 1, pattern 5
    // Frame 1 takes 6 + 17 triggers: frame 2's pattern 3 is trigger 43, lost, then stale in the retry.
    bench.camera.faults[17 + 6 + 17 + 3] = Fault::kLate;
    RecordingWriter writer = bench.writer();
    CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(3));
    std::vector<FrameCaptureCounters> seen;
    const CaptureStatistics stats =
        sequencer.run({&writer}, [&](const CapturedFrame& frame) { seen.push_back(frame.counters); });
    std::vector<FrameCaptureCounters> expected(3);
    expected[1].attempts = 2;
    expected[1].incomplete_images = 1;
    expected[2].attempts = 2;
    expected[2].lost_images = 1;
    expected[2].stale_images = 1;
    if (transport) {
      expected[0].transport = FrameTransportCounters{0, 0, 0};
      expected[1].transport = FrameTransportCounters{0, 10, 0};
      expected[2].transport = FrameTransportCounters{0, 0, 1};  // the stale image was waiting before the new one
    }
    ASSERT_EQ(seen.size(), 3u);
    for (std::size_t f = 0; f < seen.size(); ++f) EXPECT_EQ(seen[f], expected[f]) << "frame " << f;
    EXPECT_EQ(stats.retries, 2);
    EXPECT_EQ(stats.incomplete_images, 1);
    EXPECT_EQ(stats.lost_images, 1);
    EXPECT_EQ(stats.stale_images, 1);
    EXPECT_EQ(stats.transport, transport ? std::optional(FrameTransportCounters{0, 10, 1}) : std::nullopt);
    const RecordingReader reader = RecordingReader::open(bench.dir.file("rec"));
    ASSERT_EQ(reader.frame_count(), 3u);
    for (std::size_t f = 0; f < 3; ++f) EXPECT_EQ(reader.frame(f).capture, expected[f]) << "frame " << f;
  }
}

TEST(CaptureSequencer, ALostImageIsRecapturedAndTheCamerasCountFollowed) {
  Bench bench;
  bench.camera.faults[3] = Fault::kLost;              // numbered, never arrives: the wait times out
  bench.camera.faults[17 + 17 + 8] = Fault::kLostThenExtra;  // ours lost, a spurious later frame arrives
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(3));
  const CaptureStatistics stats = sequencer.run({&writer});
  EXPECT_EQ(stats.retries, 2);
  EXPECT_EQ(stats.timeouts, 1);
  EXPECT_EQ(stats.lost_images, 2);
  EXPECT_EQ(stats.incomplete_frames, 0);
  expect_recording_shows_the_scene(bench.dir.file("rec"), 3);
}

TEST(CaptureSequencer, ALateImageIsDroppedNotFiledUnderTheNextPattern) {
  Bench bench;
  bench.camera.faults[7] = Fault::kLate;
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(2));
  const CaptureStatistics stats = sequencer.run({&writer});
  EXPECT_EQ(stats.timeouts, 1);
  EXPECT_EQ(stats.stale_images, 1);
  EXPECT_EQ(stats.retries, 1);
  expect_recording_shows_the_scene(bench.dir.file("rec"), 2);
}

TEST(CaptureSequencer, AnIgnoredTriggerCostsOneMoreAttemptThenTheCountResynchronises) {
  Bench bench;
  bench.camera.faults[4] = Fault::kIgnored;
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(2));
  const CaptureStatistics stats = sequencer.run({&writer});
  // Attempt 1 times out on pattern 4; attempt 2 takes the camera's next frame for a late one and
  // times out again; attempt 3 follows the camera's count and succeeds.
  EXPECT_EQ(stats.retries, 2);
  EXPECT_EQ(stats.timeouts, 2);
  EXPECT_EQ(stats.incomplete_frames, 0);
  expect_recording_shows_the_scene(bench.dir.file("rec"), 2);
}

TEST(CaptureSequencer, WhenRetriesRunOutTheFrameIsMarkedIncompleteWithItsWholeImages) {
  Bench bench;
  bench.camera.always_incomplete[1] = 6;  // frame 1 never gets pattern 6 whole
  RecordingWriter writer = bench.writer();
  CaptureOptions options = bench.options(3);
  options.max_retries = 3;
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, options);
  const CaptureStatistics stats = sequencer.run({&writer});
  EXPECT_EQ(stats.frames, 3);
  EXPECT_EQ(stats.incomplete_frames, 1);
  EXPECT_EQ(stats.retries, 3);
  EXPECT_EQ(stats.incomplete_images, 4);
  const RecordingReader reader = RecordingReader::open(bench.dir.file("rec"));
  reader.verify(true);
  ASSERT_EQ(reader.frame_count(), 3u);
  EXPECT_TRUE(reader.frame(0).complete);
  EXPECT_FALSE(reader.frame(1).complete);
  EXPECT_EQ(reader.frame(1).image_files.size(), 6u) << "patterns 0..5, all whole";
  EXPECT_NE(reader.frame(1).note.find("incomplete after 4 attempt(s): 6 of 17 patterns whole"), std::string::npos)
      << reader.frame(1).note;
  EXPECT_TRUE(reader.frame(2).complete);
  expect_recording_shows_the_scene(bench.dir.file("rec"), 3);
}

TEST(CaptureSequencer, ACameraThatStopsAnsweringIsNamedAndTheFramesBeforeAreKept) {
  Bench bench;
  bench.camera.silent_from_frame = 2;
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(4));
  const Error error = expect_error([&] { sequencer.run({&writer}); }, ErrorCode::kTimeout);
  const std::string message = error.what();
  EXPECT_NE(message.find("capture frame 2 of 4 (turntable at 180.000 deg), pattern 0 of 17"), std::string::npos)
      << message;
  EXPECT_NE(message.find("no image in any of 3 attempt(s): camera test://camera0"), std::string::npos) << message;
  EXPECT_EQ(bench.camera.stops, 0) << "the failed camera is left alone";
  EXPECT_EQ(bench.projector.go_dark_calls, 1);
  expect_recording_shows_the_scene(bench.dir.file("rec"), 2);
  RecordingReader::open(bench.dir.file("rec")).verify(true);
}

TEST(CaptureSequencer, AGoneCameraEndsTheScanAtOnce) {
  Bench bench;
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(3));
  const Error error = expect_error(
      [&] {
        sequencer.run({&writer}, [&](const CapturedFrame& frame) { bench.camera.gone = frame.index == 0; });
      },
      ErrorCode::kDevice);
  EXPECT_NE(std::string(error.what()).find("frame 1 of 3"), std::string::npos) << error.what();
  EXPECT_NE(std::string(error.what()).find("camera test://camera0: test://camera0: camera gone"), std::string::npos)
      << error.what();
  expect_recording_shows_the_scene(bench.dir.file("rec"), 1);
}

TEST(CaptureSequencer, AProjectorErrorIsNamedWithFrameAndPattern) {
  Bench bench;
  bench.projector.fail_at_frame = 1;
  bench.projector.fail_at_pattern = 9;
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(3));
  const Error error = expect_error([&] { sequencer.run({&writer}); }, ErrorCode::kDevice);
  EXPECT_STREQ(error.what(),
               "capture frame 1 of 3 (turntable at 90.000 deg), pattern 9 of 17: projector test://projector: "
               "test projector: endpoint stalled");
  EXPECT_EQ(bench.projector.go_dark_calls, 0) << "the failed projector is left alone";
  EXPECT_EQ(bench.camera.stops, 1);
  expect_recording_shows_the_scene(bench.dir.file("rec"), 1);
}

TEST(CaptureSequencer, ATurntableErrorIsNamedAndTheFramesBeforeAreKept) {
  Bench bench;
  bench.turntable.fail_at_frame = 2;
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(4));
  const Error error = expect_error([&] { sequencer.run({&writer}); }, ErrorCode::kTimeout);
  EXPECT_NE(std::string(error.what()).find("capture frame 2 of 4 (turntable at 90.000 deg), moving to 180.000 deg: "
                                           "turntable: test turntable: not at 180 deg"),
            std::string::npos)
      << error.what();
  expect_recording_shows_the_scene(bench.dir.file("rec"), 2);
}

TEST(CaptureSequencer, CancellingKeepsTheFramesDone) {
  Bench bench;
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(4));
  expect_error([&] { sequencer.run({&writer}, {}, [](const ProgressUpdate& update) { return update.done < 2; }); },
               ErrorCode::kCancelled);
  EXPECT_EQ(bench.camera.stops, 1);
  EXPECT_EQ(bench.projector.current_pattern(), -1);
  expect_recording_shows_the_scene(bench.dir.file("rec"), 2);
}

TEST(CaptureSequencer, TwoCamerasFillTwoRecordings) {
  Bench bench;
  ScriptedCamera second(bench.stage, "test://camera1");
  bench.camera.faults[17 + 3] = Fault::kIncomplete;  // the first camera spoils frame 1 once
  RecordingWriter first_writer = bench.writer("rec0");
  RecordingWriter second_writer = bench.writer("rec1");
  CaptureSequencer sequencer(bench.projector, {&bench.camera, &second}, &bench.turntable, bench.patterns,
                             bench.options(2));
  const CaptureStatistics stats = sequencer.run({&first_writer, &second_writer});
  EXPECT_EQ(stats.retries, 1);
  EXPECT_EQ(stats.stale_images, 1) << "the second camera's image of the aborted pattern is dropped";
  expect_recording_shows_the_scene(bench.dir.file("rec0"), 2);
  expect_recording_shows_the_scene(bench.dir.file("rec1"), 2);
}

TEST(CaptureSequencer, RefusesRecordingsAndOptionsThatDoNotFit) {
  Bench bench;
  CaptureOptions bad = bench.options(1);
  bad.max_retries = -1;
  EXPECT_THROW(CaptureSequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bad), Error);
  EXPECT_THROW(CaptureSequencer(bench.projector, {}, nullptr, bench.patterns, bench.options(1)), Error);
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, nullptr, bench.patterns, bench.options(1));
  RecordingInfo info = make_recording_info(bench.projector, bench.camera, bench.patterns);
  info.camera.width = kWidth + 1;
  RecordingWriter wrong_size = RecordingWriter::create(bench.dir.file("wrong"), info, std::nullopt);
  const Error error = expect_error([&] { sequencer.run({&wrong_size}); }, ErrorCode::kInvalidArgument);
  EXPECT_NE(std::string(error.what()).find("does not fit camera test://camera0"), std::string::npos) << error.what();
  EXPECT_EQ(bench.camera.starts, 0) << "no device touched";
  EXPECT_THROW(sequencer.run({nullptr}), Error);
}

TEST(CaptureSequencer, WithoutATurntableEveryStackIsTakenWhereTheObjectStands) {
  Bench bench;
  RecordingWriter writer = bench.writer();
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, nullptr, bench.patterns, bench.options(2));
  sequencer.run({&writer});
  const RecordingReader reader = RecordingReader::open(bench.dir.file("rec"));
  ASSERT_EQ(reader.frame_count(), 2u);
  EXPECT_FALSE(reader.frame(1).turntable_angle_deg.has_value());
  EXPECT_TRUE(reader.load_image(1, 3) == scene_image(0, 3));
}

#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)  // they need the address space
// Runs `capture` (which makes its sequencer, and runs it) in a child limited by ulimit -v to 64 MiB
// more than it uses. Returns its exit status: 0 refused with kOutOfMemory, the message holding
// every string of `named`, before any device moved; 1 captured beyond the limit; 2 another error,
// or a device moved; 3 no limit could be set.
int refused_under_the_memory_limit(const Bench& bench, const std::vector<std::string>& named,
                                   const std::function<void()>& capture) {
  const pid_t child = fork();
  if (child < 0) return -1;
  if (child == 0) {
    if (!test::limit_address_space(64ull << 20)) _exit(3);
    try {
      capture();
    } catch (const Error& error) {
      bool said = error.code() == ErrorCode::kOutOfMemory;
      for (const std::string& words : named) said = said && std::string(error.what()).find(words) != std::string::npos;
      const bool untouched = bench.stage.shown == -1 && bench.turntable.homes == 0 && bench.camera.starts == 0;
      _exit(said && untouched ? 0 : 2);
    }
    _exit(1);
  }
  int status = 0;
  if (waitpid(child, &status, 0) != child || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

constexpr const char* kRefusedStatuses =
    "0: refused, naming it; 1: captured beyond the limit; 2: another error, or a device moved; 3: no limit";

// A camera of 4000x3000 and 17 patterns: a 389 MiB stack, in a child limited to its size plus
// 64 MiB (ulimit -v). The capture is refused before anything moves, naming the stack and the
// limit: no pattern shown, the turntable not homed.
TEST(CaptureSequencer, AStackBeyondTheMemoryLimitIsRefusedBeforeAnythingMoves) {
  if (!test::address_space_limits_hold()) GTEST_SKIP() << "ulimit -v does not bind here (a user-mode emulator)";
  Bench bench;
  bench.camera.width = 4000;
  bench.camera.height = 3000;
  EXPECT_EQ(refused_under_the_memory_limit(bench, {"pattern stack (17 images from 1 camera(s)) needs 389", "ulimit -v"},
                                           [&] {
                                             CaptureSequencer sequencer(bench.projector, {&bench.camera},
                                                                        &bench.turntable, bench.patterns,
                                                                        bench.options(2));
                                             sequencer.run({});
                                           }),
            0)
      << kRefusedStatuses;
}

// The stacks the recording's writer thread and the per-frame callback still hold count too: a
// 1100x1000 camera's 36 MiB stack fits the 64 MiB left by ulimit -v, but not the 4 a capture with
// the writer's default queue may hold (the one captured, 2 queued, 1 being written), nor the 3 of
// a callback that keeps 2, nor the 2 of a two-frame run; each is refused before anything moves.
TEST(CaptureSequencer, TheStacksStillBeingWrittenOrFusedAreAdmittedToo) {
  if (!test::address_space_limits_hold()) GTEST_SKIP() << "ulimit -v does not bind here (a user-mode emulator)";
  struct Case {
    int frames;
    bool record;
    std::size_t callback_holds;
    const char* named;
  };
  const Case cases[] = {{4, true, 0, "up to 4 at once"}, {4, false, 2, "up to 3 at once"}, {2, true, 0, "up to 2 at once"}};
  for (const Case& c : cases) {
    Bench bench;
    bench.camera.width = 1100;
    bench.camera.height = 1000;
    EXPECT_EQ(refused_under_the_memory_limit(bench, {c.named, "17 images from 1 camera(s)"},
                                             [&] {
                                               std::optional<RecordingWriter> writer;
                                               if (c.record) writer.emplace(bench.writer());
                                               CaptureOptions options = bench.options(c.frames);
                                               options.callback_holds_frames = c.callback_holds;
                                               CaptureSequencer sequencer(bench.projector, {&bench.camera},
                                                                          &bench.turntable, bench.patterns, options);
                                               sequencer.run(writer ? std::vector<RecordingWriter*>{&*writer}
                                                                    : std::vector<RecordingWriter*>{});
                                             }),
              0)
        << c.named << " (" << kRefusedStatuses << ")";
  }
}
#endif

// The simulated scanner through the sequencer gives the images of the simulator's own
// recording path (same rig, same seeds): one capture model for both.
TEST(CaptureSequencer, SimulatedScannerGivesTheSimulatorsRecording) {
  test::TemporaryDirectory dir;
  sim::SimRecordingOptions sim_options;
  sim_options.rig.preset = "ci";
  sim_options.rig.frames = 3;
  sim_options.rig.camera_width = 120;
  sim_options.reference_spacing_m = 1e-3;
  sim::write_sim_recording(dir.file("direct"), sim_options, Device::cpu(), {});

  const auto scanner = sim::SimScanner::create(sim_options.object, sim_options.rig, Device::cpu());
  auto projector = scanner->projector();
  auto camera = scanner->camera();
  auto turntable = scanner->turntable();
  CaptureOptions options;
  options.frames_per_revolution = 3;
  RecordingWriter writer =
      RecordingWriter::create(dir.file("sequenced"), make_recording_info(*projector, *camera, scanner->rig().patterns),
                              scanner->rig().calibration());
  CaptureSequencer sequencer(*projector, {camera.get()}, turntable.get(), scanner->rig().patterns, options);
  sequencer.run({&writer});

  const RecordingReader direct = RecordingReader::open(dir.file("direct"));
  const RecordingReader sequenced = RecordingReader::open(dir.file("sequenced"));
  ASSERT_EQ(sequenced.frame_count(), 3u);
  for (std::size_t f = 0; f < 3; ++f) {
    EXPECT_EQ(sequenced.frame(f).timestamp_ns, direct.frame(f).timestamp_ns);
    EXPECT_EQ(sequenced.frame(f).turntable_angle_deg, direct.frame(f).turntable_angle_deg);
    const std::vector<Image16u> a = direct.load_images(f);
    const std::vector<Image16u> b = sequenced.load_images(f);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_TRUE(a[k] == b[k]) << "frame " << f << " pattern " << k;
  }
}

}  // namespace
}  // namespace sls::session

namespace sls::session {
namespace {

// A capture cut off after two frames goes on from the third into the same recording (a
// writer re-opened as after a restart): the recording is the uninterrupted one.
TEST(CaptureSequencer, AResumedCaptureContinuesFromTheFirstMissingFrame) {
  Bench bench;
  {
    RecordingWriter writer = bench.writer();
    CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, bench.options(4));
    expect_error([&] { sequencer.run({&writer}, {}, [](const ProgressUpdate& update) { return update.done < 2; }); },
                 ErrorCode::kCancelled);
  }
  RecordingWriterOptions writer_options;
  writer_options.sync = false;
  RecordingWriter writer = RecordingWriter::append_to(bench.dir.file("rec"), writer_options);
  ASSERT_EQ(writer.frame_count(), 2u);

  CaptureOptions wrong = bench.options(4);
  wrong.first_frame = 1;
  CaptureSequencer mismatched(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, wrong);
  const int starts = bench.camera.starts;
  const Error error = expect_error([&] { mismatched.run({&writer}); }, ErrorCode::kInvalidArgument);
  EXPECT_NE(std::string(error.what()).find("holds 2 frame(s); the capture resumes at frame 1"), std::string::npos)
      << error.what();
  EXPECT_EQ(bench.camera.starts, starts) << "no device touched";
  CaptureOptions beyond = bench.options(4);
  beyond.first_frame = 5;
  EXPECT_THROW(CaptureSequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, beyond), Error);

  CaptureOptions options = bench.options(4);
  options.first_frame = 2;
  CaptureSequencer sequencer(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, options);
  std::vector<int> indices;
  std::vector<std::size_t> progress;
  const CaptureStatistics stats = sequencer.run(
      {&writer}, [&](const CapturedFrame& frame) { indices.push_back(frame.index); },
      [&](const ProgressUpdate& update) {
        EXPECT_EQ(update.total, 4u);
        progress.push_back(update.done);
        return true;
      });
  EXPECT_EQ(stats.frames, 2);
  EXPECT_EQ(indices, (std::vector<int>{2, 3}));
  EXPECT_EQ(progress, (std::vector<std::size_t>{3, 4}));
  expect_recording_shows_the_scene(bench.dir.file("rec"), 4);
  const RecordingReader reader = RecordingReader::open(bench.dir.file("rec"));
  for (std::size_t f = 0; f < 4; ++f) {
    EXPECT_EQ(reader.frame(f).index, static_cast<int>(f));
    EXPECT_DOUBLE_EQ(*reader.frame(f).turntable_angle_deg, 90.0 * static_cast<double>(f));
  }

  // Everything captured: nothing to do, no device touched.
  CaptureOptions done = bench.options(4);
  done.first_frame = 4;
  CaptureSequencer finished(bench.projector, {&bench.camera}, &bench.turntable, bench.patterns, done);
  const int triggers = bench.camera.software_triggers;
  EXPECT_EQ(finished.run({&writer}).frames, 0);
  EXPECT_EQ(bench.camera.software_triggers, triggers);
}

// The simulated scanner, cut off and resumed by a fresh scanner (a new process): the same
// images as the simulator's direct, uninterrupted recording.
TEST(CaptureSequencer, ASimulatedCaptureResumedByNewDevicesGivesTheUninterruptedImages) {
  test::TemporaryDirectory dir;
  sim::SimRecordingOptions sim_options;
  sim_options.rig.preset = "ci";
  sim_options.rig.frames = 3;
  sim_options.rig.camera_width = 96;
  sim_options.reference_spacing_m = 1e-3;
  sim::write_sim_recording(dir.file("direct"), sim_options, Device::cpu(), {});

  for (const int first_frame : {0, 1}) {
    const auto scanner = sim::SimScanner::create(sim_options.object, sim_options.rig, Device::cpu());
    auto projector = scanner->projector();
    auto camera = scanner->camera();
    auto turntable = scanner->turntable();
    CaptureOptions options;
    options.frames_per_revolution = 3;
    options.first_frame = first_frame;
    RecordingWriter writer =
        first_frame == 0 ? RecordingWriter::create(dir.file("sequenced"),
                                                   make_recording_info(*projector, *camera, scanner->rig().patterns),
                                                   scanner->rig().calibration())
                         : RecordingWriter::append_to(dir.file("sequenced"));
    CaptureSequencer sequencer(*projector, {camera.get()}, turntable.get(), scanner->rig().patterns, options);
    if (first_frame == 0) {
      expect_error([&] { sequencer.run({&writer}, {}, [](const ProgressUpdate& update) { return update.done < 1; }); },
                   ErrorCode::kCancelled);
    } else {
      sequencer.run({&writer});
    }
  }

  const RecordingReader direct = RecordingReader::open(dir.file("direct"));
  const RecordingReader sequenced = RecordingReader::open(dir.file("sequenced"));
  ASSERT_EQ(sequenced.frame_count(), 3u);
  for (std::size_t f = 0; f < 3; ++f) {
    EXPECT_EQ(sequenced.frame(f).timestamp_ns, direct.frame(f).timestamp_ns);
    EXPECT_EQ(sequenced.frame(f).turntable_angle_deg, direct.frame(f).turntable_angle_deg);
    const std::vector<Image16u> a = direct.load_images(f);
    const std::vector<Image16u> b = sequenced.load_images(f);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_TRUE(a[k] == b[k]) << "frame " << f << " pattern " << k;
  }
}

}  // namespace
}  // namespace sls::session
