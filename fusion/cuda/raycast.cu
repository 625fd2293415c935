// CUDA launcher of the raycaster: one thread per pixel around raycast_pixel
// (raycast_shared.h, the code the CPU loop runs).
#include "fusion/cuda/raycast_cuda.h"

#include <math_constants.h>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/kernel_profile.h"

namespace sls::fusion::detail {
namespace {

__global__ void raycast_kernel(VolumeView volume, RaycastParams params, RaycastGuideView guide, Rigid3f T_volume_camera,
                               const Vec3f* __restrict__ rays, int width, int height, RaycastOutputsDevice out) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= width || y >= height) return;
  const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
  const Vec3f ray = rays[i];
  guided_depth_range(guide, x, y, &params);
  const RaycastHit hit = raycast_pixel(volume, params, T_volume_camera, ray);
  out.depth[i] = hit.depth_m;
  out.points[i] = hit.point_camera;
  out.normals[i] = hit.normal_camera;
  out.shaded[i] = shade(hit, ray);
}

// One block per raycast tile: min and max of the measured depths under it.
constexpr int kGuideThreads = 256;

__global__ void guide_tiles_kernel(const float* __restrict__ guide, int guide_width, int guide_height, int width,
                                   int height, int tiles_x, float* tile_min, float* tile_max) {
  const int tx = static_cast<int>(blockIdx.x), ty = static_cast<int>(blockIdx.y);
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  guide_span(tx * kRaycastGuideTile, kRaycastGuideTile, width, guide_width, &x0, &x1);
  guide_span(ty * kRaycastGuideTile, kRaycastGuideTile, height, guide_height, &y0, &y1);
  const int span_x = x1 - x0, count = span_x * (y1 - y0);
  float lo = CUDART_INF_F, hi = 0.0f;
  for (int n = static_cast<int>(threadIdx.x); n < count; n += kGuideThreads) {
    const float depth = guide[static_cast<std::size_t>(y0 + n / span_x) * static_cast<std::size_t>(guide_width) +
                              static_cast<std::size_t>(x0 + n % span_x)];
    if (!is_measured_depth(depth)) continue;
    lo = fminf(lo, depth);
    hi = fmaxf(hi, depth);
  }
  __shared__ float lows[kGuideThreads], highs[kGuideThreads];
  lows[threadIdx.x] = lo;
  highs[threadIdx.x] = hi;
  __syncthreads();
  for (int stride = kGuideThreads / 2; stride > 0; stride /= 2) {
    if (static_cast<int>(threadIdx.x) < stride) {
      lows[threadIdx.x] = fminf(lows[threadIdx.x], lows[threadIdx.x + stride]);
      highs[threadIdx.x] = fmaxf(highs[threadIdx.x], highs[threadIdx.x + stride]);
    }
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    tile_min[ty * tiles_x + tx] = lows[0];
    tile_max[ty * tiles_x + tx] = highs[0];
  }
}

}  // namespace

void launch_raycast_guide_tiles_cuda(const float* guide_depth, int guide_width, int guide_height, int width,
                                     int height, float* tile_min, float* tile_max, cudaStream_t stream) {
  const int tiles_x = (width + kRaycastGuideTile - 1) / kRaycastGuideTile;
  const int tiles_y = (height + kRaycastGuideTile - 1) / kRaycastGuideTile;
  const dim3 grid(static_cast<unsigned>(tiles_x), static_cast<unsigned>(tiles_y));
  guide_tiles_kernel<<<grid, kGuideThreads, 0, stream>>>(guide_depth, guide_width, guide_height, width, height,
                                                         tiles_x, tile_min, tile_max);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_raycast_cuda(const VolumeView& volume, const RaycastParams& params, const RaycastGuideView& guide,
                         const Rigid3f& T_volume_camera, const Vec3f* rays, int width, int height,
                         const RaycastOutputsDevice& out, cudaStream_t stream) {
  // Per pixel its ray read, four maps written (4 + 12 + 12 + 1 bytes) and the guide read; the
  // voxels along the ray depend on the scene and are not counted.
  const double pixel_bytes = 12.0 + 29.0 + (guide.depth_m != nullptr ? 4.0 : 0.0);
  const KernelTimer timer("raycast", pixel_bytes * static_cast<double>(width) * height, stream);
  const dim3 block(32, 8);
  const dim3 grid((static_cast<unsigned>(width) + block.x - 1) / block.x,
                  (static_cast<unsigned>(height) + block.y - 1) / block.y);
  raycast_kernel<<<grid, block, 0, stream>>>(volume, params, guide, T_volume_camera, rays, width, height, out);
  SLS_CUDA_CHECK_LAUNCH();
}

}  // namespace sls::fusion::detail
