#include "sdk/core/kernel_profile.h"

#include <algorithm>
#include <atomic>
#include <deque>
#include <map>
#include <mutex>

#include "sdk/core/error.h"

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>

#include "sdk/core/cuda/cuda_check.h"
#endif

namespace sls {
namespace {

#if defined(SLS_HAVE_CUDA)
struct Record {
  const char* name;
  double bytes;
  cudaEvent_t start;
  cudaEvent_t stop;
  bool stopped = false;  // the stop event recorded (a launcher that threw records none)
};

// A record's figures (its stop event complete) added to its kernel's.
void add_figures(const Record& r, std::map<std::string, KernelFigures>* by_name) {
  float ms = 0.0f;
  SLS_CUDA_CHECK(cudaEventElapsedTime(&ms, r.start, r.stop));
  KernelFigures& f = (*by_name)[r.name];
  f.name = r.name;
  f.launches += 1;
  f.gpu_ms += static_cast<double>(ms);
  f.bytes += r.bytes;
}

// Records and spare events: events are made once and reused (making one per launch costs
// microseconds of driver time on the frame loop's thread). Records whose stop event the GPU has
// passed are summed into `done` as new timers start, so that a scan's thousands of launches
// reuse a few hundred events instead of making two per launch.
struct Profile {
  std::mutex mutex;
  std::deque<Record> records;  // pending, oldest first
  long first_record = 0;       // the sequence number of records.front()
  std::map<std::string, KernelFigures> done;  // summed from the records already completed
  std::vector<cudaEvent_t> spare;
  unsigned long generation = 0;  // counts the resets, so a timer outliving one records nothing

  cudaEvent_t event() {
    if (spare.empty()) harvest();
    if (!spare.empty()) {
      const cudaEvent_t e = spare.back();
      spare.pop_back();
      return e;
    }
    cudaEvent_t e = nullptr;
    SLS_CUDA_CHECK(cudaEventCreate(&e));
    return e;
  }
  void retire_front() {
    spare.push_back(records.front().start);
    spare.push_back(records.front().stop);
    records.pop_front();
    ++first_record;
  }
  // The oldest records, in order, while their kernels have finished (a timer still open, or
  // work the GPU has not reached, stops it: those stay pending).
  void harvest() {
    while (!records.empty() && records.front().stopped) {
      const cudaError_t status = cudaEventQuery(records.front().stop);
      if (status == cudaErrorNotReady) return;
      SLS_CUDA_CHECK(status);
      add_figures(records.front(), &done);
      retire_front();
    }
  }
  // Every record's events back to the spares, the figures discarded.
  void reset() {
    while (!records.empty()) retire_front();
    done.clear();
  }
};

Profile& profile() {
  static Profile* p = new Profile();  // never destroyed: timers may run during static destruction
  return *p;
}
#endif

std::atomic<bool> profiling{false};

}  // namespace

void set_kernel_profiling(bool on) {
#if defined(SLS_HAVE_CUDA)
  Profile& p = profile();
  const std::lock_guard<std::mutex> lock(p.mutex);
  if (on) {
    for (const Record& r : p.records) {
      if (r.stopped) (void)cudaEventSynchronize(r.stop);
    }
    p.reset();
    ++p.generation;
  }
#endif
  profiling.store(on);
}

bool kernel_profiling() { return profiling.load(); }

std::vector<KernelFigures> kernel_profile() {
  std::vector<KernelFigures> out;
#if defined(SLS_HAVE_CUDA)
  Profile& p = profile();
  const std::lock_guard<std::mutex> lock(p.mutex);
  std::map<std::string, KernelFigures> by_name = p.done;
  for (const Record& r : p.records) {
    if (!r.stopped) continue;
    SLS_CUDA_CHECK(cudaEventSynchronize(r.stop));
    add_figures(r, &by_name);
  }
  for (auto& [name, figures] : by_name) out.push_back(figures);
  std::sort(out.begin(), out.end(), [](const KernelFigures& a, const KernelFigures& b) { return a.gpu_ms > b.gpu_ms; });
#endif
  return out;
}

KernelTimer::KernelTimer(const char* name, double bytes, void* stream) : stream_(stream) {
  if (!profiling.load(std::memory_order_relaxed)) return;
#if defined(SLS_HAVE_CUDA)
  Profile& p = profile();
  const std::lock_guard<std::mutex> lock(p.mutex);
  const Record r{name, bytes, p.event(), p.event()};
  SLS_CUDA_CHECK(cudaEventRecord(r.start, static_cast<cudaStream_t>(stream)));
  record_ = p.first_record + static_cast<long>(p.records.size());
  generation_ = p.generation;
  p.records.push_back(r);
#else
  (void)name, (void)bytes;
#endif
}

KernelTimer::~KernelTimer() {
  if (record_ < 0) return;
#if defined(SLS_HAVE_CUDA)
  Profile& p = profile();
  const std::lock_guard<std::mutex> lock(p.mutex);
  // Profiling turned on again meanwhile discarded the record: nothing to stop.
  if (generation_ != p.generation) return;
  // Pending still: harvest() stops at the first record whose timer is open.
  Record& r = p.records[static_cast<std::size_t>(record_ - p.first_record)];
  r.stopped = cudaEventRecord(r.stop, static_cast<cudaStream_t>(stream_)) == cudaSuccess;
#endif
}

}  // namespace sls
