#include "fusion/integrator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <tuple>
#include <utility>
#include <vector>

#include "fusion/integrator_gpu.h"
#include "fusion/integrator_internal.h"
#include "sdk/core/error.h"
#include "sdk/core/parallel_for.h"

namespace sls::fusion {

IntegrationOptions IntegrationOptions::tsdf() {
  IntegrationOptions o;
  o.lambda = 0.0;
  return o;
}

IntegrationOptions IntegrationOptions::gtsdf() {
  IntegrationOptions o;
  // Chosen on full simulated revolutions (tests/bench/bench_fusion_conditions, docs/benchmarks.md
  // "GTSDF against TSDF, and under which conditions"): over λ 1..16, κ 0.01..0.3 and the three
  // φ, κ = 0.03 gave the lowest edge C2C of the GTSDF settings in all eight object × condition
  // cells (exact, tracked, estimated calibration, projector gamma) and the lowest C2C in seven,
  // within 2 % of TSDF's or below it. The
  // earlier κ = 0.1, picked on a few very noisy views of a ridge (tests/unit/fusion), smooths
  // more there but rounds a revolution's ~100 agreeing views.
  o.lambda = 4.0;
  o.beta = 1.0 / 6.0;
  o.kappa = 0.03;
  o.penalty = Penalty::kGemanMcClure;
  o.iterations = 3;
  return o;
}

void IntegrationOptions::validate(VoxelFormat format) const {
  if (!(truncation_voxels > 0.0) || !std::isfinite(truncation_voxels)) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: truncation {} voxels is not positive", truncation_voxels);
  }
  if (!(eta_voxels > truncation_voxels) || !std::isfinite(eta_voxels)) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: eta {} voxels must exceed the truncation {} voxels", eta_voxels,
                truncation_voxels);
  }
  const int cap = format == VoxelFormat::kCompact ? 255 : 1 << 24;
  if (weight_max < 1 || weight_max > cap) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: weight cap {} outside 1..{} for {} voxels", weight_max, cap,
                voxel_format_name(format));
  }
  if (!(lambda >= 0.0) || !std::isfinite(lambda)) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: lambda {} is negative or not finite", lambda);
  }
  if (!(beta > 0.0 && beta <= 1.0 / 6.0 + 1e-12)) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: beta {} outside (0, 1/6]", beta);
  }
  if (!(kappa > 0.0) || !std::isfinite(kappa)) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: kappa {} is not positive", kappa);
  }
  if (iterations < 0 || iterations > 100) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: {} iterations outside 0..100", iterations);
  }
}

IntegrationParams IntegrationOptions::params(double voxel_size_m) const {
  IntegrationParams p;
  p.truncation_m = static_cast<float>(truncation_voxels * voxel_size_m);
  p.inverse_truncation_m = 1.0f / p.truncation_m;
  p.eta_m = static_cast<float>(eta_voxels * voxel_size_m);
  p.weight_max = static_cast<float>(weight_max);
  p.alpha = is_gtsdf() ? static_cast<float>(lambda * beta) : 0.0f;
  p.kappa = static_cast<float>(kappa);
  p.penalty = penalty;
  return p;
}

IntegrationOptions parse_fusion_method(const std::string& name) {
  if (name == "tsdf") return IntegrationOptions::tsdf();
  if (name == "gtsdf") return IntegrationOptions::gtsdf();
  throw_error(ErrorCode::kInvalidArgument, "unknown fusion method '{}' (tsdf or gtsdf)", name);
}

Penalty parse_penalty(const std::string& name) {
  if (name == "perona-malik") return Penalty::kPeronaMalik;
  if (name == "charbonnier") return Penalty::kCharbonnier;
  if (name == "geman-mcclure") return Penalty::kGemanMcClure;
  throw_error(ErrorCode::kInvalidArgument, "unknown penalty '{}' (perona-malik, charbonnier, geman-mcclure)", name);
}

