// The Tracker's CUDA path, built with CUDA only (fusion/no_cuda.cpp without it): maps read
// where they live (uploaded from the host, else in place), the device pyramids and reference
// frame, and the Gauss–Newton loop's reductions on the GPU (one copy of the sums to the host
// per step).
#include <utility>
#include <vector>

#include <cuda_runtime_api.h>

#include "fusion/cuda/track_cuda.h"
#include "fusion/tracker_internal.h"
#include "sdk/core/cuda/cuda_stream.h"
#include "sdk/core/cuda/device_buffer.h"

namespace sls::fusion {

using namespace tracking_detail;

namespace {

// `image` on the GPU: itself where it lives there, else uploaded into `upload` (made once, the
// size of the largest map it takes) on `stream`.
template <typename T>
const T* on_device(const Image<T>& image, DeviceBuffer<T>& upload, cudaStream_t stream) {
  if (image.memory_type() == MemoryType::kDevice) return image.data();
  if (upload.size() < image.pixel_count()) upload.allocate(image.pixel_count());
  upload.upload(image.data(), image.pixel_count(), stream);
  return upload.data();
}

}  // namespace

struct Tracker::Impl::Gpu {
  cudaStream_t stream = nullptr;  // gpu_stream's
  std::vector<DeviceBuffer<float>> depth;  // level 0: uploads of host maps; the coarse levels
  DeviceBuffer<float> live_upload;         // a host live map at the live camera's size
  std::vector<DeviceBuffer<float>> input_device;  // the halvings down to level 0
  // The measurement weights (options.weight_by_confidence): per level (level 0 when the input
  // is halved or uploaded), a host map's upload, the halvings down to level 0.
  std::vector<DeviceBuffer<float>> weight_device, input_weight_device;
  DeviceBuffer<float> weight_upload;
  std::vector<DeviceBuffer<Vec3f>> normals;
  DeviceBuffer<Vec3f> crease_normals_device;
  DeviceBuffer<std::uint8_t> crease_mask_device;
  DeviceBuffer<Vec3f> uploaded_points, uploaded_normals;  // host models, uploaded
  DeviceBuffer<double> partials, device_sums;
  double* host_sums = nullptr;  // pinned, kTrackSums
  // The photometric term's: the texture pyramid (level 0 when the input is halved or
  // uploaded), a host texture's upload, the halvings, the reference's pyramids, and the
  // reductions' buffers (kPhotometricSums).
  std::vector<DeviceBuffer<float>> texture_device, input_texture_device;
  DeviceBuffer<float> texture_upload;
  std::vector<DeviceBuffer<float>> reference_depth, reference_texture;
  DeviceBuffer<double> photometric_partials, photometric_sums;
  double* photometric_host_sums = nullptr;  // pinned, kPhotometricSums

