#include "fusion/raycaster.h"

#include <algorithm>
#include <limits>

#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>

#include "fusion/cuda/raycast_cuda.h"
#include "sdk/core/cuda/cuda_stream.h"
#include "sdk/core/cuda/device_buffer.h"
#endif

namespace sls::fusion {

struct Raycaster::Impl {
  Device device;
  CameraIntrinsics camera;
  RaycastOptions options;
  std::shared_ptr<const SharedRayMap> shared_rays;  // the camera's, shared with the other stages
  const RayMap* rays = nullptr;                     // shared_rays->host
  GpuStream gpu_stream;                             // the session's, or its own (CUDA)
#if defined(SLS_HAVE_CUDA)
  cudaStream_t stream = nullptr;  // gpu_stream's
  DeviceBuffer<float> depth;
  DeviceBuffer<Vec3f> points, normals;
  DeviceBuffer<std::uint8_t> shaded;
  DeviceBuffer<float> guide_tile_min, guide_tile_max;
#endif

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
#if defined(SLS_HAVE_CUDA)
  // The kernel into this raycaster's device maps, on its stream.
  void launch(const Volume& volume, const Pose& T_world_camera, const RaycastGuideView& guide) {
    const Rigid3f T_volume_camera = (volume.geometry().T_world_volume.inverse() * T_world_camera).to_rigid3f();
    detail::RaycastOutputsDevice out;
    out.depth = depth.data();
    out.points = points.data();
    out.normals = normals.data();
    out.shaded = shaded.data();
    detail::launch_raycast_cuda(volume.view(), params(volume), guide, T_volume_camera, shared_rays->rays_device,
                                camera.width, camera.height, out, stream);
  }
#endif
};

void Raycaster::Impl::raycast_cpu(const Volume& volume, const Pose& T_world_camera, const RaycastGuideView& guide,
                                  RaycastResult* result) const {
  const VolumeView view = volume.view();
  const RaycastParams base = params(volume);
  const Rigid3f T_volume_camera = (volume.geometry().T_world_volume.inverse() * T_world_camera).to_rigid3f();
  const int width = camera.width, height = camera.height;
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
      result->depth_m.data()[i] = hit.depth_m;
      result->points_camera[i] = hit.point_camera;
      result->normals_camera[i] = hit.normal_camera;
      result->shaded.data()[i] = shade(hit, ray);
    }
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
#if defined(SLS_HAVE_CUDA)
  if (device.is_cuda()) {
    Impl& s = *impl_;
    const std::size_t pixels = s.rays->rays.size();
    s.stream = cuda_stream(s.gpu_stream);
    s.depth.allocate(pixels);
    s.points.allocate(pixels);
    s.normals.allocate(pixels);
    s.shaded.allocate(pixels);
  }
#endif
}

Raycaster::~Raycaster() = default;
Raycaster::Raycaster(Raycaster&&) noexcept = default;
Raycaster& Raycaster::operator=(Raycaster&&) noexcept = default;

const CameraIntrinsics& Raycaster::camera() const { return impl_->camera; }
const Device& Raycaster::device() const { return impl_->device; }

namespace {

RaycastResult empty_result(const CameraIntrinsics& camera) {
  const std::size_t pixels = static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height);
  RaycastResult result;
  result.depth_m = Image32f(camera.width, camera.height, 0.0f);
  result.shaded = Image8u(camera.width, camera.height, 0);
  result.points_camera.assign(pixels, Vec3f{0.0f, 0.0f, 0.0f});
  result.normals_camera.assign(pixels, Vec3f{0.0f, 0.0f, 0.0f});
  return result;
}

}  // namespace

RaycastResult Raycaster::raycast(const Volume& volume, const Pose& T_world_camera) {
  Impl& s = *impl_;
  if (!(volume.device() == s.device)) {
    throw_error(ErrorCode::kInvalidArgument, "raycast: the volume lives on {}, the raycaster on {}",
                volume.device().to_string(), s.device.to_string());
  }
  RaycastResult result = empty_result(s.camera);
  if (s.device.is_cuda()) {
#if defined(SLS_HAVE_CUDA)
    raycast_device(volume, T_world_camera);
    download(&result);
    return result;
#endif
  }
  s.raycast_cpu(volume, T_world_camera, RaycastGuideView{}, &result);
  return result;
}

