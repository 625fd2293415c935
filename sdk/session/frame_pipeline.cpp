#include "sdk/session/frame_pipeline.h"

#include <chrono>
#include <condition_variable>
#include <algorithm>
#include <deque>
#include <exception>
#include <future>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include <fmt/format.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "sdk/core/error.h"
#include "sdk/core/serial_worker.h"
#include "sdk/core/stopwatch.h"
#include "sdk/session/hdr_frame.h"

namespace sls::session {

void PipelineOptions::validate() const {
  if (queue_frames < 1) throw_error(ErrorCode::kInvalidArgument, "pipeline: queue_frames {} (1 or more)", queue_frames);
}

namespace {

using Clock = SteadyClock;

double seconds_between(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double>(to - from).count();
}

// The queue between the source's thread and the fusing one.
class FrameQueue {
 public:
  FrameQueue(std::size_t capacity, Clock::time_point start) : capacity_(capacity), start_(start) {}

  // The source's side: waits for room; false once stopped.
  bool push(ScanFrame&& frame) {
    std::unique_lock<std::mutex> lock(mutex_);
    const Clock::time_point asked = Clock::now();
    bool waited = false;
    while (!stopped_ && queue_.size() >= capacity_) {
      waited = true;
      room_.wait(lock);
    }
    if (stopped_) return false;
    const Clock::time_point now = Clock::now();
    Entry entry{std::move(frame), seconds_between(start_, now), waited ? seconds_between(asked, now) : 0.0};
    if (waited) {
      ++waits_;
      wait_s_ += entry.waited_s;
    }
    ++delivered_;
    queue_.push_back(std::move(entry));
    deepest_ = std::max(deepest_, queue_.size());
    ready_.notify_one();
    return true;
  }

  // The source is done (returned or threw); its exception, if any.
  void finish(std::exception_ptr error, double source_s) {
    std::lock_guard<std::mutex> lock(mutex_);
    finished_ = true;
    error_ = std::move(error);
    source_s_ = source_s;
    ready_.notify_one();
  }

  // The fusing side asks the source to stop: deliver() returns false from now on.
  void stop() {
    std::lock_guard<std::mutex> lock(mutex_);
    stopped_ = true;
    room_.notify_all();
  }

  struct Entry {
    ScanFrame frame;
    double delivered_s = 0.0;
    double waited_s = 0.0;
  };
  // The frame after the one last popped, if the source has delivered it (else null). It stays
  // in place until the next pop(): only this thread pops, and the source only appends.
  const ScanFrame* next() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return queue_.empty() ? nullptr : &queue_.front().frame;
  }

  // The next frame, waiting for one; nullopt once the source is done and the queue empty.
  std::optional<Entry> pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    ready_.wait(lock, [this] { return !queue_.empty() || finished_; });
    if (queue_.empty()) return std::nullopt;
    Entry entry = std::move(queue_.front());
    queue_.pop_front();
    room_.notify_one();
    return entry;
  }

  void fill(PipelineOutcome* outcome) const {
    std::lock_guard<std::mutex> lock(mutex_);
    outcome->delivered = delivered_;
    outcome->waits = waits_;
    outcome->wait_s = wait_s_;
    outcome->deepest_queue = deepest_;
    outcome->source_s = source_s_;
  }
  std::exception_ptr error() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return error_;
  }

 private:
  const std::size_t capacity_;
  const Clock::time_point start_;
  mutable std::mutex mutex_;
  std::condition_variable room_, ready_;
  std::deque<Entry> queue_;
  bool stopped_ = false, finished_ = false;
  std::exception_ptr error_;
  std::size_t delivered_ = 0, waits_ = 0, deepest_ = 0;
  double wait_s_ = 0.0, source_s_ = 0.0;
};

// Whether an exception is sls::Error(kCancelled), and its message.
bool is_cancel(const std::exception_ptr& error, std::string* message) {
  if (!error) return false;
  try {
    std::rethrow_exception(error);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::kCancelled) return false;
    *message = e.what();
    return true;
  } catch (...) {
    return false;
  }
}

}  // namespace

