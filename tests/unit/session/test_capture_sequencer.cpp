// The capture sequencer against scripted in-memory devices (scripted_capture_devices.h: every
// transport fault on demand, incomplete, lost, late and ignored frames, silent and failing
// devices), and the memory it admits before a capture. The simulated scanner and resumed captures:
// test_capture_resume.cpp.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/session/capture_sequencer.h"
#include "tests/support/process_memory.h"
#include "tests/support/test_support.h"
#include "tests/unit/session/scripted_capture_devices.h"

namespace sls::session {
namespace {

using namespace capture_test;

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

}  // namespace
}  // namespace sls::session
