// replay:// devices (drivers/replay) on small synthetic recordings whose every image names its
// frame and pattern: the capture sequencer re-records them image for image (with the turntable,
// without it, on the hardware trigger line, with an incomplete frame), the devices of one URI
// share the recording, the projector refuses another pattern set, the turntable answers the
// recorded angles, and the end of the recording, a missing or corrupt recording and bad URIs
// are clear errors. timing=recorded is checked with an injected clock (no wall-clock
// assertions).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/device_registry.h"
#include "drivers/replay/replay_recording.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/session/capture_sequencer.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

using std::chrono::milliseconds;
using test::TemporaryDirectory;

constexpr int kWidth = 8;
constexpr int kHeight = 6;

template <typename Call>
std::string expect_error(Call&& call, ErrorCode code) {
  try {
    call();
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), code) << error.what();
    return error.what();
  }
  ADD_FAILURE() << "no sls::Error thrown";
  return {};
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

PatternSet small_set(int projector_width = 64) {
  GrayPhaseOptions options;
  options.projector_width = projector_width;
  options.projector_height = 16;
  options.phase_steps = 3;
  options.phase_period_px = 8;
  return make_gray_phase_pattern_set(options);
}

// Pixel (x, y) of frame f, pattern p: distinct per image and per pixel, within 12 bits.
std::uint16_t pixel(int frame, int pattern, int x, int y) {
  return static_cast<std::uint16_t>((frame * 97 + pattern * 13 + x * 7 + y * 3) % 4096);
}

struct RecordedFrame {
  std::optional<double> angle;
  std::int64_t timestamp_ns = 0;
  int images = -1;  // fewer than the set's: an incomplete frame
};

// A recording of `frames` in the format `sls scan` writes (a 12-bit camera, the small set).
std::string write_recording(const TemporaryDirectory& dir, const std::string& name,
                            const std::vector<RecordedFrame>& frames) {
  const PatternSet patterns = small_set();
  RecordingInfo info;
  info.device = {"sim://recorded?preset=ci", "rec projector + rec camera", "REC-0"};
  info.camera = {kWidth, kHeight, 12};
  info.pattern_set_json = pattern_set_to_json(patterns);
  info.images_per_frame = static_cast<int>(patterns.size());
  RecordingWriterOptions options;
  options.sync = false;
  RecordingWriter writer = RecordingWriter::create(dir.file(name), info, std::nullopt, options);
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const int count = frames[f].images < 0 ? static_cast<int>(patterns.size()) : frames[f].images;
    std::vector<Image16u> images;
    for (int p = 0; p < count; ++p) {
      Image16u image(kWidth, kHeight);
      for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) image(x, y) = pixel(static_cast<int>(f), p, x, y);
      }
      images.push_back(std::move(image));
    }
    FrameMetadata metadata;
    metadata.timestamp_ns = frames[f].timestamp_ns;
    metadata.turntable_angle_deg = frames[f].angle;
    metadata.complete = count == static_cast<int>(patterns.size());
    if (!metadata.complete) metadata.note = "camera timed out";
    writer.append_frame(images, metadata);
  }
  return dir.file(name);
}

