#include "sdk/core/device.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <vector>

#include "sdk/core/error.h"

#if defined(SLS_HAVE_CUDA)
#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/cuda/device_buffer.h"
#endif

namespace sls {

std::string Device::to_string() const {
  return kind == Kind::kCpu ? std::string("cpu") : "cuda:" + std::to_string(id);
}

Device default_device() { return cuda_device_count() > 0 ? Device::cuda(0) : Device::cpu(); }

Device parse_device(const std::string& text) {
  if (text == "cpu") return Device::cpu();
  if (text == "cuda") return Device::cuda(0);
  if (text.rfind("cuda:", 0) == 0 && text.size() > 5) {
    char* end = nullptr;
    const long id = std::strtol(text.c_str() + 5, &end, 10);
    if (end != nullptr && *end == '\0' && id >= 0 && id < 1024) return Device::cuda(static_cast<int>(id));
  }
  throw_error(ErrorCode::kInvalidArgument, "unknown device '{}' (expected cpu, cuda or cuda:N)", text);
}

bool cuda_compiled() {
#if defined(SLS_HAVE_CUDA)
  return true;
#else
  return false;
#endif
}

int cuda_device_count() {
#if defined(SLS_HAVE_CUDA)
  int count = 0;
  // No driver or no GPU is a normal situation (CI), not an error: report zero devices.
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    (void)cudaGetLastError();
    return 0;
  }
  return count;
#else
  return 0;
#endif
}

std::string cuda_device_name(int id) {
#if defined(SLS_HAVE_CUDA)
  if (id < 0 || id >= cuda_device_count()) {
    throw_error(ErrorCode::kDevice, "CUDA device {} does not exist ({} present)", id, cuda_device_count());
  }
  cudaDeviceProp properties{};
  SLS_CUDA_CHECK(cudaGetDeviceProperties(&properties, id));
  return properties.name;
#else
  throw_error(ErrorCode::kUnsupported, "CUDA device {} requested, but this build has no CUDA support", id);
#endif
}

void require_device(const Device& device) {
  if (!device.is_cuda()) return;
  if (!cuda_compiled()) {
    throw_error(ErrorCode::kUnsupported,
                "device {} requested, but this build has no CUDA support (reconfigure with nvcc present)",
                device.to_string());
  }
#if defined(SLS_HAVE_CUDA)
  const int count = cuda_device_count();
  if (device.id >= count) {
    throw_error(ErrorCode::kDevice, "device {} requested, but {} CUDA device(s) are present",
                device.to_string(), count);
  }
  SLS_CUDA_CHECK(cudaSetDevice(device.id));
#endif
}

namespace {

void require_gpu(const Device& device, const char* what) {
  if (!device.is_cuda()) throw_error(ErrorCode::kInvalidArgument, "{}: {} is not a GPU", what, device.to_string());
  require_device(device);
}

}  // namespace

namespace {
std::atomic<std::size_t> gpu_in_use_bytes{0};
std::atomic<std::size_t> gpu_peak_bytes{0};
}  // namespace

GpuAllocations gpu_allocations() { return {gpu_in_use_bytes.load(), gpu_peak_bytes.load()}; }

void reset_gpu_allocation_peak() { gpu_peak_bytes.store(gpu_in_use_bytes.load()); }

void note_gpu_allocation(std::ptrdiff_t bytes) {
  if (bytes < 0) {
    gpu_in_use_bytes.fetch_sub(static_cast<std::size_t>(-bytes));
    return;
  }
  const std::size_t now = gpu_in_use_bytes.fetch_add(static_cast<std::size_t>(bytes)) + static_cast<std::size_t>(bytes);
  std::size_t peak = gpu_peak_bytes.load();
  while (now > peak && !gpu_peak_bytes.compare_exchange_weak(peak, now)) {
  }
}

GpuMemory gpu_memory(const Device& device) {
  require_gpu(device, "GPU memory");
  GpuMemory memory;
#if defined(SLS_HAVE_CUDA)
  std::size_t free_bytes = 0;
  SLS_CUDA_CHECK(cudaMemGetInfo(&free_bytes, &memory.total_bytes));
  memory.used_bytes = memory.total_bytes - free_bytes;
#endif
  return memory;
}

double copy_bandwidth_gbps(const Device& device, std::size_t bytes) {
  require_gpu(device, "copy bandwidth");
  if (bytes == 0) throw_error(ErrorCode::kInvalidArgument, "copy bandwidth: a copy of 0 bytes");
#if defined(SLS_HAVE_CUDA)
  DeviceBuffer<unsigned char> from(bytes), to(bytes);
  SLS_CUDA_CHECK(cudaMemset(from.data(), 0x5a, bytes));  // not zeros: no path may treat them specially
  cudaEvent_t start = nullptr, stop = nullptr;
  SLS_CUDA_CHECK(cudaEventCreate(&start));
  SLS_CUDA_CHECK(cudaEventCreate(&stop));
  std::vector<float> ms;
  for (int i = 0; i < 6; ++i) {  // the first is the warm-up
    SLS_CUDA_CHECK(cudaEventRecord(start, nullptr));
    SLS_CUDA_CHECK(cudaMemcpyAsync(to.data(), from.data(), bytes, cudaMemcpyDeviceToDevice, nullptr));
    SLS_CUDA_CHECK(cudaEventRecord(stop, nullptr));
    SLS_CUDA_CHECK(cudaEventSynchronize(stop));
    float elapsed = 0.0f;
    SLS_CUDA_CHECK(cudaEventElapsedTime(&elapsed, start, stop));
    if (i > 0) ms.push_back(elapsed);
  }
  (void)cudaEventDestroy(start);
  (void)cudaEventDestroy(stop);
  std::nth_element(ms.begin(), ms.begin() + 2, ms.end());
  return 2.0 * static_cast<double>(bytes) / (static_cast<double>(ms[2]) * 1e-3) / 1e9;
#else
  return 0.0;
#endif
}

}  // namespace sls
