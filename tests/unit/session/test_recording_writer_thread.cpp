// The writer thread that tees a live capture's frames to its recording (issue 18,
// sdk/core/recording_writer_thread.h): every frame written in order and the recording equal,
// file for file, to the synchronous capture's; a capture stopped by the scan (a fusion error or
// a cancel) still writes every frame it captured; a write that fails ends the capture naming the
// folder and the frame, keeping what was written; back-pressure counted; --no-record writes
// nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <future>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/recording.h"
#include "sdk/core/recording_writer_thread.h"
#include "tests/support/test_support.h"

namespace sls::sim {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 5;

SimRecordingOptions small_options(std::size_t write_queue_frames) {
  SimRecordingOptions options;
  options.rig.preset = "ci";
  options.rig.frames = kFrames;
  options.rig.camera_width = 96;
  options.reference_spacing_m = 1e-3;
  options.write_queue_frames = write_queue_frames;
  return options;
}

TEST(RecordingWriterThread, WritesEveryFrameInOrderAndTheRecordingEqualsTheSynchronousCapture) {
  test::TemporaryDirectory dir;
  RecordingWriteStatistics threaded, synchronous;
  SimRecordingOptions options = small_options(2);
  options.write_statistics = &threaded;
  std::vector<int> delivered;
  options.on_recorded = [&](int frame, const std::shared_ptr<const std::vector<Image16u>>& images,
                            const FrameMetadata&, Image32f*) {
    delivered.push_back(frame);
    EXPECT_FALSE(images->empty());
  };
  write_sim_recording(dir.file("threaded"), options, Device::cpu(), {});
  SimRecordingOptions direct = small_options(0);
  direct.write_statistics = &synchronous;
  write_sim_recording(dir.file("direct"), direct, Device::cpu(), {});

  EXPECT_EQ(delivered, (std::vector<int>{0, 1, 2, 3, 4}));
  ASSERT_EQ(threaded.frames.size(), static_cast<std::size_t>(kFrames));
  for (int i = 0; i < kFrames; ++i) EXPECT_EQ(threaded.frames[static_cast<std::size_t>(i)].frame, i);
  EXPECT_EQ(threaded.queue_frames, 2u);
  EXPECT_EQ(synchronous.frames.size(), static_cast<std::size_t>(kFrames));
  EXPECT_GT(threaded.write_s_total(), 0.0);
  const RecordingReader recording = RecordingReader::open(dir.file("threaded"));
  ASSERT_EQ(recording.frame_count(), static_cast<std::size_t>(kFrames));
  for (std::size_t i = 0; i < recording.frame_count(); ++i) EXPECT_EQ(recording.frame(i).index, static_cast<int>(i));
  EXPECT_EQ(test::recording_snapshot(dir.file("threaded")), test::recording_snapshot(dir.file("direct")));
}

TEST(RecordingWriterThread, AScanThatStopsFusingStillLeavesEveryCapturedFrameOnDisk) {
  test::TemporaryDirectory dir;
  SimRecordingOptions options = small_options(2);
  // Fusion fails (or is cancelled) at frame 2: the capture ends after it, and every frame it
  // captured — those still queued for the writer included — is written.
  options.on_recorded = [](int frame, const std::shared_ptr<const std::vector<Image16u>>&, const FrameMetadata&,
                           Image32f*) {
    if (frame == 2) throw_error(ErrorCode::kCancelled, "the scan stopped fusing");
  };
  // A slow disk: the frames pile up in the writer's queue when the capture ends.
  options.step_hook = [](SimFrameStep step, int) {
    if (step == SimFrameStep::kImagesWritten) std::this_thread::sleep_for(std::chrono::milliseconds(30));
  };
  try {
    write_sim_recording(dir.file("rec"), options, Device::cpu(), {});
    FAIL() << "the capture should have ended with the cancel";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kCancelled);
  }
  const RecordingReader recording = RecordingReader::open(dir.file("rec"));
  EXPECT_EQ(recording.frame_count(), 3u);
  recording.verify(true);
  // And it resumes from there.
  SimRecordingOptions resume = small_options(2);
  resume.resume = true;
  EXPECT_EQ(write_sim_recording(dir.file("rec"), resume, Device::cpu(), {}).resumed_from, 3);
}

