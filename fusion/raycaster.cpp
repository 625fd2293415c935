#include "fusion/raycaster.h"

#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>

#include "fusion/cuda/raycast_cuda.h"
#include "sdk/core/cuda/device_buffer.h"
#endif

namespace sls::fusion {

struct Raycaster::Impl {
  Device device;
  CameraIntrinsics camera;
  RaycastOptions options;
  RayMap rays;
#if defined(SLS_HAVE_CUDA)
  cudaStream_t stream = nullptr;
  DeviceBuffer<Vec3f> device_rays;
  DeviceBuffer<float> depth;
  DeviceBuffer<Vec3f> points, normals;
  DeviceBuffer<std::uint8_t> shaded;
  ~Impl() {
    if (stream != nullptr) (void)cudaStreamDestroy(stream);
  }
#endif

  RaycastParams params(const Volume& volume) const {
    RaycastParams p;
    p.truncation_m = static_cast<float>(options.truncation_voxels * volume.geometry().voxel_size_m);
    p.min_depth_m = static_cast<float>(options.min_depth_m);
    p.max_depth_m = static_cast<float>(options.max_depth_m);
    return p;
  }
};

Raycaster::Raycaster(const Device& device, const CameraIntrinsics& camera, const RaycastOptions& options)
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
  impl_->rays = compute_ray_map(camera, device);
#if defined(SLS_HAVE_CUDA)
  if (device.is_cuda()) {
    require_device(device);
    Impl& s = *impl_;
    const std::size_t pixels = s.rays.rays.size();
    SLS_CUDA_CHECK(cudaStreamCreateWithFlags(&s.stream, cudaStreamNonBlocking));
    s.device_rays.allocate(pixels);
    s.depth.allocate(pixels);
    s.points.allocate(pixels);
    s.normals.allocate(pixels);
    s.shaded.allocate(pixels);
    s.device_rays.upload(s.rays.rays.data(), pixels, s.stream);
    SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
  }
#endif
}

Raycaster::~Raycaster() = default;
Raycaster::Raycaster(Raycaster&&) noexcept = default;
Raycaster& Raycaster::operator=(Raycaster&&) noexcept = default;

const CameraIntrinsics& Raycaster::camera() const { return impl_->camera; }
const Device& Raycaster::device() const { return impl_->device; }

RaycastResult Raycaster::raycast(const Volume& volume, const Pose& T_world_camera) {
  Impl& s = *impl_;
  if (!(volume.device() == s.device)) {
    throw_error(ErrorCode::kInvalidArgument, "raycast: the volume lives on {}, the raycaster on {}",
                volume.device().to_string(), s.device.to_string());
  }
  const int width = s.camera.width, height = s.camera.height;
  const std::size_t pixels = s.rays.rays.size();
  RaycastResult result;
  result.depth_m = Image32f(width, height, 0.0f);
  result.shaded = Image8u(width, height, 0);
  result.points_camera.assign(pixels, Vec3f{0.0f, 0.0f, 0.0f});
  result.normals_camera.assign(pixels, Vec3f{0.0f, 0.0f, 0.0f});
  if (s.device.is_cuda()) {
#if defined(SLS_HAVE_CUDA)
    raycast_device(volume, T_world_camera);
    s.depth.download(result.depth_m.data(), pixels, s.stream);
    s.points.download(result.points_camera.data(), pixels, s.stream);
    s.normals.download(result.normals_camera.data(), pixels, s.stream);
    s.shaded.download(result.shaded.data(), pixels, s.stream);
    SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
    return result;
#endif
  }
  const VolumeView view = volume.view();
  const RaycastParams params = s.params(volume);
  const Rigid3f T_volume_camera = (volume.geometry().T_world_volume.inverse() * T_world_camera).to_rigid3f();
#if defined(_OPENMP)
#pragma omp parallel for schedule(dynamic, 4)
#endif
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t i = s.rays.index(x, y);
      const Vec3f ray = s.rays.rays[i];
      const RaycastHit hit = raycast_pixel(view, params, T_volume_camera, ray);
      result.depth_m.data()[i] = hit.depth_m;
      result.points_camera[i] = hit.point_camera;
      result.normals_camera[i] = hit.normal_camera;
      result.shaded.data()[i] = shade(hit, ray);
    }
  }
  return result;
}

#if defined(SLS_HAVE_CUDA)
void Raycaster::raycast_device(const Volume& volume, const Pose& T_world_camera) {
  Impl& s = *impl_;
  require_device(s.device);
  const Rigid3f T_volume_camera = (volume.geometry().T_world_volume.inverse() * T_world_camera).to_rigid3f();
  detail::RaycastOutputsDevice out;
  out.depth = s.depth.data();
  out.points = s.points.data();
  out.normals = s.normals.data();
  out.shaded = s.shaded.data();
  detail::launch_raycast_cuda(volume.view(), s.params(volume), T_volume_camera, s.device_rays.data(), s.camera.width,
                              s.camera.height, out, s.stream);
}

void Raycaster::synchronize() { SLS_CUDA_CHECK(cudaStreamSynchronize(impl_->stream)); }
const float* Raycaster::depth_device() const { return impl_->depth.data(); }
const Vec3f* Raycaster::points_device() const { return impl_->points.data(); }
const Vec3f* Raycaster::normals_device() const { return impl_->normals.data(); }
#endif

}  // namespace sls::fusion
