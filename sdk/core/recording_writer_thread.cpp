#include "sdk/core/recording_writer_thread.h"

#include <algorithm>
#include <chrono>
#include <new>
#include <utility>

#include "sdk/core/error.h"
#include "sdk/core/log.h"

namespace sls {
namespace {

double seconds_between(SteadyClock::time_point from, SteadyClock::time_point to) {
  return std::chrono::duration<double>(to - from).count();
}

}  // namespace

double RecordingWriteStatistics::write_s_total() const {
  double total = 0.0;
  for (const Frame& frame : frames) total += frame.write_s;
  return total;
}

double RecordingWriteStatistics::write_s_median() const {
  if (frames.empty()) return 0.0;
  std::vector<double> values;
  values.reserve(frames.size());
  for (const Frame& frame : frames) values.push_back(frame.write_s);
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

RecordingWriterThread::RecordingWriterThread(std::string folder, std::size_t queue_frames)
    : folder_(std::move(folder)), capacity_(queue_frames) {
  statistics_.queue_frames = queue_frames;
}

RecordingWriterThread::~RecordingWriterThread() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  ready_.notify_one();
  // The thread writes what is queued before it returns (run()): a capture that unwinds keeps
  // every frame it captured.
  if (thread_.joinable()) thread_.join();
  std::lock_guard<std::mutex> lock(mutex_);
  log_unthrown_error();
}

void RecordingWriterThread::log_unthrown_error() {
  if (!error_ || error_thrown_) return;
  error_thrown_ = true;
  try {
    std::rethrow_exception(error_);
  } catch (const std::exception& error) {
    logger().error("{}", error.what());
  } catch (...) {
    logger().error("writing to the recording {} failed", folder_);
  }
}

void RecordingWriterThread::drain() noexcept {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [this] { return error_ || (queue_.empty() && !writing_); });
  log_unthrown_error();
}

std::exception_ptr RecordingWriterThread::write_one(Job& job) {
  const SteadyClock::time_point start = SteadyClock::now();
  std::exception_ptr failure;
  try {
    job.write();
  } catch (const Error& error) {
    failure = std::make_exception_ptr(Error(
        error.code(), fmt::format("writing frame {} to the recording {}: {}", job.frame, folder_, error.what())));
  } catch (const std::bad_alloc&) {
    failure = std::make_exception_ptr(Error(
        ErrorCode::kOutOfMemory, fmt::format("writing frame {} to the recording {}: out of memory", job.frame, folder_)));
  } catch (...) {
    failure = std::current_exception();  // not the SDK's (a caller's hook): passed on unchanged
  }
  const SteadyClock::time_point end = SteadyClock::now();
  std::lock_guard<std::mutex> lock(mutex_);
  if (!failure) statistics_.frames.push_back({job.frame, end, seconds_between(start, end)});
  return failure;
}

void RecordingWriterThread::throw_if_failed() {
  if (!error_) return;
  error_thrown_ = true;
  std::rethrow_exception(error_);
}

void RecordingWriterThread::push(int frame, Write write) {
  Job job{frame, std::move(write)};
  if (capacity_ == 0) {  // synchronous: the capture's thread writes
    {
      std::lock_guard<std::mutex> lock(mutex_);
      throw_if_failed();
    }
    std::exception_ptr failure = write_one(job);
    if (!failure) return;
    std::lock_guard<std::mutex> lock(mutex_);
    error_ = failure;
    throw_if_failed();
  }
  std::unique_lock<std::mutex> lock(mutex_);
  throw_if_failed();
  const SteadyClock::time_point asked = SteadyClock::now();
  bool waited = false;
  while (!error_ && queue_.size() >= capacity_) {
    waited = true;
    room_.wait(lock);
  }
  throw_if_failed();
  if (waited) {
    ++statistics_.waits;
    statistics_.wait_s += seconds_between(asked, SteadyClock::now());
  }
  queue_.push_back(std::move(job));
  statistics_.deepest_queue = std::max(statistics_.deepest_queue, queue_.size());
  if (!thread_.joinable()) thread_ = std::thread([this] { run(); });
  ready_.notify_one();
}

void RecordingWriterThread::finish() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [this] { return error_ || (queue_.empty() && !writing_); });
  throw_if_failed();
}

RecordingWriteStatistics RecordingWriterThread::statistics() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return statistics_;
}

void RecordingWriterThread::run() {
  for (;;) {
    Job job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      ready_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, everything written
      job = std::move(queue_.front());
      queue_.pop_front();
      writing_ = true;
    }
    room_.notify_one();
    std::exception_ptr failure = write_one(job);
    job.write = nullptr;  // the frame's images released before the next write
    std::lock_guard<std::mutex> lock(mutex_);
    writing_ = false;
    if (failure) {
      // Nothing after a failed frame is written: the recording must list frames in order.
      error_ = failure;
      queue_.clear();
      room_.notify_all();
      idle_.notify_all();
      return;
    }
    if (queue_.empty()) idle_.notify_all();
  }
}

}  // namespace sls