const char* penalty_name(Penalty penalty) {
  switch (penalty) {
    case Penalty::kCharbonnier:
      return "charbonnier";
    case Penalty::kGemanMcClure:
      return "geman-mcclure";
    case Penalty::kPeronaMalik:
    default:
      return "perona-malik";
  }
}

DepthFrameView make_depth_frame_view(const float* depth_m, const CameraIntrinsics& camera, const Pose& T_world_camera,
                                     const VolumeGeometry& geometry) {
  DepthFrameView frame;
  frame.depth_m = depth_m;
  frame.width = camera.width;
  frame.height = camera.height;
  frame.intrinsics = camera.cast<float>();
  frame.T_camera_volume = (T_world_camera.inverse() * geometry.T_world_volume).to_rigid3f();
  return frame;
}

VoxelBox frustum_voxel_box(const VolumeGeometry& geometry, const CameraIntrinsics& camera, const Pose& T_world_camera,
                           double near_m, double far_m) {
  VoxelBox box;
  box.i1 = geometry.nx;
  box.j1 = geometry.ny;
  box.k1 = geometry.nz;
  if (!std::isfinite(far_m) || !(near_m > 0.0) || !(far_m >= near_m)) return box;  // unknown range: all
  // The image border, densely (distortion bends its edges), at the near and far depths.
  const Pose T_volume_camera = geometry.T_world_volume.inverse() * T_world_camera;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  constexpr int kSteps = 16;
  for (int n = 0; n <= 4 * kSteps; ++n) {
    const int side = n / (kSteps + 1), step = n % (kSteps + 1);
    const double t = static_cast<double>(step) / kSteps;
    const double w = camera.width - 0.5, h = camera.height - 0.5;
    const Vec2d pixel = side == 0   ? Vec2d{-0.5 + t * w, -0.5}
                        : side == 1 ? Vec2d{w, -0.5 + t * h}
                        : side == 2 ? Vec2d{w - t * w, h}
                                    : Vec2d{-0.5, h - t * h};
    Vec3d ray;
    if (!unproject(camera, pixel, &ray)) return box;  // outside the calibrated field: no culling
    for (const double z : {near_m, far_m}) {
      const Eigen::Vector3d p = T_volume_camera * Eigen::Vector3d(ray.x * z, ray.y * z, z);
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  }
  // The camera centre too when the near depth is small; then voxel indices with a voxel of margin.
  const double s = geometry.voxel_size_m;
  auto first = [&](double coordinate, int n) { return std::clamp(static_cast<int>(std::floor(coordinate / s - 0.5)) - 1, 0, n); };
  auto last = [&](double coordinate, int n) { return std::clamp(static_cast<int>(std::ceil(coordinate / s - 0.5)) + 2, 0, n); };
  box.i0 = first(lo.x(), geometry.nx);
  box.j0 = first(lo.y(), geometry.ny);
  box.k0 = first(lo.z(), geometry.nz);
  box.i1 = last(hi.x(), geometry.nx);
  box.j1 = last(hi.y(), geometry.ny);
  box.k1 = last(hi.z(), geometry.nz);
  return box;
}

std::pair<double, double> integration_depth_band(const Image32f& depth_m) {
  std::vector<float> sample;
  sample.reserve(depth_m.pixel_count() / kDepthBandStride + 1);
  const float* data = depth_m.data();
  for (std::size_t i = 0; i < depth_m.pixel_count(); i += kDepthBandStride) {
    if (data[i] > 0.0f && std::isfinite(data[i])) sample.push_back(data[i]);
  }
  return detail::band_of_sample(sample, [&] {
    // Too few samples for quantiles: the whole measured range.
    float lo = std::numeric_limits<float>::infinity(), hi = 0.0f;
    for (std::size_t i = 0; i < depth_m.pixel_count(); ++i) {
      if (!(data[i] > 0.0f) || !std::isfinite(data[i])) continue;
      lo = std::min(lo, data[i]);
      hi = std::max(hi, data[i]);
    }
    return std::pair<float, float>(lo, hi);
  });
}

VoxelBox detail::band_box(const VolumeGeometry& geometry, const CameraIntrinsics& camera, const Pose& T_world_camera,
                          double min_depth_m, double max_depth_m, const IntegrationOptions& options) {
  if (max_depth_m <= 0.0) return VoxelBox{};  // an empty depth map
  const double eta = options.eta_voxels * geometry.voxel_size_m;
  return frustum_voxel_box(geometry, camera, T_world_camera, std::max(1e-6, min_depth_m - eta), max_depth_m + eta);
}

struct Integrator::Impl {
  Device device;
  IntegrationOptions options;
  // CPU: the active voxels of each parity.
  std::vector<ActiveVoxel> active[2];
  GpuStream gpu_stream;                     // the session's, or its own (CUDA)
  std::unique_ptr<detail::IntegratorGpu> gpu;  // on a GPU: its buffers and launches
};

Integrator::Integrator(const Device& device, const IntegrationOptions& options, const GpuStream& stream)
    : impl_(std::make_unique<Impl>()) {
  options.validate(VoxelFormat::kFloat32);
  impl_->device = device;
  impl_->options = options;
  if (device.is_cuda()) {
    impl_->gpu_stream = GpuStream::or_create(stream, device);
    impl_->gpu = std::make_unique<detail::IntegratorGpu>(device, impl_->gpu_stream);
  }
}

Integrator::~Integrator() = default;
Integrator::Integrator(Integrator&&) noexcept = default;
Integrator& Integrator::operator=(Integrator&&) noexcept = default;

const IntegrationOptions& Integrator::options() const { return impl_->options; }
const Device& Integrator::device() const { return impl_->device; }

std::size_t detail::active_capacity(const IntegrationOptions& options, std::size_t voxel_count) {
  if (options.active_capacity > 0) return options.active_capacity;
  return std::min<std::size_t>(voxel_count, std::size_t{1} << 25);
}

std::size_t integration_gpu_bytes(const IntegrationOptions& options, std::size_t voxel_count) {
  if (!options.is_gtsdf()) return 0;
  return 4 * detail::active_capacity(options, voxel_count) * sizeof(ActiveVoxel);
}

namespace {

void check_inputs(const Volume& volume, const Device& device, int width, int height, const CameraIntrinsics& camera,
                  const IntegrationOptions& options) {
  if (!(volume.device() == device)) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: the volume lives on {}, the integrator on {}",
                volume.device().to_string(), device.to_string());
  }
  if (width != camera.width || height != camera.height) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: depth map is {}x{}, the camera is {}x{}", width, height,
                camera.width, camera.height);
  }
  options.validate(volume.format());
  // Without its own A, GTSDF would feed its smoothed U back into the running average, and the
  // smoothing would pile up over a voxel's ~100 observations (fusion/README.md).
  if (options.is_gtsdf() && volume.average_storage() != AverageStorage::kSeparate) {
    throw_error(ErrorCode::kInvalidArgument,
                "fusion: GTSDF needs a volume that keeps the running average apart from U "
                "(Volume(..., IntegrationOptions::average_storage()))");
  }
}

