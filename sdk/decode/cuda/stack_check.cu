// The decoder's stack check, gathered where the stack is (decoder_cuda.h): the pixels of the
// check's grid (stack_check_shared.h, the CPU gather's too) of every image, and the largest
// contrast for the all-dark test, so that only ~1.4 MB of a 528 MB stack crosses to the host.
#include <climits>

#include <cub/block/block_reduce.cuh>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/decode/cuda/decoder_cuda.h"

namespace sls::detail {
namespace {

constexpr int kThreads = 256;

struct Larger {
  __device__ int operator()(int a, int b) const { return a > b ? a : b; }
};

__global__ void gather_kernel(const std::uint16_t* __restrict__ stack, std::size_t plane_stride, int images,
                              StackCheckGrid grid, std::uint16_t* __restrict__ samples) {
  const std::size_t count = grid.count();
  const std::size_t total = count * static_cast<std::size_t>(images);
  for (std::size_t j = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x; j < total;
       j += static_cast<std::size_t>(gridDim.x) * blockDim.x) {
    const std::size_t k = j / count;
    samples[j] = stack[k * plane_stride + grid.pixel(j - k * count)];
  }
}

// Each block reduces its share of the pixels, then one atomic per block.
__global__ void largest_kernel(const std::uint16_t* __restrict__ stack, std::size_t plane_stride,
                               std::size_t pixels, int images, int white_index, int black_index, int* largest) {
  int best = INT_MIN;
  for (std::size_t i = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x; i < pixels;
       i += static_cast<std::size_t>(gridDim.x) * blockDim.x) {
    if (white_index >= 0 && black_index >= 0) {
      best = max(best, int{stack[static_cast<std::size_t>(white_index) * plane_stride + i]} -
                           int{stack[static_cast<std::size_t>(black_index) * plane_stride + i]});
    } else {
      for (int k = 0; k < images; ++k) best = max(best, int{stack[static_cast<std::size_t>(k) * plane_stride + i]});
    }
  }
  using Reduce = cub::BlockReduce<int, kThreads>;
  __shared__ typename Reduce::TempStorage scratch;
  const int block_best = Reduce(scratch).Reduce(best, Larger{});
  if (threadIdx.x == 0) atomicMax(largest, block_best);
}

unsigned blocks_for(std::size_t work) {
  // Enough blocks to fill the GPU; the loops stride over the rest.
  const std::size_t blocks = (work + kThreads - 1) / kThreads;
  return static_cast<unsigned>(blocks < 4096 ? (blocks > 0 ? blocks : 1) : 4096);
}

}  // namespace

void launch_stack_check_gather(const std::uint16_t* stack, std::size_t plane_stride, int images,
                               const StackCheckGrid& grid, int white_index, int black_index, std::uint16_t* samples,
                               int* largest, cudaStream_t stream) {
  // The stack's planes are whole images: plane_stride pixels each.
  largest_kernel<<<blocks_for(plane_stride), kThreads, 0, stream>>>(stack, plane_stride, plane_stride, images,
                                                                     white_index, black_index, largest);
  SLS_CUDA_CHECK_LAUNCH();
  const std::size_t total = grid.count() * static_cast<std::size_t>(images);
  if (total == 0) return;
  gather_kernel<<<blocks_for(total), kThreads, 0, stream>>>(stack, plane_stride, images, grid, samples);
  SLS_CUDA_CHECK_LAUNCH();
}

}  // namespace sls::detail