RaycastResult Raycaster::raycast(const Volume& volume, const Pose& T_world_camera, const Image32f& guide_depth_m) {
  Impl& s = *impl_;
  if (!(volume.device() == s.device)) {
    throw_error(ErrorCode::kInvalidArgument, "raycast: the volume lives on {}, the raycaster on {}",
                volume.device().to_string(), s.device.to_string());
  }
  s.check_guide(guide_depth_m.width(), guide_depth_m.height());
  RaycastResult result = empty_result(s.camera);
  if (s.device.is_cuda()) {
#if defined(SLS_HAVE_CUDA)
    DeviceBuffer<float> guide(guide_depth_m.pixel_count());
    guide.upload(guide_depth_m.data(), guide_depth_m.pixel_count(), s.stream);
    raycast_device(volume, T_world_camera, guide.data(), guide_depth_m.width(), guide_depth_m.height());
    download(&result);
    return result;
#endif
  }
  // The tiles' measured depth range, for rays whose own guide pixels have none.
  const int tiles_x = s.tiles_x(), tiles_y = s.tiles_y();
  std::vector<float> tile_min(static_cast<std::size_t>(tiles_x) * static_cast<std::size_t>(tiles_y),
                              std::numeric_limits<float>::infinity());
  std::vector<float> tile_max(tile_min.size(), 0.0f);
  for (int ty = 0; ty < tiles_y; ++ty) {
    int y0 = 0, y1 = 0;
    guide_span(ty * kRaycastGuideTile, kRaycastGuideTile, s.camera.height, guide_depth_m.height(), &y0, &y1);
    for (int tx = 0; tx < tiles_x; ++tx) {
      int x0 = 0, x1 = 0;
      guide_span(tx * kRaycastGuideTile, kRaycastGuideTile, s.camera.width, guide_depth_m.width(), &x0, &x1);
      const std::size_t t = static_cast<std::size_t>(ty) * static_cast<std::size_t>(tiles_x) + static_cast<std::size_t>(tx);
      for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) {
          const float depth = guide_depth_m(x, y);
          if (!is_measured_depth(depth)) continue;
          tile_min[t] = std::min(tile_min[t], depth);
          tile_max[t] = std::max(tile_max[t], depth);
        }
      }
    }
  }
  s.raycast_cpu(volume, T_world_camera,
                s.guide_view(volume, guide_depth_m.data(), guide_depth_m.width(), guide_depth_m.height(),
                             tile_min.data(), tile_max.data()),
                &result);
  return result;
}

#if defined(SLS_HAVE_CUDA)
void Raycaster::raycast_device(const Volume& volume, const Pose& T_world_camera) {
  require_device(impl_->device);
  impl_->launch(volume, T_world_camera, RaycastGuideView{});
}

void Raycaster::raycast_device(const Volume& volume, const Pose& T_world_camera, const float* guide_depth_device,
                               int guide_width, int guide_height) {
  Impl& s = *impl_;
  require_device(s.device);
  s.check_guide(guide_width, guide_height);
  const std::size_t tiles = static_cast<std::size_t>(s.tiles_x()) * static_cast<std::size_t>(s.tiles_y());
  if (s.guide_tile_min.size() < tiles) {
    s.guide_tile_min.allocate(tiles);
    s.guide_tile_max.allocate(tiles);
  }
  detail::launch_raycast_guide_tiles_cuda(guide_depth_device, guide_width, guide_height, s.camera.width,
                                          s.camera.height, s.guide_tile_min.data(), s.guide_tile_max.data(), s.stream);
  s.launch(volume, T_world_camera,
           s.guide_view(volume, guide_depth_device, guide_width, guide_height, s.guide_tile_min.data(),
                        s.guide_tile_max.data()));
}

void Raycaster::download(RaycastResult* result) {
  Impl& s = *impl_;
  const std::size_t pixels = s.rays->rays.size();
  s.depth.download(result->depth_m.data(), pixels, s.stream);
  s.points.download(result->points_camera.data(), pixels, s.stream);
  s.normals.download(result->normals_camera.data(), pixels, s.stream);
  s.shaded.download(result->shaded.data(), pixels, s.stream);
  SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
}

void Raycaster::synchronize() { SLS_CUDA_CHECK(cudaStreamSynchronize(impl_->stream)); }
const float* Raycaster::depth_device() const { return impl_->depth.data(); }
const Vec3f* Raycaster::points_device() const { return impl_->points.data(); }
const Vec3f* Raycaster::normals_device() const { return impl_->normals.data(); }
#endif

}  // namespace sls::fusion
