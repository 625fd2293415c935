// The decoder's stack check where the stack is (decoder_cuda.h): each pixel of the check's grid
// judged as the CPU judges it (judge_stack_pixel, stack_check_shared.h) into the histograms the
// host takes the medians of, and the largest contrast for the all-dark test, so that ~0.2 MB of
// a 528 MB stack crosses to the host and the host's share is the medians. Compiled with
// -fmad=false (sdk/decode/CMakeLists.txt): the histograms' bins are then the CPU's to the bit.
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

// One thread per grid pixel; one atomic per value into the histograms (~20 per lit pixel, over
// 2048 bins each).
__global__ void judge_kernel(const std::uint16_t* __restrict__ stack, std::size_t plane_stride, StackCheckGrid grid,
                             StackCheckPlan plan, std::uint32_t* __restrict__ counts, unsigned long long* lit) {
  const std::size_t count = grid.count();
  for (std::size_t n = blockIdx.x * static_cast<std::size_t>(blockDim.x) + threadIdx.x; n < count;
       n += static_cast<std::size_t>(gridDim.x) * blockDim.x) {
    const std::size_t pixel = grid.pixel(n);
    const auto sample = [&](int k) {
      return static_cast<float>(stack[static_cast<std::size_t>(k) * plane_stride + pixel]);
    };
    const auto add = [&](int slot, int bin) {
      atomicAdd(counts + static_cast<std::size_t>(slot) * kStackCheckBins + static_cast<std::size_t>(bin), 1u);
    };
    if (judge_stack_pixel(plan, sample, add)) atomicAdd(lit, 1ull);
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

void launch_stack_check(const std::uint16_t* stack, std::size_t plane_stride, int images, const StackCheckGrid& grid,
                        const StackCheckPlan& plan, int* largest, std::uint32_t* counts, unsigned long long* lit,
                        cudaStream_t stream) {
  // The stack's planes are whole images: plane_stride pixels each.
  largest_kernel<<<blocks_for(plane_stride), kThreads, 0, stream>>>(stack, plane_stride, plane_stride, images,
                                                                     plan.white, plan.black, largest);
  SLS_CUDA_CHECK_LAUNCH();
  if (!plan.usable || grid.count() == 0) return;
  judge_kernel<<<blocks_for(grid.count()), kThreads, 0, stream>>>(stack, plane_stride, grid, plan, counts, lit);
  SLS_CUDA_CHECK_LAUNCH();
}

}  // namespace sls::detail
