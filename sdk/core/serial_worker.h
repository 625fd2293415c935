// One long-lived thread that runs jobs one after another, in the order they were submitted: for
// work beside a caller's loop (a moving volume's ships, a frame pipeline's next upload). A thread
// per job (std::async) also made, per job, an OpenMP team for the job's parallel loops and glibc
// malloc arenas for their threads, whose freed memory stayed mapped: a process that scanned again
// and again on a GPU grew by ~15 MiB a scan (docs/reliability.md, "long runs").
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <thread>
#include <type_traits>
#include <utility>

namespace sls {

class SerialWorker {
 public:
  SerialWorker() = default;
  SerialWorker(const SerialWorker&) = delete;
  SerialWorker& operator=(const SerialWorker&) = delete;
  // Runs the jobs still queued, then joins the thread.
  ~SerialWorker() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_one();
    if (thread_.joinable()) thread_.join();
  }

  // Queues `job`; its result (or what it threw) comes through the future. The thread starts
  // with the first job.
  template <typename Job>
  std::future<std::invoke_result_t<Job>> submit(Job job) {
    using Result = std::invoke_result_t<Job>;
    auto task = std::make_shared<std::packaged_task<Result()>>(std::move(job));
    std::future<Result> result = task->get_future();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      jobs_.emplace_back([task] { (*task)(); });
      if (!thread_.joinable()) thread_ = std::thread([this] { run(); });
    }
    wake_.notify_one();
    return result;
  }

 private:
  void run() {
    for (;;) {
      std::function<void()> job;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return stopping_ || !jobs_.empty(); });
        if (jobs_.empty()) return;  // stopping, nothing left
        job = std::move(jobs_.front());
        jobs_.pop_front();
      }
      job();  // a packaged task: what it throws goes to its future
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> jobs_;
  bool stopping_ = false;
  std::thread thread_;
};

// Waits for a job's future when it goes out of scope, also during unwinding (a submitted job's
// future does not, unlike std::async's): declared after what the job reads, so that it is
// released only after the job is done.
template <typename T>
class WaitOnExit {
 public:
  explicit WaitOnExit(std::future<T>& future) : future_(future) {}
  WaitOnExit(const WaitOnExit&) = delete;
  WaitOnExit& operator=(const WaitOnExit&) = delete;
  ~WaitOnExit() {
    if (future_.valid()) future_.wait();
  }

 private:
  std::future<T>& future_;
};

}  // namespace sls
