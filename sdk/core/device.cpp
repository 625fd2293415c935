#include "sdk/core/device.h"

#include <cstdlib>

#include "sdk/core/error.h"

#if defined(SLS_HAVE_CUDA)
#include "sdk/core/cuda/cuda_check.h"
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

}  // namespace sls