// The CPU integrator: the running average over every voxel (rows of the volume in
// parallel), then the red-black sweeps over the active voxels.
IntegrationStats integrate_cpu(const VolumeView& view, const IntegrationParams& params, const DepthFrameView& frame,
                               const VoxelBox& box, int iterations, std::size_t capacity,
                               std::vector<ActiveVoxel> (&active)[2]) {
  active[0].clear();
  active[1].clear();
  const bool collect = params.alpha > 0.0f && iterations > 0;
  std::size_t total_active = 0;
#if defined(_OPENMP)
#pragma omp parallel
#endif
  {
    std::vector<ActiveVoxel> local[2];
    std::size_t local_count = 0;
#if defined(_OPENMP)
#pragma omp for schedule(dynamic, 1)
#endif
    for (int k = box.k0; k < box.k1; ++k) {
      for (int j = box.j0; j < box.j1; ++j) {
        for (int i = box.i0; i < box.i1; ++i) {
          float average = 0.0f;
          if (!integrate_voxel(view, params, frame, i, j, k, &average) || !collect) continue;
          ++local_count;
          local[voxel_parity(i, j, k)].push_back(ActiveVoxel{static_cast<std::uint32_t>(view.index(i, j, k)), average});
        }
      }
    }
#if defined(_OPENMP)
#pragma omp critical
#endif
    {
      total_active += local_count;
      for (int parity = 0; parity < 2; ++parity) {
        active[parity].insert(active[parity].end(), local[parity].begin(), local[parity].end());
      }
    }
  }
  IntegrationStats stats;
  stats.active_voxels = total_active;
  stats.voxels_visited = box.count();
  for (int parity = 0; parity < 2; ++parity) {
    if (active[parity].size() > capacity) {
      stats.overflow += active[parity].size() - capacity;
      active[parity].resize(capacity);
    }
  }
  if (!collect) return stats;
  for (int t = 0; t < iterations; ++t) {
    for (int parity = 0; parity < 2; ++parity) {
      const ActiveVoxel* list = active[parity].data();
      parallel_for(Device::cpu(), active[parity].size(),
                   SLS_LAMBDA(std::size_t n) { relax_active_voxel(view, params, list, n); });
    }
  }
  return stats;
}

}  // namespace