PipelineOutcome run_pipeline(ScanSession& session, const FrameSource& source, const PipelineOptions& options,
                             const std::function<void(const FrameReport&)>& on_frame,
                             const ProgressCallback& progress, std::size_t expected_frames) {
  return run_pipeline([&session]() -> ScanSession& { return session; }, source, options, on_frame, progress,
                      expected_frames);
}

PipelineOutcome run_pipeline(const SessionProvider& session_provider, const FrameSource& source,
                             const PipelineOptions& options, const std::function<void(const FrameReport&)>& on_frame,
                             const ProgressCallback& progress, std::size_t expected_frames) {
  options.validate();
  const Clock::time_point start = Clock::now();
  FrameQueue queue(options.queue_frames, start);
  std::thread source_thread([&source, &queue, start] {
    std::exception_ptr error;
    try {
      source([&queue](ScanFrame&& frame) { return queue.push(std::move(frame)); });
    } catch (...) {
      error = std::current_exception();
    }
    queue.finish(error, seconds_between(start, Clock::now()));
  });
  // The frames were allocated on the source's thread, so in its malloc arena (glibc's), which
  // keeps what they freed: handed back to the system once the scan's frames are done, so that
  // scans in one process stay flat (tests/unit/session/test_scan_soak.cpp).
  struct TrimOnExit {
    ~TrimOnExit() {
#if defined(__GLIBC__)
      malloc_trim(0);
#endif
    }
  } trim_on_exit;
  // The source is stopped and joined on every way out of here.
  const auto stop_source = [&queue, &source_thread] {
    queue.stop();
    if (source_thread.joinable()) source_thread.join();
  };

  PipelineOutcome outcome;
  outcome.started = start;
  // The uploads ahead, on one thread for the process (a thread per frame, or per scan, also made
  // an OpenMP team and malloc arenas each time; see ship_worker() in fusion/moving_volume.cpp).
  // Pipelines of concurrent scans take turns.
  static SerialWorker uploader;
  try {
    std::size_t fused = 0;
    ScanSession* session = nullptr;
    for (;;) {
      // Before taking the next frame: a cancel leaves it queued, so the source is told while
      // it waits to hand over the one after.
      report_progress(progress, {"scan", fused, expected_frames, ""});
      std::optional<FrameQueue::Entry> entry = queue.pop();
      if (!entry) break;
      if (session == nullptr) session = &session_provider();
      // The frame after this one, uploaded to the GPU while this one is fused (a CUDA session):
      // joined before the next pop, which may move it, also when add_frame throws.
      std::future<bool> upload_ahead;
      const WaitOnExit<bool> wait_upload(upload_ahead);  // before `next` moves, also when add_frame throws
      const ScanFrame* next = session->uploads_ahead() ? queue.next() : nullptr;
      if (next != nullptr && !next->pattern_images().empty()) {
        upload_ahead = uploader.submit([session, next] { return session->prefetch(*next); });
      }
      const FrameReport report = session->add_frame(entry->frame);
      if (upload_ahead.valid()) upload_ahead.get();
      outcome.timings.push_back(
          {entry->frame.index, entry->delivered_s, seconds_between(start, Clock::now()), entry->waited_s});
      ++fused;
      if (on_frame) on_frame(report);
    }
    std::string cancelled;
    if (is_cancel(queue.error(), &cancelled)) {
      outcome.interrupted = true;
      outcome.interruption = cancelled;
    } else if (queue.error()) {
      stop_source();
      std::rethrow_exception(queue.error());
    }
  } catch (const Error& error) {
    stop_source();
    if (error.code() != ErrorCode::kCancelled) throw;
    outcome.interrupted = true;
    outcome.interruption = error.what();
  } catch (...) {
    stop_source();
    throw;
  }
  stop_source();
  queue.fill(&outcome);
  return outcome;
}

