// The per-pixel viewing rays of a camera: for every pixel, the undistorted camera-frame
// direction with z = 1, so depth-along-the-optical-axis × ray is the 3D point. Decode
// triangulation and fusion read it per pixel instead of running the Newton undistortion
// in their inner loops. Computed once per intrinsics on the CPU or the GPU (DESIGN.md
// section 6: both call ray_map_pixel below, which calls sls::unproject).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/device.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls {

struct RayMap {
  int width = 0;
  int height = 0;
  // Row-major, width * height entries each. rays[i] has z = 1 where valid[i] != 0; where
  // undistortion did not converge (outside the calibrated field) valid[i] = 0 and the ray
  // is {0, 0, 0}, which every projection rejects (z <= 0) rather than producing a point.
  std::vector<Vec3f> rays;
  std::vector<std::uint8_t> valid;

  std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
  }
  const Vec3f& ray(int x, int y) const { return rays[index(x, y)]; }
  bool is_valid(int x, int y) const { return valid[index(x, y)] != 0; }
  std::size_t valid_count() const;
};

// One pixel of the map: unprojection in double (so the stored float is the correctly
// rounded ray), then narrowed. Pixel (x, y) is the centre of that pixel (the camera model's
// convention). Returns whether the ray is valid.
SLS_HOST_DEVICE inline bool ray_map_pixel(const CameraIntrinsics& intrinsics, int x, int y, Vec3f* ray) {
  Vec3d ray_double;
  const bool ok = unproject(intrinsics, Vec2d{static_cast<double>(x), static_cast<double>(y)}, &ray_double);
  // The final residual check in undistort_normalized rejects NaN; this also guards inf.
  const bool finite = ok && std::isfinite(ray_double.x) && std::isfinite(ray_double.y);
  if (!finite) {
    *ray = {0.0f, 0.0f, 0.0f};
    return false;
  }
  *ray = {static_cast<float>(ray_double.x), static_cast<float>(ray_double.y), 1.0f};
  return true;
}

// Element i (= y * width + x) of a map: what both backends' loop runs (parallel_for).
SLS_HOST_DEVICE inline void ray_map_element(const CameraIntrinsics& intrinsics, std::size_t i, Vec3f* rays,
                                            std::uint8_t* valid) {
  const auto width = static_cast<std::size_t>(intrinsics.width);
  const int x = static_cast<int>(i % width), y = static_cast<int>(i / width);
  valid[i] = ray_map_pixel(intrinsics, x, y, &rays[i]) ? std::uint8_t{1} : std::uint8_t{0};
}

// Computes the ray map of a camera on `device`. Throws sls::Error: invalid argument for a
// non-positive image size or focal length; unsupported when CUDA is asked for in a build
// without it; device / out-of-memory errors from the GPU.
RayMap compute_ray_map(const CameraIntrinsics& intrinsics, const Device& device = Device::cpu());

// A camera's ray map as every stage that views through the camera shares it (issue 18: the
// decoder, the tracker's finest level and the raycasters of a 12-megapixel scan each held
// 156 MB of the same rays on the GPU, and computed them): the host map and, on a CUDA device,
// the same rays and flags in its memory. Made once per camera and device, kept while a stage
// holds it.
struct SharedRayMap {
  RayMap host;
  const Vec3f* rays_device = nullptr;          // host.width * host.height, on `device`; CPU: nullptr
  const std::uint8_t* valid_device = nullptr;
  Device device;
  std::shared_ptr<void> device_memory;         // owns rays_device and valid_device
};

// The shared map of `intrinsics` on `device`: the one a live stage already holds (equal
// intrinsics, same device), else a new one computed there. Thread-safe. Throws as
// compute_ray_map.
std::shared_ptr<const SharedRayMap> shared_ray_map(const CameraIntrinsics& intrinsics, const Device& device);

}  // namespace sls
