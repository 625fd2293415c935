#include "sdk/core/device_memory.h"

#include <cstring>

#include "sdk/core/device.h"
#include "sdk/core/error.h"

#if defined(SLS_HAVE_CUDA)
#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/cuda/cuda_stream.h"
#endif

namespace sls {

void* allocate_device(std::size_t bytes) {
  if (bytes == 0) return nullptr;
#if defined(SLS_HAVE_CUDA)
  void* block = nullptr;
  const cudaError_t status = cudaMalloc(&block, bytes);
  if (status != cudaSuccess) {
    (void)cudaGetLastError();
    std::size_t free_bytes = 0, total_bytes = 0;
    (void)cudaMemGetInfo(&free_bytes, &total_bytes);
    throw_error(status == cudaErrorMemoryAllocation ? ErrorCode::kOutOfMemory : ErrorCode::kDevice,
                "cannot allocate {:.1f} MiB on the GPU ({:.1f} MiB free of {:.1f} MiB): {}",
                static_cast<double>(bytes) / 1048576.0, static_cast<double>(free_bytes) / 1048576.0,
                static_cast<double>(total_bytes) / 1048576.0, cudaGetErrorString(status));
  }
  note_gpu_allocation(static_cast<std::ptrdiff_t>(bytes));
  return block;
#else
  throw_error(ErrorCode::kUnsupported, "cannot allocate {} bytes on a GPU: this build has no CUDA support", bytes);
#endif
}

void release_device(void* block, std::size_t bytes) noexcept {
  if (block == nullptr) return;
#if defined(SLS_HAVE_CUDA)
  (void)cudaFree(block);
  note_gpu_allocation(-static_cast<std::ptrdiff_t>(bytes));
#else
  (void)bytes;
#endif
}

void zero_device(void* block, std::size_t bytes, const GpuStream& stream) {
  if (bytes == 0) return;
#if defined(SLS_HAVE_CUDA)
  SLS_CUDA_CHECK(cudaMemsetAsync(block, 0, bytes, cuda_stream(stream)));
  if (!stream.valid()) SLS_CUDA_CHECK(cudaStreamSynchronize(nullptr));
#else
  (void)block, (void)stream;
  throw_error(ErrorCode::kUnsupported, "GPU memory in a build without CUDA");
#endif
}

void copy_memory(void* to, const void* from, std::size_t bytes, bool device_involved, const GpuStream& stream) {
  if (bytes == 0) return;
  if (!device_involved) {
    std::memcpy(to, from, bytes);
    return;
  }
#if defined(SLS_HAVE_CUDA)
  SLS_CUDA_CHECK(cudaMemcpyAsync(to, from, bytes, cudaMemcpyDefault, cuda_stream(stream)));
  if (!stream.valid()) SLS_CUDA_CHECK(cudaStreamSynchronize(nullptr));
#else
  (void)stream;
  throw_error(ErrorCode::kUnsupported, "GPU memory in a build without CUDA");
#endif
}

void copy_memory_2d(void* to, std::size_t to_pitch, const void* from, std::size_t from_pitch, std::size_t width_bytes,
                    std::size_t rows, bool device_involved, const GpuStream& stream) {
  if (width_bytes == 0 || rows == 0) return;
  if (!device_involved) {
    for (std::size_t row = 0; row < rows; ++row) {
      std::memcpy(static_cast<unsigned char*>(to) + row * to_pitch,
                  static_cast<const unsigned char*>(from) + row * from_pitch, width_bytes);
    }
    return;
  }
#if defined(SLS_HAVE_CUDA)
  SLS_CUDA_CHECK(cudaMemcpy2DAsync(to, to_pitch, from, from_pitch, width_bytes, rows, cudaMemcpyDefault,
                                   cuda_stream(stream)));
  if (!stream.valid()) SLS_CUDA_CHECK(cudaStreamSynchronize(nullptr));
#else
  (void)to_pitch, (void)from_pitch, (void)stream;
  throw_error(ErrorCode::kUnsupported, "GPU memory in a build without CUDA");
#endif
}

}  // namespace sls