IntegrationStats Integrator::integrate(Volume& volume, const Image32f& depth_m, const CameraIntrinsics& camera,
                                       const Pose& T_world_camera, std::optional<DepthBand> band) {
  Impl& s = *impl_;
  check_inputs(volume, s.device, depth_m.width(), depth_m.height(), camera, s.options);
  const bool on_device = depth_m.memory_type() == MemoryType::kDevice;
  if (!s.device.is_cuda()) {
    if (on_device) {
      throw_error(ErrorCode::kInvalidArgument, "fusion: the depth map lives on a GPU, the integrator on the CPU");
    }
    if (!band) {
      const auto [near_m, far_m] = integration_depth_band(depth_m);
      band = DepthBand{near_m, far_m};
    }
    const VolumeView view = volume.view();
    const DepthFrameView frame = make_depth_frame_view(depth_m.data(), camera, T_world_camera, volume.geometry());
    const VoxelBox box =
        detail::band_box(volume.geometry(), camera, T_world_camera, band->near_m, band->far_m, s.options);
    return integrate_cpu(view, s.options.params(volume.geometry().voxel_size_m), frame, box, s.options.iterations,
                         detail::active_capacity(s.options, volume.geometry().voxel_count()), s.active);
  }
  if (!band && on_device) {
    const DepthMapSummary summary = s.gpu->summarize(depth_m.data(), depth_m.pixel_count());
    band = DepthBand{summary.near_m, summary.far_m};
  } else if (!band) {
    const auto [near_m, far_m] = integration_depth_band(depth_m);
    band = DepthBand{near_m, far_m};
  }
  if (!(band->far_m > 0.0)) return IntegrationStats{};  // nothing measured
  return s.gpu->integrate(volume, s.gpu->on_device(depth_m), camera, T_world_camera, *band, s.options);
}

DepthMapSummary Integrator::summarize(const Image32f& depth_m) {
  Impl& s = *impl_;
  if (depth_m.memory_type() != MemoryType::kDevice) {
    DepthMapSummary summary;
    const float* z = depth_m.data();
    for (std::size_t i = 0; i < depth_m.pixel_count(); ++i) summary.valid_pixels += z[i] > 0.0f && std::isfinite(z[i]);
    std::tie(summary.near_m, summary.far_m) = integration_depth_band(depth_m);
    return summary;
  }
  if (!s.device.is_cuda()) {
    throw_error(ErrorCode::kInvalidArgument, "fusion: the depth map lives on a GPU, the integrator on the CPU");
  }
  return s.gpu->summarize(depth_m.data(), depth_m.pixel_count());
}

}  // namespace sls::fusion
