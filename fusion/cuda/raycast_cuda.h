// Internal: the CUDA launcher of the raycaster (fusion/raycaster.h).
#pragma once

#include <cstdint>

#include <cuda_runtime_api.h>

#include "fusion/raycast_shared.h"

namespace sls::fusion::detail {

struct RaycastOutputsDevice {
  float* depth = nullptr;
  Vec3f* points = nullptr;
  Vec3f* normals = nullptr;
  std::uint8_t* shaded = nullptr;
};

void launch_raycast_cuda(const VolumeView& volume, const RaycastParams& params, const Rigid3f& T_volume_camera,
                         const Vec3f* rays, int width, int height, const RaycastOutputsDevice& out,
                         cudaStream_t stream);

}  // namespace sls::fusion::detail
