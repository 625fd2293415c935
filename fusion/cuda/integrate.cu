// CUDA launchers of the integrator: one thread per voxel around integrate_voxel, one thread
// per active voxel around relax_voxel (integrate_shared.h, the code the CPU loops run).
#include "fusion/cuda/integrate_cuda.h"

#include "sdk/core/cuda/cuda_check.h"

namespace sls::fusion::detail {
namespace {

__global__ void integrate_kernel(VolumeView volume, IntegrationParams params, DepthFrameView frame,
                                 ActiveVoxel* active_red, ActiveVoxel* active_black, std::uint32_t* counters,
                                 std::uint32_t capacity) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int j = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  const int k = static_cast<int>(blockIdx.z);
  if (i >= volume.nx || j >= volume.ny) return;
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
                           ActiveVoxel* const active[2], std::uint32_t* counters, std::uint32_t capacity,
                           cudaStream_t stream) {
  const dim3 block(64, 4, 1);
  const dim3 grid((static_cast<unsigned>(volume.nx) + block.x - 1) / block.x,
                  (static_cast<unsigned>(volume.ny) + block.y - 1) / block.y, static_cast<unsigned>(volume.nz));
  integrate_kernel<<<grid, block, 0, stream>>>(volume, params, frame, active[0], active[1], counters, capacity);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_relax_cuda(const VolumeView& volume, const IntegrationParams& params, const ActiveVoxel* active,
                       std::uint32_t count, cudaStream_t stream) {
  if (count == 0) return;
  const unsigned block = 256;
  relax_kernel<<<(count + block - 1) / block, block, 0, stream>>>(volume, params, active, count);
  SLS_CUDA_CHECK_LAUNCH();
}

}  // namespace sls::fusion::detail
