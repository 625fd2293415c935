// CUDA launcher of the raycaster: one thread per pixel around raycast_pixel
// (raycast_shared.h, the code the CPU loop runs).
#include "fusion/cuda/raycast_cuda.h"

#include "sdk/core/cuda/cuda_check.h"

namespace sls::fusion::detail {
namespace {

__global__ void raycast_kernel(VolumeView volume, RaycastParams params, Rigid3f T_volume_camera,
                               const Vec3f* __restrict__ rays, int width, int height, RaycastOutputsDevice out) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= width || y >= height) return;
  const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
  const Vec3f ray = rays[i];
  const RaycastHit hit = raycast_pixel(volume, params, T_volume_camera, ray);
  out.depth[i] = hit.depth_m;
  out.points[i] = hit.point_camera;
  out.normals[i] = hit.normal_camera;
  out.shaded[i] = shade(hit, ray);
}

}  // namespace

void launch_raycast_cuda(const VolumeView& volume, const RaycastParams& params, const Rigid3f& T_volume_camera,
                         const Vec3f* rays, int width, int height, const RaycastOutputsDevice& out,
                         cudaStream_t stream) {
  const dim3 block(32, 8);
  const dim3 grid((static_cast<unsigned>(width) + block.x - 1) / block.x,
                  (static_cast<unsigned>(height) + block.y - 1) / block.y);
  raycast_kernel<<<grid, block, 0, stream>>>(volume, params, T_volume_camera, rays, width, height, out);
  SLS_CUDA_CHECK_LAUNCH();
}

}  // namespace sls::fusion::detail
