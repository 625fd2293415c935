// One loop over n elements wherever it runs (issue 18; as Open3D's core::ParallelFor): on the
// CPU across OpenMP's threads, on a CUDA GPU as a kernel of one thread per element queued on
// `stream` (asynchronous: the stream's next work, or its synchronize(), sees the results).
// The body is an SLS_LAMBDA over the per-element code of a *_shared.h header, so a stage's
// loop is written once and no backend repeats the grid, the bounds check and the launch check.
//
//   parallel_for(device, n, SLS_LAMBDA(std::size_t i) { out[i] = f(in[i]); }, stream);
//
// Pointers the body captures must live where the loop runs. A CUDA loop compiles only in CUDA
// sources (.cu): elsewhere asking for one throws sls::Error(kUnsupported) naming the loop.
// Loops whose elements cost very different amounts, which reduce or share memory between
// threads, or whose 2D/3D blocks keep a warp on one row of an image or volume, keep their own
// kernels and OpenMP schedules.
//
// Call it from a function of a .cpp or .cu file, not from an inline function of a header: the
// CPU and CUDA compilations of such a function would be two bodies under one name, and the
// linker keeps one of them.
#pragma once

#include <cstddef>

#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/host_device.h"

#if defined(__CUDACC__)
#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/cuda/cuda_stream.h"
#endif

namespace sls {

constexpr unsigned kParallelForThreads = 256;  // CUDA threads a block

#if defined(__CUDACC__)
namespace detail {
template <typename Body>
__global__ void parallel_for_kernel(std::size_t count, Body body) {
  const std::size_t i = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < count) body(i);
}
}  // namespace detail
#endif

#if defined(__CUDACC__)
// The CUDA loop on a stream a CUDA launcher was handed as such (the current device's).
template <typename Body>
void parallel_for(std::size_t count, const Body& body, cudaStream_t stream) {
  if (count == 0) return;
  const std::size_t blocks = (count + kParallelForThreads - 1) / kParallelForThreads;
  detail::parallel_for_kernel<<<static_cast<unsigned>(blocks), kParallelForThreads, 0, stream>>>(count, body);
  SLS_CUDA_CHECK_LAUNCH();
}
#endif

template <typename Body>
void parallel_for(const Device& device, std::size_t count, const Body& body,
                  [[maybe_unused]] const GpuStream& stream = {}) {
  if (count == 0) return;
  if (device.is_cuda()) {
#if defined(__CUDACC__)
    parallel_for(count, body, cuda_stream(stream));
    return;
#else
    throw_error(ErrorCode::kUnsupported, "parallel_for on {}: this loop was compiled for the CPU only",
                device.to_string());
#endif
  }
  const auto n = static_cast<std::ptrdiff_t>(count);
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (std::ptrdiff_t i = 0; i < n; ++i) body(static_cast<std::size_t>(i));
}

}  // namespace sls
