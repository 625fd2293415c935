#include "fusion/raycaster.h"

#include <algorithm>
#include <limits>

#include "fusion/raycaster_gpu.h"
#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"

namespace sls::fusion {

struct Raycaster::Impl {
  Device device;
  CameraIntrinsics camera;
  RaycastOptions options;
  std::shared_ptr<const SharedRayMap> shared_rays;  // the camera's, shared with the other stages
  const RayMap* rays = nullptr;                     // shared_rays->host
  GpuStream gpu_stream;                             // the session's, or its own (CUDA)
  // A CUDA raycaster's: the maps of a raycast asked for in host memory (made on first such
  // call), a host guide's upload and the guide's depth range per tile.
  std::unique_ptr<RaycastResult> device_maps;
  Image32f guide_upload{MemoryType::kDevice};
  Buffer<float> guide_tile_min, guide_tile_max;

  RaycastParams params(const Volume& volume) const {
    RaycastParams p;
    p.truncation_m = static_cast<float>(options.truncation_voxels * volume.geometry().voxel_size_m);
    p.min_depth_m = static_cast<float>(options.min_depth_m);
    p.max_depth_m = static_cast<float>(options.max_depth_m);
    return p;
  }

  int tiles_x() const { return (camera.width + kRaycastGuideTile - 1) / kRaycastGuideTile; }
  int tiles_y() const { return (camera.height + kRaycastGuideTile - 1) / kRaycastGuideTile; }

  RaycastGuideView guide_view(const Volume& volume, const float* guide_depth, int guide_width, int guide_height,
                              const float* tile_min, const float* tile_max) const {
    RaycastGuideView g;
    g.depth_m = guide_depth;
    g.guide_width = guide_width;
    g.guide_height = guide_height;
    g.width = camera.width;
    g.height = camera.height;
    g.tile_min_m = tile_min;
    g.tile_max_m = tile_max;
    g.tiles_x = tiles_x();
    g.tiles_y = tiles_y();
    g.margin_m = static_cast<float>(options.guide_margin_truncations * options.truncation_voxels *
                                    volume.geometry().voxel_size_m);
    return g;
  }

  void check_guide(int guide_width, int guide_height) const {
    if (guide_width < camera.width || guide_height < camera.height) {
      throw_error(ErrorCode::kInvalidArgument, "raycast: a guide depth map of {}x{} pixels for a {}x{} raycast",
                  guide_width, guide_height, camera.width, camera.height);
    }
  }

