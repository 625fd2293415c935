// The raycaster's GPU launches (fusion/raycaster_gpu.h) on a GpuStream, built with CUDA only.
#include "fusion/raycaster_gpu.h"

#include "fusion/cuda/raycast_cuda.h"
#include "sdk/core/cuda/cuda_stream.h"

namespace sls::fusion::detail {

void raycast_gpu(const VolumeView& volume, const RaycastParams& params, const RaycastGuideView& guide,
                 const Rigid3f& T_volume_camera, const Vec3f* rays, int width, int height,
                 const RaycastOutputsDevice& out, const GpuStream& stream) {
  launch_raycast_cuda(volume, params, guide, T_volume_camera, rays, width, height, out, cuda_stream(stream));
}

void raycast_guide_tiles_gpu(const float* guide_depth, int guide_width, int guide_height, int width, int height,
                             float* tile_min, float* tile_max, const GpuStream& stream) {
  launch_raycast_guide_tiles_cuda(guide_depth, guide_width, guide_height, width, height, tile_min, tile_max,
                                  cuda_stream(stream));
}

}  // namespace sls::fusion::detail