ScanFrame read_recording_frame(const RecordingReader& recording, std::size_t position,
                               const std::vector<StampedPose>* known_poses, MemoryType image_memory) {
  const FrameInfo& info = recording.frame(position);
  ScanFrame frame;
  frame.index = info.index;
  frame.timestamp_ns = info.timestamp_ns;
  frame.turntable_angle_deg = info.turntable_angle_deg;
  if (known_poses != nullptr) frame.known_T_world_camera = known_poses->at(position).T_world_camera;
  const SteadyClock::time_point start = SteadyClock::now();
  try {
    if (!info.complete) {
      frame.problem = "incomplete pattern stack" + (info.note.empty() ? std::string() : ": " + info.note);
    } else if (recording.info().images_per_frame > 0) {
      frame.images = recording.load_images(position, image_memory);
      // HDR: the exposures' stacks fused into one; the decode options are scan_setup's.
      fuse_hdr_frame(recording.info(), hdr_decode_options(recording.info()), &frame);
    } else {
      frame.depth_m = recording.load_depth_m(position);
      if (!frame.depth_m) frame.problem = "no depth map";
    }
  } catch (const Error& error) {
    if (!is_frame_problem(error)) throw;
    frame.problem = fmt::format("cannot read: {}", error.what());
  }
  frame.read_ms = ms_since(start);
  return frame;
}

FrameSource recording_frames(const RecordingReader& recording, const std::vector<StampedPose>* known_poses,
                             MemoryType image_memory) {
  if (known_poses != nullptr && known_poses->size() != recording.frame_count()) {
    throw_error(ErrorCode::kInvalidArgument, "{} known poses for the {} frames of {}", known_poses->size(),
                recording.frame_count(), recording.folder());
  }
  return [&recording, known_poses, image_memory](const FrameDelivery& deliver) {
    for (std::size_t i = 0; i < recording.frame_count(); ++i) {
      if (!deliver(read_recording_frame(recording, i, known_poses, image_memory))) return;
    }
  };
}

FrameSource captured_frames(const std::string& folder, std::function<void(const RecordedFrame& recorded)> capture) {
  return [folder, capture = std::move(capture)](const FrameDelivery& deliver) {
    std::size_t next = 0;  // the recording's next frame the pipeline has not had
    bool stopped = false;
    // The recording's frames before `end` that were not handed over, read back.
    const auto read_back = [&](std::size_t end) {
      if (folder.empty() || next >= end || stopped) return;  // no recording: nothing to read back
      const RecordingReader recording = RecordingReader::open(folder);
      end = std::min(end, recording.frame_count());
      for (; next < end; ++next) {
        if (!deliver(read_recording_frame(recording, next))) {
          stopped = true;
          return;
        }
      }
    };
    capture([&](ScanFrame&& frame) {
      if (frame.index < 0) throw_error(ErrorCode::kInternal, "{}: a captured frame numbered {}", folder, frame.index);
      const std::size_t position = static_cast<std::size_t>(frame.index);
      read_back(position);
      if (stopped || !deliver(std::move(frame))) {
        stopped = true;
        throw_error(ErrorCode::kCancelled, "capture into {} stopped after frame {}: the scan stopped fusing",
                    folder.empty() ? std::string("no recording") : folder, position);
      }
      next = position + 1;
    });
    if (!folder.empty()) read_back(RecordingReader::open(folder).frame_count());
  };
}

ReplayOutcome run_recording(ScanSession& session, const RecordingReader& recording,
                            const std::vector<StampedPose>* known_poses,
                            const std::function<void(const FrameReport&)>& on_frame, const ProgressCallback& progress,
                            const PipelineOptions& options) {
  // Page-locked where the session uploads stacks to a GPU, so its decoder reads them without
  // staging, as it reads a camera's (capture_memory_for).
  const MemoryType image_memory = session.uploads_ahead() ? MemoryType::kPinned : MemoryType::kHost;
  return run_pipeline(session, recording_frames(recording, known_poses, image_memory), options, on_frame, progress,
                      recording.frame_count());
}

}  // namespace sls::session
