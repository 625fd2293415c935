#include "sdk/core/ray_map.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <utility>

#include "sdk/core/error.h"
#include "sdk/core/parallel_for.h"

#if defined(SLS_HAVE_CUDA)
#include "sdk/core/cuda/cuda_stream.h"
#include "sdk/core/cuda/device_buffer.h"
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

// The map in host memory, computed on `device` (on a GPU in buffers of its memory, which
// `device_out` keeps when given; else they are freed).
RayMap ray_map_on(const CameraIntrinsics& intrinsics, const Device& device, std::shared_ptr<void>* device_out,
                  const Vec3f** rays_device, const std::uint8_t** valid_device) {
  require_device(device);
  check_intrinsics(intrinsics);
  RayMap map;
  map.width = intrinsics.width;
  map.height = intrinsics.height;
  const std::size_t count = static_cast<std::size_t>(map.width) * static_cast<std::size_t>(map.height);
  map.rays.resize(count);
  map.valid.resize(count);
  if (!device.is_cuda()) {
    Vec3f* rays = map.rays.data();
    std::uint8_t* valid = map.valid.data();
    parallel_for(device, count, SLS_LAMBDA(std::size_t i) { ray_map_element(intrinsics, i, rays, valid); });
    return map;
  }
#if defined(SLS_HAVE_CUDA)
  struct DeviceRays {
    DeviceBuffer<Vec3f> rays;
    DeviceBuffer<std::uint8_t> valid;
  };
  auto memory = std::make_shared<DeviceRays>();
  memory->rays.allocate(count);
  memory->valid.allocate(count);
  const GpuStream stream = GpuStream::create(device);
  detail::fill_ray_map_cuda(device, intrinsics, memory->rays.data(), memory->valid.data(), stream);
  memory->rays.download(map.rays.data(), count, cuda_stream(stream));
  memory->valid.download(map.valid.data(), count, cuda_stream(stream));
  stream.synchronize();
  if (device_out != nullptr) {
    *rays_device = memory->rays.data();
    *valid_device = memory->valid.data();
    *device_out = std::move(memory);
  }
#else
  // require_device already threw; this keeps the CPU-only build honest if that changes.
  (void)device_out, (void)rays_device, (void)valid_device;
  throw_error(ErrorCode::kUnsupported, "ray map on {}: this build has no CUDA support", device.to_string());
#endif
  return map;
}

bool same_camera(const CameraIntrinsics& a, const CameraIntrinsics& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx &&
         a.cy == b.cy && a.k1 == b.k1 && a.k2 == b.k2 && a.k3 == b.k3 && a.p1 == b.p1 && a.p2 == b.p2;
}

}  // namespace

RayMap compute_ray_map(const CameraIntrinsics& intrinsics, const Device& device) {
  return ray_map_on(intrinsics, device, nullptr, nullptr, nullptr);
}

std::shared_ptr<const SharedRayMap> shared_ray_map(const CameraIntrinsics& intrinsics, const Device& device) {
  struct Entry {
    CameraIntrinsics intrinsics;
    Device device;
    std::weak_ptr<const SharedRayMap> map;
  };
  static std::mutex mutex;
  static std::vector<Entry> entries;
  const std::lock_guard<std::mutex> lock(mutex);
  entries.erase(std::remove_if(entries.begin(), entries.end(), [](const Entry& e) { return e.map.expired(); }),
                entries.end());
  for (const Entry& entry : entries) {
    if (entry.device == device && same_camera(entry.intrinsics, intrinsics)) {
      if (auto map = entry.map.lock()) return map;
    }
  }
  auto map = std::make_shared<SharedRayMap>();
  map->device = device;
  map->host = ray_map_on(intrinsics, device, &map->device_memory, &map->rays_device, &map->valid_device);
  entries.push_back({intrinsics, device, map});
  return map;
}

}  // namespace sls
