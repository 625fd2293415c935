#include "sdk/core/ray_map.h"

#include <cmath>

#include "sdk/core/error.h"

#if defined(SLS_HAVE_CUDA)
#include "sdk/core/cuda/ray_map_cuda.h"
#endif

namespace sls {

std::size_t RayMap::valid_count() const {
  std::size_t count = 0;
  for (const std::uint8_t v : valid) count += v != 0 ? 1u : 0u;
  return count;
}

namespace {

void check_intrinsics(const CameraIntrinsics& c) {
  if (c.width <= 0 || c.height <= 0) {
    throw_error(ErrorCode::kInvalidArgument, "ray map: image size {}x{} is not positive", c.width, c.height);
  }
  if (!(c.fx > 0.0) || !(c.fy > 0.0) || !std::isfinite(c.fx) || !std::isfinite(c.fy)) {
    throw_error(ErrorCode::kInvalidArgument, "ray map: focal length ({}, {}) is not positive and finite", c.fx,
                c.fy);
  }
}

void compute_ray_map_cpu(const CameraIntrinsics& c, Vec3f* rays, std::uint8_t* valid) {
  const int width = c.width;
  const int height = c.height;
  // Rows are independent; static scheduling is enough since the Newton cost varies little.
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < height; ++y) {
    const std::size_t row = static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
    for (int x = 0; x < width; ++x) {
      const std::size_t i = row + static_cast<std::size_t>(x);
      valid[i] = ray_map_pixel(c, x, y, &rays[i]) ? std::uint8_t{1} : std::uint8_t{0};
    }
  }
}

}  // namespace

RayMap compute_ray_map(const CameraIntrinsics& intrinsics, const Device& device) {
  require_device(device);
  check_intrinsics(intrinsics);
  RayMap map;
  map.width = intrinsics.width;
  map.height = intrinsics.height;
  const std::size_t count = static_cast<std::size_t>(map.width) * static_cast<std::size_t>(map.height);
  map.rays.resize(count);
  map.valid.resize(count);
  if (device.is_cuda()) {
#if defined(SLS_HAVE_CUDA)
    detail::compute_ray_map_cuda(intrinsics, map.rays.data(), map.valid.data());
#else
    // require_device already threw; this keeps the CPU-only build honest if that changes.
    throw_error(ErrorCode::kUnsupported, "ray map on {}: this build has no CUDA support", device.to_string());
#endif
  } else {
    compute_ray_map_cpu(intrinsics, map.rays.data(), map.valid.data());
  }
  return map;
}

}  // namespace sls
