// CUDA launchers of the integrator: one thread per voxel around integrate_voxel, one thread
// per active voxel around relax_voxel (integrate_shared.h, the code the CPU loops run).
#include "fusion/cuda/integrate_cuda.h"

#include <cub/device/device_radix_sort.cuh>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/device.h"

namespace sls::fusion::detail {
namespace {

__global__ void integrate_kernel(VolumeView volume, IntegrationParams params, DepthFrameView frame, int i0, int j0,
                                 int k0, int i1, int j1, ActiveVoxel* active_red, ActiveVoxel* active_black,
                                 std::uint32_t* counters, std::uint32_t capacity) {
  const int i = i0 + static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int j = j0 + static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  const int k = k0 + static_cast<int>(blockIdx.z);
  if (i >= i1 || j >= j1) return;
  float average = 0.0f;
  if (!integrate_voxel(volume, params, frame, i, j, k, &average) || !(params.alpha > 0.0f)) return;
  const int parity = voxel_parity(i, j, k);
  const std::uint32_t slot = atomicAdd(&counters[parity], 1u);
  if (slot < capacity) {
    (parity == 0 ? active_red : active_black)[slot] =
        ActiveVoxel{static_cast<std::uint32_t>(volume.index(i, j, k)), average};
  }
}

__global__ void relax_kernel(VolumeView volume, IntegrationParams params, const ActiveVoxel* __restrict__ active,
                             std::uint32_t count) {
  const std::uint32_t n = blockIdx.x * blockDim.x + threadIdx.x;
  if (n >= count) return;
  const ActiveVoxel voxel = active[n];
  volume.set_u(voxel.index, relax_voxel(volume, params, voxel));
}

}  // namespace

void launch_integrate_cuda(const VolumeView& volume, const IntegrationParams& params, const DepthFrameView& frame,
                           const int first[3], const int extent[3], ActiveVoxel* const active[2],
                           std::uint32_t* counters, std::uint32_t capacity, cudaStream_t stream) {
  if (extent[0] <= 0 || extent[1] <= 0 || extent[2] <= 0) return;
  const dim3 block(64, 4, 1);
  const dim3 grid((static_cast<unsigned>(extent[0]) + block.x - 1) / block.x,
                  (static_cast<unsigned>(extent[1]) + block.y - 1) / block.y, static_cast<unsigned>(extent[2]));
  integrate_kernel<<<grid, block, 0, stream>>>(volume, params, frame, first[0], first[1], first[2],
                                               first[0] + extent[0], first[1] + extent[1], active[0], active[1],
                                               counters, capacity);
  SLS_CUDA_CHECK_LAUNCH();
}

void sort_active_cuda(ActiveVoxel* active, std::uint32_t count, void** scratch, std::size_t* scratch_bytes,
                      ActiveVoxel** sorted, std::size_t* sorted_capacity, cudaStream_t stream) {
  if (count < 2) return;
  // An ActiveVoxel is 8 bytes, index in the low word: sort it as a 64-bit key on bits 0..31.
  static_assert(sizeof(ActiveVoxel) == sizeof(unsigned long long), "ActiveVoxel packs into 64 bits");
  const auto* keys_in = reinterpret_cast<const unsigned long long*>(active);
  if (*sorted_capacity < count) {
    if (*sorted != nullptr) {
      SLS_CUDA_CHECK(cudaFree(*sorted));
      note_gpu_allocation(-static_cast<std::ptrdiff_t>(*sorted_capacity * sizeof(ActiveVoxel)));
    }
    *sorted = nullptr;
    *sorted_capacity = 0;
    SLS_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(sorted), count * sizeof(ActiveVoxel)));
    *sorted_capacity = count;
    note_gpu_allocation(static_cast<std::ptrdiff_t>(count * sizeof(ActiveVoxel)));
  }
  auto* keys_out = reinterpret_cast<unsigned long long*>(*sorted);
  std::size_t needed = 0;
  SLS_CUDA_CHECK(cub::DeviceRadixSort::SortKeys(nullptr, needed, keys_in, keys_out, static_cast<int>(count), 0, 32,
                                                stream));
  if (*scratch_bytes < needed) {
    if (*scratch != nullptr) {
      SLS_CUDA_CHECK(cudaFree(*scratch));
      note_gpu_allocation(-static_cast<std::ptrdiff_t>(*scratch_bytes));
    }
    *scratch = nullptr;
    *scratch_bytes = 0;
    SLS_CUDA_CHECK(cudaMalloc(scratch, needed));
    *scratch_bytes = needed;
    note_gpu_allocation(static_cast<std::ptrdiff_t>(needed));
  }
  SLS_CUDA_CHECK(cub::DeviceRadixSort::SortKeys(*scratch, needed, keys_in, keys_out, static_cast<int>(count), 0, 32,
                                                stream));
  SLS_CUDA_CHECK(cudaMemcpyAsync(active, *sorted, count * sizeof(ActiveVoxel), cudaMemcpyDeviceToDevice, stream));
}

void launch_relax_cuda(const VolumeView& volume, const IntegrationParams& params, const ActiveVoxel* active,
                       std::uint32_t count, cudaStream_t stream) {
  if (count == 0) return;
  const unsigned block = 256;
  relax_kernel<<<(count + block - 1) / block, block, 0, stream>>>(volume, params, active, count);
  SLS_CUDA_CHECK_LAUNCH();
}

}  // namespace sls::fusion::detail