  ~Gpu() {
    if (host_sums != nullptr) (void)cudaFreeHost(host_sums);
    if (photometric_host_sums != nullptr) (void)cudaFreeHost(photometric_host_sums);
  }
};

void Tracker::Impl::GpuDelete::operator()(Gpu* gpu) const { delete gpu; }

// The device buffers, made once (no allocation per frame).
void Tracker::Impl::allocate_on_device() {
  Impl& s = *this;
  s.gpu.reset(new Gpu);
  const CameraIntrinsics& live = s.live_camera;
  s.gpu->stream = cuda_stream(s.gpu_stream);
  s.gpu->depth.resize(s.levels.size());
  s.gpu->normals.resize(s.levels.size());
  for (std::size_t l = 0; l < s.levels.size(); ++l) {
    const std::size_t pixels = s.levels[l].pixels();
    s.gpu->depth[l].allocate(pixels);
    s.gpu->normals[l].allocate(pixels);
  }
  if (!s.input_cameras.empty()) {
    s.gpu->live_upload.allocate(static_cast<std::size_t>(live.width) * static_cast<std::size_t>(live.height));
    for (std::size_t k = 1; k < s.input_cameras.size(); ++k) {
      s.gpu->input_device.emplace_back(static_cast<std::size_t>(s.input_cameras[k].width) *
                                  static_cast<std::size_t>(s.input_cameras[k].height));
    }
  }
  if (s.options.weight_by_confidence) {
    for (std::size_t l = 0; l < s.levels.size(); ++l) s.gpu->weight_device.emplace_back(s.levels[l].pixels());
    s.gpu->weight_upload.allocate(static_cast<std::size_t>(live.width) *
                             static_cast<std::size_t>(live.height));
    for (std::size_t k = 1; k < s.input_cameras.size(); ++k) {
      s.gpu->input_weight_device.emplace_back(static_cast<std::size_t>(s.input_cameras[k].width) *
                                         static_cast<std::size_t>(s.input_cameras[k].height));
    }
  }
  if (s.crease_test()) {
    s.gpu->crease_normals_device.allocate(s.levels[0].pixels());
    s.gpu->crease_mask_device.allocate(s.levels[0].pixels());
  }
  s.gpu->uploaded_points.allocate(s.levels[0].pixels());
  s.gpu->uploaded_normals.allocate(s.levels[0].pixels());
  s.gpu->partials.allocate(static_cast<std::size_t>(detail::kTrackPartials));
  s.gpu->device_sums.allocate(kTrackSums);
  SLS_CUDA_CHECK(cudaMallocHost(reinterpret_cast<void**>(&s.gpu->host_sums), kTrackSums * sizeof(double)));
  if (s.photometric_on) {
    for (std::size_t l = 0; l < s.levels.size(); ++l) {
      s.gpu->texture_device.emplace_back(s.levels[l].pixels());
      s.gpu->reference_depth.emplace_back(s.levels[l].pixels());
      s.gpu->reference_texture.emplace_back(s.levels[l].pixels());
    }
    s.gpu->texture_upload.allocate(static_cast<std::size_t>(live.width) *
                              static_cast<std::size_t>(live.height));
    for (std::size_t k = 1; k < s.input_cameras.size(); ++k) {
      s.gpu->input_texture_device.emplace_back(static_cast<std::size_t>(s.input_cameras[k].width) *
                                          static_cast<std::size_t>(s.input_cameras[k].height));
    }
    s.gpu->photometric_partials.allocate(static_cast<std::size_t>(detail::kTrackMaxBlocks) * kPhotometricSums);
    s.gpu->photometric_sums.allocate(kPhotometricSums);
    SLS_CUDA_CHECK(cudaMallocHost(reinterpret_cast<void**>(&s.gpu->photometric_host_sums),
                                  kPhotometricSums * sizeof(double)));
  }
  SLS_CUDA_CHECK(cudaStreamSynchronize(s.gpu->stream));
}

TrackingResult Tracker::Impl::track_gpu(const Image32f& depth_m, const Image<Vec3f>& model_points,
                                        const Image<Vec3f>& model_normals, const Pose& T_world_model,
                                        const Pose& guess, const Image32f* live_texture, const Image32f* live_weight) {
  require_device(device);
  // A host live map goes where the pyramid starts: level 0 when ICP runs at the live size.
  const float* live = on_device(depth_m, input_cameras.empty() ? gpu->depth[0] : gpu->live_upload, gpu->stream);
  const Vec3f* points = on_device(model_points, gpu->uploaded_points, gpu->stream);
  const Vec3f* point_normals = on_device(model_normals, gpu->uploaded_normals, gpu->stream);
  const float* texture_in = live_texture != nullptr ? on_device(*live_texture, gpu->texture_upload, gpu->stream) : nullptr;
  const float* weight_in = live_weight != nullptr ? on_device(*live_weight, gpu->weight_upload, gpu->stream) : nullptr;
  return track_on_device(live, points, point_normals, T_world_model, guess, texture_in, weight_in);
}

void Tracker::Impl::set_reference_gpu(const Image32f& depth_m, const Image32f& reference_texture_in,
                                      const Pose& T_world_camera) {
  require_device(device);
  const float* depth_in = on_device(depth_m, input_cameras.empty() ? gpu->depth[0] : gpu->live_upload, gpu->stream);
  set_reference_on_device(depth_in, on_device(reference_texture_in, gpu->texture_upload, gpu->stream), T_world_camera);
}

void Tracker::Impl::depth_pyramid_device(const float* depth_device, const float* weight_in,
                                         const float* level_depth[8], const float* level_weight[8],
                                         bool with_normals) {
  Impl& s = *this;
  // The live map (and its weights) halved down to ICP's finest level (into level 0's buffer),
  // then the pyramid and normals, on the device.
  const bool weighted = weight_in != nullptr;
  for (std::size_t k = 0; k < s.input_cameras.size(); ++k) {
    const CameraIntrinsics& fine = s.input_cameras[k];
    const CameraIntrinsics& coarse = k + 1 < s.input_cameras.size() ? s.input_cameras[k + 1] : s.camera;
    const bool last = k + 1 == s.input_cameras.size();
    float* coarse_depth = last ? s.gpu->depth[0].data() : s.gpu->input_device[k].data();
    float* coarse_weight = !weighted ? nullptr : (last ? s.gpu->weight_device[0].data() : s.gpu->input_weight_device[k].data());
    detail::launch_downsample_depth_cuda(depth_device, weight_in, fine.width, fine.height, static_cast<float>(fine.fx),
                                         coarse_depth, coarse_weight, coarse.width, coarse.height, s.gpu->stream);
    depth_device = coarse_depth;
    weight_in = coarse_weight;
  }
  level_depth[0] = depth_device;
  level_weight[0] = weight_in;
  for (std::size_t l = 0; l < s.levels.size(); ++l) {
    const Level& level = s.levels[l];
    if (l > 0) {
      const Level& fine = s.levels[l - 1];
      float* coarse_weight = weighted ? s.gpu->weight_device[l].data() : nullptr;
      detail::launch_downsample_depth_cuda(level_depth[l - 1], level_weight[l - 1], fine.camera.width,
                                           fine.camera.height, static_cast<float>(fine.camera.fx), s.gpu->depth[l].data(),
                                           coarse_weight, level.camera.width, level.camera.height, s.gpu->stream);
      level_depth[l] = s.gpu->depth[l].data();
      level_weight[l] = coarse_weight;
    }
    if (!with_normals) continue;
    detail::launch_live_normals_cuda(level_depth[l], s.levels[static_cast<std::size_t>(l)].shared_rays->rays_device, level.camera.width, level.camera.height,
                                     static_cast<float>(level.camera.fx),
                                     static_cast<float>(s.options.normal_baseline_m), s.gpu->normals[l].data(), s.gpu->stream);
  }
}

void Tracker::Impl::texture_pyramid_device(const float* texture_in, const float* level_texture[8]) {
  for (std::size_t k = 0; k < input_cameras.size(); ++k) {
    const CameraIntrinsics& fine = input_cameras[k];
    const CameraIntrinsics& coarse = k + 1 < input_cameras.size() ? input_cameras[k + 1] : camera;
    float* out = k + 1 < input_cameras.size() ? gpu->input_texture_device[k].data() : gpu->texture_device[0].data();
    detail::launch_downsample_texture_cuda(texture_in, fine.width, fine.height, out, coarse.width, coarse.height,
                                           gpu->stream);
    texture_in = out;
  }
  level_texture[0] = texture_in;
  for (std::size_t l = 1; l < levels.size(); ++l) {
    const CameraIntrinsics& fine = levels[l - 1].camera;
    detail::launch_downsample_texture_cuda(level_texture[l - 1], fine.width, fine.height, gpu->texture_device[l].data(),
                                           levels[l].camera.width, levels[l].camera.height, gpu->stream);
    level_texture[l] = gpu->texture_device[l].data();
  }
}

double Tracker::Impl::texture_mean_device(const float* texture0, const float* depth0) {
  detail::launch_texture_statistics_cuda(texture0, depth0, camera.width * camera.height, gpu->photometric_partials.data(),
                                         gpu->photometric_sums.data(), gpu->stream);
  SLS_CUDA_CHECK(cudaMemcpyAsync(gpu->photometric_host_sums, gpu->photometric_sums.data(), kTextureSums * sizeof(double),
                                 cudaMemcpyDeviceToHost, gpu->stream));
  SLS_CUDA_CHECK(cudaStreamSynchronize(gpu->stream));
  return gpu->photometric_host_sums[1] > 0.0 ? gpu->photometric_host_sums[0] / gpu->photometric_host_sums[1] : 0.0;
}

void Tracker::Impl::keep_reference_device(const float* const level_depth[8], const float* const level_texture[8],
                                          double mean, const Pose& T_world_camera) {
  for (std::size_t l = 0; l < levels.size(); ++l) {
    const std::size_t bytes = levels[l].pixels() * sizeof(float);
    SLS_CUDA_CHECK(cudaMemcpyAsync(gpu->reference_depth[l].data(), level_depth[l], bytes, cudaMemcpyDeviceToDevice, gpu->stream));
    SLS_CUDA_CHECK(
        cudaMemcpyAsync(gpu->reference_texture[l].data(), level_texture[l], bytes, cudaMemcpyDeviceToDevice, gpu->stream));
  }
  // The inputs are the caller's (the decoder's next frame may overwrite them): copied now.
  SLS_CUDA_CHECK(cudaStreamSynchronize(gpu->stream));
  reference_frame.mean = mean;
  reference_frame.T_world_camera = T_world_camera;
  reference_frame.valid = true;
}

void Tracker::Impl::set_reference_on_device(const float* depth_device, const float* texture_in,
                                            const Pose& T_world_camera) {
  const float* level_depth[8] = {};
  const float* level_weight[8] = {};
  const float* level_texture[8] = {};
  depth_pyramid_device(depth_device, nullptr, level_depth, level_weight, false);
  texture_pyramid_device(texture_in, level_texture);
  const double mean = texture_mean_device(level_texture[0], level_depth[0]);
  if (!(mean > 0.0) || !std::isfinite(mean)) {
    reference_frame.valid = false;
    return;
  }
  keep_reference_device(level_depth, level_texture, mean, T_world_camera);
}

TrackingResult Tracker::Impl::track_on_device(const float* depth_device, const Vec3f* model_points,
                                              const Vec3f* model_normals, const Pose& T_world_model,
                                              const Pose& T_world_camera_guess, const float* texture_in,
                                              const float* weight_in) {
  Impl& s = *this;
  const int width = s.camera.width, height = s.camera.height;
  const int pixels = width * height;
  const float* level_depth[8] = {};  // validate(): at most 8 levels
  const float* level_weight[8] = {};
  s.depth_pyramid_device(depth_device, weight_in, level_depth, level_weight, true);
  depth_device = level_depth[0];
  auto download = [&](int count) {
    SLS_CUDA_CHECK(cudaMemcpyAsync(s.gpu->host_sums, s.gpu->device_sums.data(), static_cast<std::size_t>(count) * sizeof(double),
                                   cudaMemcpyDeviceToHost, s.gpu->stream));
    SLS_CUDA_CHECK(cudaStreamSynchronize(s.gpu->stream));
  };
  const TrackRegion region = s.region(T_world_camera_guess);
  auto statistics = [&](Vec3f reference) {
    detail::launch_frame_statistics_cuda(model_points, depth_device, s.levels[0].shared_rays->rays_device, region, pixels, reference,
                                         s.gpu->partials.data(), s.gpu->device_sums.data(), s.gpu->stream);
    download(kFrameSums);
    FrameSums sums{};
    std::copy(s.gpu->host_sums, s.gpu->host_sums + kFrameSums, sums.begin());
    return sums;
  };
  const Frame frame = s.frame_from_statistics(statistics);

  TrackModelView model_view = s.model_view(model_points, model_normals);
  if (s.crease_test()) {
    detail::launch_model_creases_cuda(model_points, width, height, static_cast<float>(s.camera.fx),
                                      static_cast<float>(s.options.normal_baseline_m),
                                      static_cast<float>(s.options.crease_radius_m), s.crease_min_cos(),
                                      s.gpu->crease_normals_device.data(), s.gpu->crease_mask_device.data(), s.gpu->stream);
    model_view.creases = s.gpu->crease_mask_device.data();
  }
  auto reduce = [&](int l, const TrackParams& params) {
    const Level& level = s.levels[static_cast<std::size_t>(l)];
    TrackLiveView live;
    live.depth = level_depth[l];
    live.rays = s.levels[static_cast<std::size_t>(l)].shared_rays->rays_device;
    live.normals = s.gpu->normals[static_cast<std::size_t>(l)].data();
    live.weights = level_weight[l];
    live.width = level.camera.width;
    live.height = level.camera.height;
    detail::launch_track_cuda(live, model_view, params, s.gpu->partials.data(), s.gpu->device_sums.data(), s.gpu->stream);
    download(kTrackSums);
    Sums sums{};
    std::copy(s.gpu->host_sums, s.gpu->host_sums + kTrackSums, sums.begin());
    return sums;
  };

  const float* level_texture[8] = {};
  double live_mean = 0.0;
  if (texture_in != nullptr) {
    s.texture_pyramid_device(texture_in, level_texture);
    live_mean = s.texture_mean_device(level_texture[0], level_depth[0]);
  }
  std::string skipped;
  const std::optional<PhotometricSetup> setup =
      s.photometric_setup(texture_in != nullptr, live_mean, T_world_model, &skipped);
  Impl::ReducePhotometric reduce_photometric;
  if (setup) {
    reduce_photometric = [&](int l, const PhotometricParams& params) {
      const std::size_t level = static_cast<std::size_t>(l);
      PhotometricLevelView ref, live;
      ref.texture = s.gpu->reference_texture[level].data();
      ref.depth = s.gpu->reference_depth[level].data();
      ref.rays = s.levels[level].shared_rays->rays_device;
      ref.width = live.width = s.levels[level].camera.width;
      ref.height = live.height = s.levels[level].camera.height;
      live.texture = level_texture[l];
      live.depth = level_depth[l];
      live.rays = ref.rays;
      detail::launch_photometric_cuda(ref, live, params, s.gpu->photometric_partials.data(), s.gpu->photometric_sums.data(),
                                      s.gpu->stream);
      SLS_CUDA_CHECK(cudaMemcpyAsync(s.gpu->photometric_host_sums, s.gpu->photometric_sums.data(),
                                     kPhotometricSums * sizeof(double), cudaMemcpyDeviceToHost, s.gpu->stream));
      SLS_CUDA_CHECK(cudaStreamSynchronize(s.gpu->stream));
      PhotometricSums sums{};
      std::copy(s.gpu->photometric_host_sums, s.gpu->photometric_host_sums + kPhotometricSums, sums.begin());
      return sums;
    };
  }
  TrackingResult result = s.run(frame, T_world_model, T_world_camera_guess, reduce, setup ? &*setup : nullptr,
                                reduce_photometric);
  if (!skipped.empty()) result.photometric_skipped = skipped;
  if (texture_in != nullptr && live_mean > 0.0 && std::isfinite(live_mean) && !result.lost) {
    s.keep_reference_device(level_depth, level_texture, live_mean, result.T_world_camera);
  }
  return result;
}

}  // namespace sls::fusion