  void raycast_cpu(const Volume& volume, const Pose& T_world_camera, const RaycastGuideView& guide,
                   RaycastResult* result) const;
  // Sized to the camera in the memory `out` was made for (kept when it already is).
  void size_maps(RaycastResult& out) const {
    const int w = camera.width, h = camera.height;
    if (out.depth_m.width() == w && out.depth_m.height() == h && out.points_camera.width() == w &&
        out.points_camera.height() == h && out.normals_camera.width() == w && out.normals_camera.height() == h &&
        out.shaded.width() == w && out.shaded.height() == h) {
      return;
    }
    out.depth_m.resize(w, h, 0.0f);
    out.points_camera.resize(w, h, Vec3f{0.0f, 0.0f, 0.0f});
    out.normals_camera.resize(w, h, Vec3f{0.0f, 0.0f, 0.0f});
    out.shaded.resize(w, h, 0);
  }
  void raycast_cpu(const Volume& volume, const Pose& T_world_camera, const Image32f* guide, RaycastResult& out) const;
  void raycast_gpu(const Volume& volume, const Pose& T_world_camera, const Image32f* guide, RaycastResult& out);
};


void Raycaster::Impl::raycast_cpu(const Volume& volume, const Pose& T_world_camera, const Image32f* guide_depth_m,
                                  RaycastResult& out) const {
  // The tiles' measured depth range, for rays whose own guide pixels have none.
  RaycastGuideView guide;
  std::vector<float> tile_min, tile_max;
  if (guide_depth_m != nullptr) {
    const int tiles_x = this->tiles_x(), tiles_y = this->tiles_y();
    tile_min.assign(static_cast<std::size_t>(tiles_x) * static_cast<std::size_t>(tiles_y),
                    std::numeric_limits<float>::infinity());
    tile_max.assign(tile_min.size(), 0.0f);
    for (int ty = 0; ty < tiles_y; ++ty) {
      int y0 = 0, y1 = 0;
      guide_span(ty * kRaycastGuideTile, kRaycastGuideTile, camera.height, guide_depth_m->height(), &y0, &y1);
      for (int tx = 0; tx < tiles_x; ++tx) {
        int x0 = 0, x1 = 0;
        guide_span(tx * kRaycastGuideTile, kRaycastGuideTile, camera.width, guide_depth_m->width(), &x0, &x1);
        const std::size_t t =
            static_cast<std::size_t>(ty) * static_cast<std::size_t>(tiles_x) + static_cast<std::size_t>(tx);
        for (int y = y0; y < y1; ++y) {
          for (int x = x0; x < x1; ++x) {
            const float depth = (*guide_depth_m)(x, y);
            if (!is_measured_depth(depth)) continue;
            tile_min[t] = std::min(tile_min[t], depth);
            tile_max[t] = std::max(tile_max[t], depth);
          }
        }
      }
    }
    guide = guide_view(volume, guide_depth_m->data(), guide_depth_m->width(), guide_depth_m->height(),
                       tile_min.data(), tile_max.data());
  }
  const VolumeView view = volume.view();
  const RaycastParams base = params(volume);
  const Rigid3f T_volume_camera = (volume.geometry().T_world_volume.inverse() * T_world_camera).to_rigid3f();
  const int width = camera.width, height = camera.height;
  float* depth = out.depth_m.data();
  Vec3f* points = out.points_camera.data();
  Vec3f* normals = out.normals_camera.data();
  std::uint8_t* shaded = out.shaded.data();
#if defined(_OPENMP)
#pragma omp parallel for schedule(dynamic, 4)
#endif
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t i = rays->index(x, y);
      const Vec3f ray = rays->rays[i];
      RaycastParams pixel_params = base;
      guided_depth_range(guide, x, y, &pixel_params);
      const RaycastHit hit = raycast_pixel(view, pixel_params, T_volume_camera, ray);
      depth[i] = hit.depth_m;
      points[i] = hit.point_camera;
      normals[i] = hit.normal_camera;
      shaded[i] = shade(hit, ray);
    }
  }
}

void Raycaster::Impl::raycast_gpu(const Volume& volume, const Pose& T_world_camera, const Image32f* guide_depth_m,
                                  RaycastResult& out) {
  require_device(device);
  RaycastGuideView guide;
  if (guide_depth_m != nullptr) {
    const Image32f* guide_on_device = guide_depth_m;
    if (guide_depth_m->memory_type() != MemoryType::kDevice) {
      guide_upload.copy_from(*guide_depth_m, gpu_stream);
      guide_on_device = &guide_upload;
    }
    const std::size_t tiles = static_cast<std::size_t>(tiles_x()) * static_cast<std::size_t>(tiles_y());
    guide_tile_min.resize_uninitialized(tiles, MemoryType::kDevice);
    guide_tile_max.resize_uninitialized(tiles, MemoryType::kDevice);
    detail::raycast_guide_tiles_gpu(guide_on_device->data(), guide_on_device->width(), guide_on_device->height(),
                                    camera.width, camera.height, guide_tile_min.data(), guide_tile_max.data(),
                                    gpu_stream);
    guide = guide_view(volume, guide_on_device->data(), guide_on_device->width(), guide_on_device->height(),
                       guide_tile_min.data(), guide_tile_max.data());
  }
  // Host maps: raycast into device maps kept for that, then downloaded.
  const bool download = out.memory_type() != MemoryType::kDevice;
  if (download && !device_maps) device_maps = std::make_unique<RaycastResult>(MemoryType::kDevice);
  RaycastResult& maps = download ? *device_maps : out;
  size_maps(maps);
  const Rigid3f T_volume_camera = (volume.geometry().T_world_volume.inverse() * T_world_camera).to_rigid3f();
  detail::RaycastOutputsDevice outputs;
  outputs.depth = maps.depth_m.data();
  outputs.points = maps.points_camera.data();
  outputs.normals = maps.normals_camera.data();
  outputs.shaded = maps.shaded.data();
  detail::raycast_gpu(volume.view(), params(volume), guide, T_volume_camera, shared_rays->rays_device, camera.width,
                      camera.height, outputs, gpu_stream);
  if (download) {
    out.depth_m.copy_from(maps.depth_m, gpu_stream);
    out.points_camera.copy_from(maps.points_camera, gpu_stream);
    out.normals_camera.copy_from(maps.normals_camera, gpu_stream);
    out.shaded.copy_from(maps.shaded, gpu_stream);
    gpu_stream.synchronize();
  }
}