TEST(RecordingWriterThread, AWriteFailureEndsTheCaptureNamingTheFolderAndTheFrameAndKeepsWhatWasWritten) {
  test::TemporaryDirectory dir;
  SimRecordingOptions options = small_options(2);
  RecordingWriteStatistics writes;
  options.write_statistics = &writes;
  // The disk fills up while frame 1 is written.
  options.step_hook = [](SimFrameStep step, int frame) {
    if (step == SimFrameStep::kImagesWritten && frame == 1) {
      throw_error(ErrorCode::kIo, "cannot write frame files: No space left on device");
    }
  };
  std::atomic<int> handed_over{0};
  options.on_recorded = [&](int, const std::shared_ptr<const std::vector<Image16u>>&, const FrameMetadata&,
                            Image32f*) { ++handed_over; };
  const std::string folder = dir.file("rec");
  try {
    write_sim_recording(folder, options, Device::cpu(), {});
    FAIL() << "the capture should have ended with the write error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kIo);
    const std::string message = error.what();
    EXPECT_NE(message.find("frame 1"), std::string::npos) << message;
    EXPECT_NE(message.find(folder), std::string::npos) << message;
    EXPECT_NE(message.find("No space left"), std::string::npos) << message;
  }
  EXPECT_EQ(RecordingReader::open(folder).frame_count(), 1u);
  EXPECT_EQ(writes.frames.size(), 1u);
  EXPECT_GE(handed_over.load(), 2);  // the scan had frame 1 (and kept fusing) before the write failed
}

TEST(RecordingWriterThread, NoRecordWritesNothingAndDescribesTheRecordingItWouldHold) {
  test::TemporaryDirectory dir;
  SimRecordingOptions options = small_options(2);
  options.record = false;
  int frames = 0;
  bool described = false;
  options.described = [&](const RecordingInfo& info, const std::optional<ScannerCalibration>& calibration) {
    described = true;
    EXPECT_GT(info.images_per_frame, 0);
    EXPECT_TRUE(calibration.has_value());
  };
  options.on_recorded = [&](int frame, const std::shared_ptr<const std::vector<Image16u>>& images,
                            const FrameMetadata&, Image32f*) {
    EXPECT_EQ(frame, frames++);
    EXPECT_FALSE(images->empty());
  };
  write_sim_recording(dir.file("none"), options, Device::cpu(), {});
  EXPECT_TRUE(described);
  EXPECT_EQ(frames, kFrames);
  EXPECT_FALSE(fs::exists(dir.file("none")));
  options.resume = true;
  EXPECT_THROW(write_sim_recording(dir.file("none"), options, Device::cpu(), {}), Error);
}

TEST(RecordingWriterThread, ABusyDiskHoldsTheCaptureBackCountedAndNeverDropsAFrame) {
  RecordingWriteStatistics statistics;
  std::vector<int> written;
  {
    RecordingWriterThread writes("folder", 1);
    for (int frame = 0; frame < 6; ++frame) {
      writes.push(frame, [&written, frame] {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        written.push_back(frame);
      });
    }
    writes.finish();
    statistics = writes.statistics();
  }
  EXPECT_EQ(written, (std::vector<int>{0, 1, 2, 3, 4, 5}));
  EXPECT_GT(statistics.waits, 0u);
  EXPECT_GT(statistics.wait_s, 0.0);
  EXPECT_EQ(statistics.deepest_queue, 1u);
  EXPECT_EQ(statistics.frames.size(), 6u);
}

TEST(RecordingWriterThread, AFailedWriteIsThrownByTheNextPushAndNothingAfterItIsWritten) {
  std::vector<int> written;
  // Frame 1's write fails only once frame 2 is queued: without the gate, the failure could show
  // before push(2), which would then throw instead (also right, but not what this test checks).
  std::promise<void> frame_2_queued;
  std::shared_future<void> gate = frame_2_queued.get_future().share();
  RecordingWriterThread writes("/full/disk", 4);
  writes.push(0, [&] { written.push_back(0); });
  writes.push(1, [gate] {
    gate.wait();
    throw_error(ErrorCode::kIo, "No space left on device");
  });
  writes.push(2, [&] { written.push_back(2); });
  frame_2_queued.set_value();
  try {
    writes.finish();
    FAIL() << "finish should throw the write error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kIo);
    EXPECT_EQ(std::string(error.what()), "writing frame 1 to the recording /full/disk: No space left on device");
  }
  EXPECT_THROW(writes.push(3, [&] { written.push_back(3); }), Error);
  EXPECT_EQ(written, (std::vector<int>{0}));
}

TEST(RecordingWriterThread, UnwindingWritesEveryQueuedFrame) {
  std::vector<int> written;
  {
    RecordingWriterThread writes("folder", 8);
    for (int frame = 0; frame < 5; ++frame) {
      writes.push(frame, [&written, frame] {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        written.push_back(frame);
      });
    }
  }  // no finish(): a capture unwinding from an error
  EXPECT_EQ(written, (std::vector<int>{0, 1, 2, 3, 4}));
}

}  // namespace
}  // namespace sls::sim
