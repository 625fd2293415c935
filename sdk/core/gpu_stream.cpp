#include "sdk/core/gpu_stream.h"

#include "sdk/core/error.h"

#if defined(SLS_HAVE_CUDA)
#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/cuda/cuda_stream.h"
#endif

namespace sls {

GpuStream GpuStream::create(const Device& device) {
  GpuStream stream;
  if (!device.is_cuda()) return stream;
  require_device(device);
#if defined(SLS_HAVE_CUDA)
  cudaStream_t handle = nullptr;
  SLS_CUDA_CHECK(cudaStreamCreateWithFlags(&handle, cudaStreamNonBlocking));
  // The deleter waits for the stream's work before destroying it, so memory a stage frees after
  // its last use is not still being read.
  stream.stream_ = std::shared_ptr<void>(handle, [](void* native) {
    const auto cuda = static_cast<cudaStream_t>(native);
    (void)cudaStreamSynchronize(cuda);
    (void)cudaStreamDestroy(cuda);
  });
#endif
  return stream;
}

void GpuStream::synchronize() const {
  if (!valid()) return;
#if defined(SLS_HAVE_CUDA)
  SLS_CUDA_CHECK(cudaStreamSynchronize(cuda_stream(*this)));
#endif
}

}  // namespace sls
