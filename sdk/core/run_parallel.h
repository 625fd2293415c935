// Runs a few coarse, CPU-bound jobs side by side on threads of their own: the PNGs of a
// frame (tens of 24 MB images encoded or decoded), a calibration view's images. Unlike
// parallel_for (OpenMP's team, or a GPU kernel, for uniform per-element loops), each job may
// throw: the first exception is rethrown once every thread has joined.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace sls {

// job(0 .. count - 1) on up to `threads` threads (0: one per hardware thread), this one
// among them.
template <typename Job>
void run_parallel(std::size_t count, int threads, const Job& job) {
  std::size_t workers = threads > 0 ? static_cast<std::size_t>(threads) : std::thread::hardware_concurrency();
  workers = std::max<std::size_t>(1, std::min(workers, count));
  if (workers <= 1) {
    for (std::size_t k = 0; k < count; ++k) job(k);
    return;
  }
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr first_error;
  std::mutex error_mutex;
  const auto work = [&] {
    for (std::size_t k = next++; k < count && !failed; k = next++) {
      try {
        job(k);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (!first_error) first_error = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(workers - 1);
  try {
    for (std::size_t t = 1; t < workers; ++t) pool.emplace_back(work);
  } catch (...) {
    // Could not start more threads: the ones running and this one finish the work.
  }
  work();
  for (std::thread& thread : pool) thread.join();
  if (first_error) std::rethrow_exception(first_error);
}

}  // namespace sls
