// Each hot GPU kernel's time and achieved bandwidth (issue 18: `sls bench` judges every hot
// kernel against the copy bandwidth measured in the same run). While profiling is on, a CUDA
// launcher's KernelTimer puts a CUDA event before and after its kernels on their stream, and
// adds the bytes those kernels move by the launcher's traffic model (its comment says what it
// counts: mostly each input read once and each output written once; reads that depend on the
// scene, such as a raycast's voxels along a ray, are not counted, and the integration's box of
// voxels is an estimate), so bytes / time is an effective bandwidth, comparable with the copy
// bandwidth (read + written) but not the DRAM traffic a profiler (ncu) counts.
// Off by default: nothing is recorded and a timer costs a branch.
// Events are recorded, not waited for: kernel_profile() waits for them once, at the end.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace sls {

struct KernelFigures {
  std::string name;         // the launcher's (e.g. "integrate", "raycast")
  std::size_t launches = 0;
  double gpu_ms = 0.0;      // summed GPU time between each launch's two events
  double bytes = 0.0;       // summed compulsory traffic (read + written)
  double achieved_gb_s() const { return gpu_ms > 0.0 ? bytes / (gpu_ms * 1e6) : 0.0; }
};

// Turns profiling on or off for every launcher of the process (thread-safe). Turning it on
// discards what was recorded before.
void set_kernel_profiling(bool on);
bool kernel_profiling();
// What was recorded since profiling was turned on, summed per kernel, longest GPU time first;
// waits for the outstanding events (the work they follow must have been queued).
std::vector<KernelFigures> kernel_profile();

// Times the kernels a launcher queues on `stream` (a cudaStream_t) from construction to
// destruction, when profiling is on; `bytes`: their compulsory traffic.
class KernelTimer {
 public:
  KernelTimer(const char* name, double bytes, void* stream);
  ~KernelTimer();
  KernelTimer(const KernelTimer&) = delete;
  KernelTimer& operator=(const KernelTimer&) = delete;

 private:
  long record_ = -1;  // the pending record, -1 when profiling is off
  unsigned long generation_ = 0;
  void* stream_ = nullptr;
};

}  // namespace sls