Raycaster::Raycaster(const Device& device, const CameraIntrinsics& camera, const RaycastOptions& options,
                     const GpuStream& stream)
    : impl_(std::make_unique<Impl>()) {
  if (camera.width <= 0 || camera.height <= 0) {
    throw_error(ErrorCode::kInvalidArgument, "raycast: camera of {}x{} pixels", camera.width, camera.height);
  }
  if (!(options.max_depth_m > options.min_depth_m) || !(options.truncation_voxels > 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "raycast: depth range [{}, {}] m or truncation {} voxels unusable",
                options.min_depth_m, options.max_depth_m, options.truncation_voxels);
  }
  impl_->device = device;
  impl_->camera = camera;
  impl_->options = options;
  impl_->shared_rays = shared_ray_map(camera, device);
  impl_->rays = &impl_->shared_rays->host;
  impl_->gpu_stream = GpuStream::or_create(stream, device);
}

Raycaster::~Raycaster() = default;
Raycaster::Raycaster(Raycaster&&) noexcept = default;
Raycaster& Raycaster::operator=(Raycaster&&) noexcept = default;

const CameraIntrinsics& Raycaster::camera() const { return impl_->camera; }
const Device& Raycaster::device() const { return impl_->device; }

void Raycaster::raycast(const Volume& volume, const Pose& T_world_camera, RaycastResult& out,
                        const Image32f* guide_depth_m) {
  Impl& s = *impl_;
  if (!(volume.device() == s.device)) {
    throw_error(ErrorCode::kInvalidArgument, "raycast: the volume lives on {}, the raycaster on {}",
                volume.device().to_string(), s.device.to_string());
  }
  if (guide_depth_m != nullptr) s.check_guide(guide_depth_m->width(), guide_depth_m->height());
  if (s.device.is_cuda()) {
    s.raycast_gpu(volume, T_world_camera, guide_depth_m, out);
    return;
  }
  const bool device_guide = guide_depth_m != nullptr && guide_depth_m->memory_type() == MemoryType::kDevice;
  if (out.memory_type() == MemoryType::kDevice || device_guide) {
    throw_error(ErrorCode::kInvalidArgument, "raycast: a raycaster for {} reads and writes host maps, not {} on a GPU",
                s.device.to_string(), device_guide ? "a guide depth map" : "maps");
  }
  s.size_maps(out);
  s.raycast_cpu(volume, T_world_camera, guide_depth_m, out);
}

RaycastResult Raycaster::raycast(const Volume& volume, const Pose& T_world_camera) {
  RaycastResult result;
  raycast(volume, T_world_camera, result);
  return result;
}

RaycastResult Raycaster::raycast(const Volume& volume, const Pose& T_world_camera, const Image32f& guide_depth_m) {
  RaycastResult result;
  raycast(volume, T_world_camera, result, &guide_depth_m);
  return result;
}

void Raycaster::synchronize() { impl_->gpu_stream.synchronize(); }

}  // namespace sls::fusion
