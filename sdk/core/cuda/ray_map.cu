// CUDA backend of the ray map: ray_map_element (sdk/core/ray_map.h) in parallel_for, the
// same per-element code the CPU loop runs.
#include "sdk/core/cuda/ray_map_cuda.h"

#include <cstddef>

#include "sdk/core/parallel_for.h"
#include "sdk/core/ray_map.h"

namespace sls::detail {

void fill_ray_map_cuda(const Device& device, const CameraIntrinsics& intrinsics, Vec3f* rays_device,
                       std::uint8_t* valid_device, const GpuStream& stream) {
  const std::size_t count =
      static_cast<std::size_t>(intrinsics.width) * static_cast<std::size_t>(intrinsics.height);
  parallel_for(
      device, count, SLS_LAMBDA(std::size_t i) { ray_map_element(intrinsics, i, rays_device, valid_device); },
      stream);
}

}  // namespace sls::detail
