// Internal: the raycaster's GPU launches (fusion/raycaster.h), on the session's stream.
// Declared in every build, without CUDA's headers; defined in fusion/cuda/raycaster_gpu.cpp
// over raycast.cu's launchers, or in a build without CUDA by fusion/no_cuda.cpp, where they
// throw kUnsupported (a raycaster on a GPU is refused before: require_device).
#pragma once

#include <cstdint>

#include "fusion/raycast_shared.h"
#include "sdk/core/gpu_stream.h"

namespace sls::fusion::detail {

// Where a raycast on the GPU writes (device memory, width x height each).
struct RaycastOutputsDevice {
  float* depth = nullptr;
  Vec3f* points = nullptr;
  Vec3f* normals = nullptr;
  std::uint8_t* shaded = nullptr;
};

// guide: RaycastGuideView{} for an unguided raycast. Returns once queued on `stream`.
void raycast_gpu(const VolumeView& volume, const RaycastParams& params, const RaycastGuideView& guide,
                 const Rigid3f& T_volume_camera, const Vec3f* rays, int width, int height,
                 const RaycastOutputsDevice& out, const GpuStream& stream);

// The guide's measured depth range per raycast tile (RaycastGuideView's tile_min_m/tile_max_m).
void raycast_guide_tiles_gpu(const float* guide_depth, int guide_width, int guide_height, int width, int height,
                             float* tile_min, float* tile_max, const GpuStream& stream);

}  // namespace sls::fusion::detail
