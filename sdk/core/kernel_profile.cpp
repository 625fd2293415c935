#include "sdk/core/kernel_profile.h"

#include <algorithm>
#include <atomic>
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

// Records and spare events: events are made once and reused (making one per launch costs
// microseconds of driver time on the frame loop's thread).
struct Profile {
  std::mutex mutex;
  std::vector<Record> records;
  std::vector<cudaEvent_t> spare;
  unsigned long generation = 0;  // counts the resets, so a timer outliving one records nothing

  cudaEvent_t event() {
    if (!spare.empty()) {
      const cudaEvent_t e = spare.back();
      spare.pop_back();
      return e;
    }
    cudaEvent_t e = nullptr;
    SLS_CUDA_CHECK(cudaEventCreate(&e));
    return e;
  }
  void recycle_records() {
    for (const Record& r : records) {
      spare.push_back(r.start);
      spare.push_back(r.stop);
    }
    records.clear();
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
    p.recycle_records();
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
  std::map<std::string, KernelFigures> by_name;
  for (const Record& r : p.records) {
    if (!r.stopped) continue;
    SLS_CUDA_CHECK(cudaEventSynchronize(r.stop));
    float ms = 0.0f;
    SLS_CUDA_CHECK(cudaEventElapsedTime(&ms, r.start, r.stop));
    KernelFigures& f = by_name[r.name];
    f.name = r.name;
    f.launches += 1;
    f.gpu_ms += static_cast<double>(ms);
    f.bytes += r.bytes;
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
  record_ = static_cast<long>(p.records.size());
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
  Record& r = p.records[static_cast<std::size_t>(record_)];
  r.stopped = cudaEventRecord(r.stop, static_cast<cudaStream_t>(stream_)) == cudaSuccess;
#endif
}

}  // namespace sls