std::vector<RecordedFrame> revolution(int frames, double jitter_deg = 0.0) {
  std::vector<RecordedFrame> recorded;
  for (int f = 0; f < frames; ++f) {
    recorded.push_back({360.0 * f / frames + jitter_deg, 1'000'000'000LL + f * 250'000'000LL, -1});
  }
  return recorded;
}

struct ReplayDevices {
  std::unique_ptr<drivers::Projector> projector;
  std::unique_ptr<drivers::Camera> camera;
  std::unique_ptr<drivers::Turntable> turntable;
};

ReplayDevices open_devices(const std::string& uri, bool turntable = true) {
  ReplayDevices devices;
  devices.projector = drivers::open_projector(uri);
  devices.camera = drivers::open_camera(uri);
  if (turntable) devices.turntable = drivers::open_turntable(uri);
  return devices;
}

// Captures `frames` stacks through the sequencer from `devices` into a new recording `copy`.
session::CaptureStatistics capture(ReplayDevices& devices, const std::string& copy, int frames,
                                   drivers::TriggerSource trigger = drivers::TriggerSource::kSoftware) {
  session::CaptureOptions options;
  options.frames_per_revolution = frames;
  options.trigger = trigger;
  const PatternSet patterns = devices.projector->patterns();
  RecordingWriterOptions writer_options;
  writer_options.sync = false;
  RecordingWriter writer = RecordingWriter::create(
      copy, session::make_recording_info(*devices.projector, *devices.camera, patterns), std::nullopt, writer_options);
  session::CaptureSequencer sequencer(*devices.projector, {devices.camera.get()}, devices.turntable.get(), patterns,
                                      options);
  return sequencer.run({&writer});
}

// The copy holds what the original holds: every image pixel for pixel, timestamps, angles,
// completeness, pattern set, camera and device model.
void expect_same_recording(const std::string& original_folder, const std::string& copy_folder) {
  const RecordingReader original = RecordingReader::open(original_folder);
  const RecordingReader copy = RecordingReader::open(copy_folder);
  EXPECT_EQ(copy.info().pattern_set_json, original.info().pattern_set_json);
  EXPECT_EQ(copy.info().images_per_frame, original.info().images_per_frame);
  EXPECT_EQ(copy.info().camera.width, original.info().camera.width);
  EXPECT_EQ(copy.info().camera.bit_depth, original.info().camera.bit_depth);
  EXPECT_EQ(copy.info().device.model, original.info().device.model);
  EXPECT_EQ(copy.info().device.serial, original.info().device.serial);
  ASSERT_EQ(copy.frame_count(), original.frame_count());
  for (std::size_t f = 0; f < original.frame_count(); ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    EXPECT_EQ(copy.frame(f).timestamp_ns, original.frame(f).timestamp_ns);
    EXPECT_EQ(copy.frame(f).turntable_angle_deg, original.frame(f).turntable_angle_deg);
    EXPECT_EQ(copy.frame(f).complete, original.frame(f).complete);
    const std::vector<Image16u> ours = copy.load_images(f);
    const std::vector<Image16u> theirs = original.load_images(f);
    ASSERT_EQ(ours.size(), theirs.size());
    for (std::size_t i = 0; i < ours.size(); ++i) EXPECT_TRUE(ours[i] == theirs[i]) << "image " << i;
  }
}

TEST(ReplayDevices, ACaptureThroughThemReRecordsTheRecording) {
  TemporaryDirectory dir;
  const std::string original = write_recording(dir, "rec", revolution(4, 0.01));
  const std::string uri = "replay://" + original;
  ReplayDevices devices = open_devices(uri);
  EXPECT_EQ(devices.camera->info().uri, uri);
  EXPECT_EQ(devices.camera->info().model, "rec camera");
  EXPECT_EQ(devices.projector->info().model, "rec projector");
  EXPECT_EQ(devices.projector->info().width, 64);
  EXPECT_EQ(devices.turntable->steps_per_revolution(), 4);
  const session::CaptureStatistics statistics = capture(devices, dir.file("copy"), 4);
  EXPECT_EQ(statistics.frames, 4);
  EXPECT_EQ(statistics.retries, 0);
  expect_same_recording(original, dir.file("copy"));
  EXPECT_EQ(RecordingReader::open(dir.file("copy")).info().device.uri, uri) << "what it was captured from";
  EXPECT_DOUBLE_EQ(devices.turntable->position_deg(), 270.01) << "the recorded angle, not the commanded one";
}

TEST(ReplayDevices, WithoutATurntableFramesPlayInOrderUntilTheEnd) {
  TemporaryDirectory dir;
  std::vector<RecordedFrame> frames = revolution(3);
  for (RecordedFrame& frame : frames) frame.angle.reset();
  const std::string original = write_recording(dir, "rec", frames);
  const std::string uri = "replay://" + original + "?timing=fast";
  std::string message = expect_error([&] { drivers::open_turntable(uri); }, ErrorCode::kUnsupported);
  EXPECT_TRUE(contains(message, "without a turntable")) << message;
  {
    ReplayDevices devices = open_devices(uri, false);
    capture(devices, dir.file("copy"), 3);
    expect_same_recording(original, dir.file("copy"));
  }
  // A fourth stack: the recording has ended.
  ReplayDevices devices = open_devices(uri, false);
  message = expect_error([&] { capture(devices, dir.file("longer"), 4); }, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(message, "end of the recording") && contains(message, uri)) << message;
  EXPECT_EQ(RecordingReader::open(dir.file("longer")).frame_count(), 3u) << "the frames before the end are kept";
}

TEST(ReplayDevices, TheHardwareTriggerLineGivesTheSameCopy) {
  TemporaryDirectory dir;
  const std::string original = write_recording(dir, "rec", revolution(3));
  ReplayDevices devices = open_devices("replay://" + original);
  capture(devices, dir.file("copy"), 3, drivers::TriggerSource::kHardwareLine);
  expect_same_recording(original, dir.file("copy"));
}

TEST(ReplayDevices, AnIncompleteFrameIsRecordedIncompleteAgain) {
  TemporaryDirectory dir;
  std::vector<RecordedFrame> frames = revolution(3);
  frames[1].images = 5;
  const std::string original = write_recording(dir, "rec", frames);
  ReplayDevices devices = open_devices("replay://" + original);
  const session::CaptureStatistics statistics = capture(devices, dir.file("copy"), 3);
  EXPECT_EQ(statistics.incomplete_frames, 1);
  expect_same_recording(original, dir.file("copy"));
  const RecordingReader copy = RecordingReader::open(dir.file("copy"));
  EXPECT_TRUE(contains(copy.frame(1).note, "recorded incomplete (5 of")) << copy.frame(1).note;
  EXPECT_TRUE(contains(copy.frame(1).note, "camera timed out")) << copy.frame(1).note;
}

TEST(ReplayDevices, DevicesOfOneUriShareTheRecording) {
  TemporaryDirectory dir;
  const std::string original = write_recording(dir, "rec", revolution(4));
  // The turntable opened by another spelling of the same folder drives the camera's frame.
  const auto camera = drivers::open_camera("replay://" + original);
  const auto projector = drivers::open_projector("replay://" + original + "/");
  const auto turntable = drivers::open_turntable("replay://" + dir.path() + "/./rec");
  turntable->home(milliseconds(100));
  turntable->move_to_deg(180.0, milliseconds(100));
  EXPECT_DOUBLE_EQ(turntable->position_deg(), 180.0);
  camera->start();
  projector->show_pattern(4);
  camera->software_trigger();
  const drivers::CapturedImage image = camera->wait_image(milliseconds(100));
  EXPECT_TRUE(image.complete);
  EXPECT_EQ(image.image(3, 2), pixel(2, 4, 3, 2)) << "frame 2 (180 deg), pattern 4";
  EXPECT_EQ(image.timestamp_ns, 1'500'000'000LL);
  // Not triggered: a timeout, as a camera gives.
  expect_error([&] { camera->wait_image(milliseconds(1)); }, ErrorCode::kTimeout);
  projector->go_dark();
  const std::string message = expect_error([&] { camera->software_trigger(); }, ErrorCode::kInvalidArgument);
  EXPECT_TRUE(contains(message, "dark")) << message;
}

TEST(ReplayDevices, TheTurntableAnswersOnlyRecordedAngles) {
  TemporaryDirectory dir;
  const std::string original = write_recording(dir, "rec", revolution(4));
  const std::string uri = "replay://" + original;
  const auto turntable = drivers::open_turntable(uri);
  expect_error([&] { turntable->move_to_deg(90.0, milliseconds(1)); }, ErrorCode::kInvalidArgument);  // not homed
  turntable->home(milliseconds(1));
  EXPECT_DOUBLE_EQ(turntable->position_deg(), 0.0);
  turntable->move_to_deg(90.3, milliseconds(1));  // a table's rounding to its steps
  EXPECT_DOUBLE_EQ(turntable->position_deg(), 90.0);
  std::string message = expect_error([&] { turntable->move_to_deg(100.0, milliseconds(1)); }, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(message, "no recorded frame at 100.000 deg") && contains(message, "frame 1 at 90.000"))
      << message;
  message = expect_error([&] { turntable->move_to_deg(360.0, milliseconds(1)); }, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(message, "ends before it") && contains(message, "0.000 .. 270.000")) << message;

  // A capture of more frames than recorded ends there, naming the turntable's move.
  ReplayDevices devices = open_devices(uri);
  session::CaptureOptions options;
  options.frames_per_revolution = 4;
  options.frames = 5;
  const PatternSet patterns = devices.projector->patterns();
  session::CaptureSequencer sequencer(*devices.projector, {devices.camera.get()}, devices.turntable.get(), patterns,
                                      options);
  message = expect_error([&] { sequencer.run({}); }, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(message, "frame 4 of 5") && contains(message, "turntable")) << message;
}

TEST(ReplayDevices, TheProjectorRefusesAnotherPatternSetNamingBoth) {
  TemporaryDirectory dir;
  const std::string original = write_recording(dir, "rec", revolution(2));
  const auto projector = drivers::open_projector("replay://" + original);
  EXPECT_TRUE(projector->patterns() == small_set());
  projector->load_patterns(small_set());
  const PatternSet other = small_set(128);
  const std::string message = expect_error([&] { projector->load_patterns(other); }, ErrorCode::kInvalidArgument);
  EXPECT_TRUE(contains(message, small_set().name) && contains(message, other.name)) << message;
  EXPECT_TRUE(contains(message, "64x16") && contains(message, "128x16")) << message;
  expect_error([&] { projector->show_pattern(static_cast<int>(other.size()) + 5); }, ErrorCode::kInvalidArgument);
}

TEST(ReplayDevices, MissingOrCorruptRecordingsAndBadUrisAreClearErrors) {
  TemporaryDirectory dir;
  std::string message =
      expect_error([&] { drivers::open_camera("replay://" + dir.file("nothing")); }, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(message, "replay://" + dir.file("nothing"))) << message;
  const std::string original = write_recording(dir, "rec", revolution(2));
  message = expect_error([&] { drivers::open_camera("replay://" + original + "?speed=2"); },
                         ErrorCode::kInvalidArgument);
  EXPECT_TRUE(contains(message, "speed")) << message;
  expect_error([&] { drivers::open_camera("replay://" + original + "?timing=slow"); }, ErrorCode::kInvalidArgument);
  expect_error([&] { drivers::open_camera("replay://"); }, ErrorCode::kInvalidArgument);

  // A frame's image gone: the capture ends naming the file.
  std::remove((original + "/frames/000001/pattern_002.png").c_str());
  ReplayDevices devices = open_devices("replay://" + original);
  message = expect_error([&] { capture(devices, dir.file("copy"), 2); }, ErrorCode::kNotFound);
  EXPECT_TRUE(contains(message, "pattern_002.png")) << message;

  std::ofstream(original + "/manifest.json") << "{\"format\": ";
  message = expect_error([&] { drivers::open_projector("replay://" + original + "?timing=recorded"); },
                         ErrorCode::kFormat);
  EXPECT_TRUE(contains(message, "manifest.json")) << message;
}

// A clock that records the waits and jumps to their end.
class FakeClock final : public replay::ReplayClock {
 public:
  TimePoint now() const override { return now_; }
  void sleep_until(TimePoint when) override {
    waits.push_back(std::chrono::duration_cast<std::chrono::nanoseconds>(when - TimePoint{}).count());
    if (when > now_) now_ = when;
  }
  std::vector<std::int64_t> waits;  // since the clock's epoch, ns

 private:
  TimePoint now_{};
};

TEST(ReplayDevices, RecordedTimingWaitsForEachFramesTimestamp) {
  TemporaryDirectory dir;
  std::vector<RecordedFrame> frames = revolution(3);
  frames[2].timestamp_ns = frames[1].timestamp_ns + 2'000'000'000LL;  // a long pause before the last
  const std::string original = write_recording(dir, "rec", frames);
  for (const char* timing : {"fast", "recorded"}) {
    SCOPED_TRACE(timing);
    const auto clock = std::make_shared<FakeClock>();
    const auto replay = replay::ReplayRecording::open("replay://" + original + "?timing=" + timing, clock);
    ReplayDevices devices{replay->projector(), replay->camera(), replay->turntable()};
    capture(devices, dir.file(std::string("copy_") + timing), 3);
    expect_same_recording(original, dir.file(std::string("copy_") + timing));
    if (std::string(timing) == "fast") {
      EXPECT_TRUE(clock->waits.empty());
    } else {
      // The first frame sets the origin (clock time 0); each later one is due its recorded
      // time after it, once per frame however many images it has.
      EXPECT_EQ(clock->waits, (std::vector<std::int64_t>{250'000'000LL, 2'250'000'000LL}));
    }
  }
}

}  // namespace
}  // namespace sls
