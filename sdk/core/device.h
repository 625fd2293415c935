// Where an algorithm runs: Device{cpu} or Device{cuda, id}, chosen at run time
// (DESIGN.md section 6). Asking for CUDA in a build without it, or on a machine without a
// GPU, is a clear sls::Error (unsupported / device), never a silent fallback.
#pragma once

#include <cstddef>
#include <string>

namespace sls {

struct Device {
  enum class Kind { kCpu, kCuda };
  Kind kind = Kind::kCpu;
  int id = 0;  // CUDA device ordinal

  static Device cpu() { return {Kind::kCpu, 0}; }
  static Device cuda(int id = 0) { return {Kind::kCuda, id}; }
  bool is_cuda() const { return kind == Kind::kCuda; }
  bool operator==(const Device& other) const { return kind == other.kind && id == other.id; }
  std::string to_string() const;  // "cpu", "cuda:0"
};

// The first CUDA GPU when one is usable, else the CPU: the default wherever the caller
// does not choose.
Device default_device();

// Parses "cpu", "cuda" or "cuda:N"; throws sls::Error (invalid argument) otherwise.
Device parse_device(const std::string& text);

// True when this build has the CUDA backends compiled in.
bool cuda_compiled();

// Number of usable CUDA devices: 0 in a build without CUDA or with no GPU/driver present.
int cuda_device_count();

// Name of a CUDA device, e.g. "NVIDIA H100 80GB HBM3"; throws when it does not exist.
std::string cuda_device_name(int id);

// Throws sls::Error unless `device` can run work now: unsupported when CUDA was not built,
// device error when the ordinal has no GPU behind it. Selects the device for this thread.
void require_device(const Device& device);

// What slscan's own allocations hold on the GPUs of this process (DeviceBuffer, the
// integrator's sort buffers), in bytes: now, and the most at once since the process started or
// reset_gpu_allocation_peak(). The CUDA context, the driver's and CUB's temporary storage, and
// other processes are not in it (gpu_memory() sees them). Thread-safe.
struct GpuAllocations {
  std::size_t in_use_bytes = 0;
  std::size_t peak_bytes = 0;
};
GpuAllocations gpu_allocations();
void reset_gpu_allocation_peak();
// The bookkeeping behind it: an allocation (bytes > 0) or a release (bytes < 0).
void note_gpu_allocation(std::ptrdiff_t bytes);

// A GPU's memory (cudaMemGetInfo: every process's use), in bytes.
struct GpuMemory {
  std::size_t used_bytes = 0;
  std::size_t total_bytes = 0;
};
// Throws as require_device (which it calls: the device becomes this thread's), and
// ErrorCode::kInvalidArgument for the CPU.
GpuMemory gpu_memory(const Device& device);

// The bandwidth of a device-to-device copy on a GPU, in GB/s of bytes read plus written: a copy
// of `bytes`, warmed up, the median of five timed with CUDA events. The ceiling a memory-bound
// kernel's bandwidth is judged against (`sls bench`). Throws as gpu_memory, and
// ErrorCode::kOutOfMemory when the two buffers do not fit.
double copy_bandwidth_gbps(const Device& device, std::size_t bytes = std::size_t{1} << 30);

}  // namespace sls
