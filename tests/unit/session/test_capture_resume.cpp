// The capture sequencer against the simulated scanner, whose direct recording path it must
// reproduce image for image, and captures cut off and resumed into the same recording (by the
// same scripted devices, scripted_capture_devices.h, and by a new simulated scanner).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/session/capture_sequencer.h"
#include "tests/support/test_support.h"
#include "tests/unit/session/scripted_capture_devices.h"

namespace sls::session {
namespace {

using namespace capture_test;

// The recording at `sequenced` holds `frames` frames, each with the timestamp, table angle and
// images of the same frame of the recording at `direct`.
void expect_same_frames(const std::string& direct_path, const std::string& sequenced_path, std::size_t frames) {
  const RecordingReader direct = RecordingReader::open(direct_path);
  const RecordingReader sequenced = RecordingReader::open(sequenced_path);
  ASSERT_EQ(sequenced.frame_count(), frames);
  for (std::size_t f = 0; f < frames; ++f) {
    EXPECT_EQ(sequenced.frame(f).timestamp_ns, direct.frame(f).timestamp_ns);
    EXPECT_EQ(sequenced.frame(f).turntable_angle_deg, direct.frame(f).turntable_angle_deg);
    const std::vector<Image16u> a = direct.load_images(f);
    const std::vector<Image16u> b = sequenced.load_images(f);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_TRUE(a[k] == b[k]) << "frame " << f << " pattern " << k;
  }
}

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

  expect_same_frames(dir.file("direct"), dir.file("sequenced"), 3);
}

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

  expect_same_frames(dir.file("direct"), dir.file("sequenced"), 3);
}

}  // namespace
}  // namespace sls::session
