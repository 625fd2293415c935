// The frame pipeline (sdk/session/frame_pipeline.h): frames fused as a source thread delivers
// them through a bounded queue. The model equals a sequential run's bit for bit, whatever the
// queue's size; the source never runs further ahead than the queue lets it, and waits are
// counted, no frame dropped; a source's error after some frames fuses them and is rethrown, its
// cancel is an interruption; a cancel or a fault on the fusing side stops and joins the source.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "sdk/core/error.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_session.h"
#include "tests/support/test_support.h"
#include "tests/unit/session/sim_frames.h"

namespace sls::session {
namespace {

constexpr int kFrames = 8;

// The knurled knob's first frames at 10° steps (ci preset, depth maps), made once.
const std::vector<ScanFrame>& knob_frames() {
  static const std::vector<ScanFrame> frames = [] {
    SimFrames sim("knurled-knob", 36);
    std::vector<ScanFrame> out;
    for (int k = 0; k < kFrames; ++k) out.push_back(sim.frame(k));
    return out;
  }();
  return frames;
}

ScannerCalibration knob_calibration() { return SimFrames("knurled-knob", 36).calibration(); }

ScanSessionOptions options() {
  ScanSessionOptions o = small_options(Device::cpu());
  o.turntable_prior = true;
  return o;
}

// Delivers the knob's frames in order; counts what it delivered and whether deliver() refused.
struct CountingSource {
  std::atomic<int> delivered{0};
  std::atomic<bool> refused{false};
  FrameSource source(int count = kFrames) {
    return [this, count](const FrameDelivery& deliver) {
      for (int k = 0; k < count; ++k) {
        ScanFrame frame = knob_frames()[static_cast<std::size_t>(k % kFrames)];
        frame.index = k;
        if (!deliver(std::move(frame))) {
          refused = true;
          return;
        }
        ++delivered;
      }
    };
  }
};

TEST(FramePipeline, FusesTheSameModelAsASequentialRunWhateverTheQueue) {
  const ScannerCalibration calibration = knob_calibration();
  ScanSession sequential(calibration, nullptr, options());
  for (const ScanFrame& frame : knob_frames()) ASSERT_EQ(sequential.add_frame(frame).status, FrameStatus::kFused);
  const fusion::ExtractedSurface expected = sequential.final_surface();
  const std::vector<StampedPose> expected_trajectory = sequential.trajectory();
  ASSERT_GT(expected.cloud.size(), 1000u);

  for (const std::size_t queue : {std::size_t{1}, std::size_t{3}}) {
    ScanSession session(calibration, nullptr, options());
    CountingSource source;
    PipelineOptions pipeline;
    pipeline.queue_frames = queue;
    std::vector<std::size_t> progress;
    const PipelineOutcome outcome = run_pipeline(
        session, source.source(), pipeline, {},
        [&progress](const ProgressUpdate& update) {
          EXPECT_EQ(update.stage, "scan");
          EXPECT_EQ(update.total, static_cast<std::size_t>(kFrames));
          progress.push_back(update.done);
          return true;
        },
        kFrames);
    EXPECT_FALSE(outcome.interrupted) << outcome.interruption;
    EXPECT_EQ(outcome.delivered, static_cast<std::size_t>(kFrames));
    EXPECT_LE(outcome.deepest_queue, queue);
    ASSERT_EQ(outcome.timings.size(), static_cast<std::size_t>(kFrames));
    for (int k = 0; k < kFrames; ++k) {
      const FrameTiming& t = outcome.timings[static_cast<std::size_t>(k)];
      EXPECT_EQ(t.index, k);
      EXPECT_LE(t.delivered_s, t.fused_s);
      if (k > 0) {
        EXPECT_LE(outcome.timings[static_cast<std::size_t>(k - 1)].fused_s, t.fused_s);
      }
    }
    EXPECT_EQ(progress, std::vector<std::size_t>({0, 1, 2, 3, 4, 5, 6, 7, 8}));
    const fusion::ExtractedSurface model = session.final_surface();
    ASSERT_EQ(model.cloud.size(), expected.cloud.size()) << "queue " << queue;
    EXPECT_TRUE(model.cloud.positions == expected.cloud.positions) << "queue " << queue;
    EXPECT_TRUE(model.cloud.normals == expected.cloud.normals) << "queue " << queue;
    const std::vector<StampedPose> trajectory = session.trajectory();
    ASSERT_EQ(trajectory.size(), expected_trajectory.size());
    for (std::size_t i = 0; i < trajectory.size(); ++i) {
      EXPECT_EQ(trajectory[i].T_world_camera.translation(), expected_trajectory[i].T_world_camera.translation());
      EXPECT_EQ(trajectory[i].T_world_camera.rotation(), expected_trajectory[i].T_world_camera.rotation());
    }
  }
}

// A source far faster than fusion: it is held back (never more than the queue plus the frame
// being fused ahead), its waits are counted, and every frame is fused.
TEST(FramePipeline, BackPressureHoldsTheSourceBackAndDropsNothing) {
  ScanSession session(knob_calibration(), nullptr, options());
  std::atomic<int> fused{0};
  std::atomic<int> furthest_ahead{0};
  std::mutex mutex;
  std::condition_variable attempted;
  bool third_attempted = false;
  const FrameSource source = [&](const FrameDelivery& deliver) {
    for (int k = 0; k < kFrames; ++k) {
      if (k == 2) {
        std::lock_guard<std::mutex> lock(mutex);
        third_attempted = true;
        attempted.notify_all();
      }
      ASSERT_TRUE(deliver(ScanFrame(knob_frames()[static_cast<std::size_t>(k)])));
      furthest_ahead = std::max(furthest_ahead.load(), k + 1 - fused.load());
    }
  };
  PipelineOptions pipeline;
  pipeline.queue_frames = 1;
  const PipelineOutcome outcome = run_pipeline(session, source, pipeline, [&](const FrameReport& report) {
    if (report.index == 0) {
      // Fusion is slow here: the source, with frame 1 queued, must wait to hand frame 2 over.
      std::unique_lock<std::mutex> lock(mutex);
      attempted.wait(lock, [&] { return third_attempted; });
      lock.unlock();
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    ++fused;
  });
  EXPECT_FALSE(outcome.interrupted);
  EXPECT_EQ(session.fused_count(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(outcome.delivered, static_cast<std::size_t>(kFrames));
  EXPECT_GE(outcome.waits, 1u);
  EXPECT_GT(outcome.wait_s, 0.1);
  EXPECT_EQ(outcome.deepest_queue, 1u);
  // Delivered, not yet counted fused: at most the queued frame and the one being fused.
  EXPECT_LE(furthest_ahead.load(), 2);
  double waited = 0.0;
  for (const FrameTiming& t : outcome.timings) waited += t.waited_s;
  EXPECT_NEAR(waited, outcome.wait_s, 1e-9);
}

TEST(FramePipeline, ASourceErrorFusesWhatCameBeforeAndIsRethrown) {
  ScanSession session(knob_calibration(), nullptr, options());
  const FrameSource source = [](const FrameDelivery& deliver) {
    for (int k = 0; k < 3; ++k) ASSERT_TRUE(deliver(ScanFrame(knob_frames()[static_cast<std::size_t>(k)])));
    throw_error(ErrorCode::kTimeout, "camera gige://10.0.0.2: no image in 2000 ms");
  };
  try {
    run_pipeline(session, source, PipelineOptions{});
    ADD_FAILURE() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kTimeout);
    EXPECT_NE(std::string(error.what()).find("no image in 2000 ms"), std::string::npos) << error.what();
  }
  EXPECT_EQ(session.fused_count(), 3u);  // the frames captured before the fault are in the model
}

TEST(FramePipeline, ASourceCancelIsAnInterruptionAfterItsFrames) {
  ScanSession session(knob_calibration(), nullptr, options());
  const FrameSource source = [](const FrameDelivery& deliver) {
    for (int k = 0; k < 2; ++k) ASSERT_TRUE(deliver(ScanFrame(knob_frames()[static_cast<std::size_t>(k)])));
    throw_error(ErrorCode::kCancelled, "capture cancelled after 2 of 36");
  };
  const PipelineOutcome outcome = run_pipeline(session, source, PipelineOptions{});
  EXPECT_TRUE(outcome.interrupted);
  EXPECT_NE(outcome.interruption.find("cancelled after 2 of 36"), std::string::npos) << outcome.interruption;
  EXPECT_EQ(session.fused_count(), 2u);
}

// A cancel on the fusing side: the source is told (deliver() returns false) and joined, and
// at most the frames it had queued are left unfused.
TEST(FramePipeline, ACancelStopsTheSource) {
  ScanSession session(knob_calibration(), nullptr, options());
  CountingSource source;
  PipelineOptions pipeline;
  pipeline.queue_frames = 2;
  const PipelineOutcome outcome = run_pipeline(
      session, source.source(100), pipeline, {}, [](const ProgressUpdate& update) { return update.done < 3; }, 100);
  EXPECT_TRUE(outcome.interrupted);
  EXPECT_EQ(session.fused_count(), 3u);
  EXPECT_TRUE(source.refused.load());
  EXPECT_LE(source.delivered.load(), 3 + 2 + 1);  // fused, queued, and one handed over as it stopped
}

TEST(FramePipeline, AFaultWhileFusingStopsTheSourceAndIsRethrown) {
  ScanSession session(knob_calibration(), nullptr, options());
  CountingSource source;
  EXPECT_THROW(run_pipeline(session, source.source(100), PipelineOptions{},
                            [](const FrameReport& report) {
                              if (report.index == 1) throw std::runtime_error("out of disk");
                            }),
               std::runtime_error);
  EXPECT_EQ(session.fused_count(), 2u);
  EXPECT_TRUE(source.refused.load());
}

TEST(FramePipeline, BadOptionsAreRefusedBeforeTheSourceStarts) {
  ScanSession session(knob_calibration(), nullptr, options());
  bool started = false;
  PipelineOptions pipeline;
  pipeline.queue_frames = 0;
  EXPECT_EQ(test::code_of([&] { run_pipeline(session, [&](const FrameDelivery&) { started = true; }, pipeline); }),
            ErrorCode::kInvalidArgument);
  EXPECT_FALSE(started);
}

}  // namespace
}  // namespace sls::session
