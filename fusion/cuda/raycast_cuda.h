// Internal: the CUDA launcher of the raycaster (fusion/raycaster.h).
#pragma once

#include <cstdint>

#include <cuda_runtime_api.h>

#include "fusion/raycast_shared.h"
#include "fusion/raycaster_gpu.h"

namespace sls::fusion::detail {

// guide: RaycastGuideView{} for an unguided raycast.
void launch_raycast_cuda(const VolumeView& volume, const RaycastParams& params, const RaycastGuideView& guide,
                         const Rigid3f& T_volume_camera, const Vec3f* rays, int width, int height,
                         const RaycastOutputsDevice& out, cudaStream_t stream);

// The guide's measured depth range per raycast tile (RaycastGuideView's tile_min_m/tile_max_m).
void launch_raycast_guide_tiles_cuda(const float* guide_depth, int guide_width, int guide_height, int width,
                                     int height, float* tile_min, float* tile_max, cudaStream_t stream);

}  // namespace sls::fusion::detail
