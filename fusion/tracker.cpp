#include "fusion/tracker.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "fusion/track_shared.h"
#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"

#if defined(_OPENMP)
#include <omp.h>
#endif

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>

#include "fusion/cuda/track_cuda.h"
#include "sdk/core/cuda/device_buffer.h"
#endif

namespace sls::fusion {

void TrackingOptions::validate() const {
  if (iterations.empty() || iterations.size() > 8) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: {} pyramid levels (iterations) outside 1..8",
                iterations.size());
  }
  for (std::size_t level = 0; level < iterations.size(); ++level) {
    if (iterations[level] < 0 || iterations[level] > 100) {
      throw_error(ErrorCode::kInvalidArgument, "tracking: {} iterations at level {} outside 0..100", iterations[level],
                  level);
    }
  }
  if (iterations[0] < 1) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: the finest level needs at least one iteration, not {}",
                iterations[0]);
  }
  auto positive = [](double value) { return value > 0.0 && std::isfinite(value); };
  if (!positive(max_distance_m)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: max_distance_m {} is not positive", max_distance_m);
  }
  if (!(huber_rms_factor >= 0.0) || !std::isfinite(huber_rms_factor)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: huber_rms_factor {} must be 0 or positive", huber_rms_factor);
  }
  if (max_model_width < 16) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: max_model_width {} (at least 16 pixels)", max_model_width);
  }
  if (!(normal_baseline_m > 0.0) || !std::isfinite(normal_baseline_m)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: normal_baseline_m {} must be positive", normal_baseline_m);
  }
  if (!(max_normal_angle_deg > 0.0 && max_normal_angle_deg <= 180.0)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: max_normal_angle_deg {} outside (0, 180]",
                max_normal_angle_deg);
  }
  if (!(min_translation_step_m >= 0.0) || !std::isfinite(min_translation_step_m) || !(min_rotation_step_rad >= 0.0) ||
      !std::isfinite(min_rotation_step_rad)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: minimum steps {} m, {} rad must be non-negative",
                min_translation_step_m, min_rotation_step_rad);
  }
  if (!(degenerate_eigen_ratio >= 0.0 && degenerate_eigen_ratio < 1.0)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: degenerate_eigen_ratio {} outside [0, 1)",
                degenerate_eigen_ratio);
  }
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: min_inlier_fraction {} outside [0, 1]", min_inlier_fraction);
  }
  if (!positive(max_residual_rms_m)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: max_residual_rms_m {} is not positive", max_residual_rms_m);
  }
  if (!positive(max_correction_m) || !positive(max_correction_deg)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: max_correction {} m / {} deg must be positive",
                max_correction_m, max_correction_deg);
  }
}

namespace {

using Sums = std::array<double, kTrackSums>;
using FrameSums = std::array<double, kFrameSums>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// One level of the live pyramid: its camera and ray map (host), and on the CPU its depth and
// normals (level 0's depth is the caller's).
struct Level {
  CameraIntrinsics camera;
  RayMap rays;
  std::vector<float> depth;
  std::vector<Vec3f> normals;
  std::size_t pixels() const {
    return static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height);
  }
};

// Level l + 1's camera from level l's: half the focal length, the 2x2 block's centre.
CameraIntrinsics half_camera(const CameraIntrinsics& c) {
  CameraIntrinsics out = c;
  out.width = c.width / 2;
  out.height = c.height / 2;
  out.fx = 0.5 * c.fx;
  out.fy = 0.5 * c.fy;
  out.cx = 0.5 * (c.cx - 0.5);
  out.cy = 0.5 * (c.cy - 0.5);
  return out;
}

// The centre c and scale L of the parameterisation (track_shared.h) from the frame sums.
struct Frame {
  std::size_t live_pixels = 0;
  std::size_t model_points = 0;
  Vec3f centre{0.0f, 0.0f, 0.0f};
  double scale = 1.0;
};

// The solved step of one Gauss–Newton iteration.
struct Step {
  Vector6d twist = Vector6d::Zero();  // [ρ, ω'] of track_shared.h
  int degenerate = 0;
  double condition = 0.0;
};

Step solve(const Sums& sums, double degenerate_ratio) {
  Matrix6d a;
  Vector6d b;
  int k = 0;
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c) {
      a(r, c) = sums[static_cast<std::size_t>(k)];
      a(c, r) = sums[static_cast<std::size_t>(k)];
      ++k;
    }
    b(r) = sums[static_cast<std::size_t>(kTrackJtr + r)];
  }
  Step step;
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(a);
  const Vector6d& values = eigen.eigenvalues();  // ascending
  const double largest = values(5), smallest = values(0);
  step.condition = smallest > 0.0 ? largest / smallest : std::numeric_limits<double>::infinity();
  if (!(largest > 0.0)) {
    step.degenerate = 6;
    return step;
  }
  // x = −A⁺b over the constrained eigen-directions; the degenerate ones get no update.
  for (int i = 0; i < 6; ++i) {
    if (!(values(i) >= degenerate_ratio * largest) || !(values(i) > 0.0)) {
      ++step.degenerate;
      continue;
    }
    const Vector6d v = eigen.eigenvectors().col(i);
    step.twist -= v * (v.dot(b) / values(i));
  }
  return step;
}

// δT = Tr(c) · exp([ρ, ω'/L]) · Tr(−c) (track_shared.h).
Pose step_pose(const Vector6d& twist, const Frame& frame) {
  Vector6d scaled = twist;
  scaled.tail<3>() /= frame.scale;
  const Eigen::Vector3d c(frame.centre.x, frame.centre.y, frame.centre.z);
  return Pose(Eigen::Quaterniond::Identity(), c) * Pose::exp(scaled) * Pose(Eigen::Quaterniond::Identity(), -c);
}

std::string percent(double fraction) { return fmt::format("{:.1f} %", 100.0 * fraction); }

// A depth map at `fine`'s size halved into `coarse`'s (downsample_depth per coarse pixel; the
// CPU side of launch_downsample_depth_cuda).
void halve_depth(const float* fine_depth, const CameraIntrinsics& fine, float* coarse_depth,
                 const CameraIntrinsics& coarse) {
  const float fine_fx = static_cast<float>(fine.fx);
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < coarse.height; ++y) {
    for (int x = 0; x < coarse.width; ++x) {
      coarse_depth[static_cast<std::size_t>(y) * static_cast<std::size_t>(coarse.width) + static_cast<std::size_t>(x)] =
          downsample_depth(fine_depth, fine.width, fine.height, fine_fx, x, y);
    }
  }
}

}  // namespace

struct Tracker::Impl {
  Device device;
  CameraIntrinsics live_camera;  // the live depth maps' camera
  CameraIntrinsics camera;       // ICP's finest level, the model maps' camera
  TrackingOptions options;
  // The live camera halved down to `camera` (empty when they are the same), and the host
  // buffers of those halvings (the last is ICP's finest live depth).
  std::vector<CameraIntrinsics> input_cameras;
  std::vector<std::vector<float>> input_depth;
  std::vector<Level> levels;
#if defined(SLS_HAVE_CUDA)
  cudaStream_t stream = nullptr;
  std::vector<DeviceBuffer<float>> depth;  // level 0: uploads of host maps; the coarse levels
  DeviceBuffer<float> live_upload;         // a host live map at the live camera's size
  std::vector<DeviceBuffer<float>> input_device;  // the halvings down to level 0
  std::vector<DeviceBuffer<Vec3f>> rays, normals;
  DeviceBuffer<Vec3f> uploaded_points, uploaded_normals;  // host models, uploaded
  DeviceBuffer<double> partials, device_sums;
  double* host_sums = nullptr;  // pinned, kTrackSums
  // The pyramid, normals, frame statistics and Gauss–Newton steps on the device: one
  // device-to-host copy of the sums per step, no allocation.
  TrackingResult track_on_device(const float* depth_device, const Vec3f* model_points, const Vec3f* model_normals,
                                 const Pose& T_world_model, const Pose& T_world_camera_guess);
  ~Impl() {
    if (host_sums != nullptr) (void)cudaFreeHost(host_sums);
    if (stream != nullptr) (void)cudaStreamDestroy(stream);
  }
#endif

  // The Gauss–Newton loop over the levels, coarse to fine, and the lost-frame tests; `reduce`
  // (level, params) returns the level's sums for one estimate.
  template <typename Reduce>
  TrackingResult run(const Frame& frame, const Pose& T_world_model, const Pose& guess, Reduce&& reduce) const;
  Frame frame_from_sums(const FrameSums& first, const FrameSums& second, Vec3f reference) const;
  // Two passes of `statistics(reference)`: about the origin for the centroid, then about it.
  template <typename Statistics>
  Frame frame_from_statistics(Statistics&& statistics) const {
    const FrameSums first = statistics(Vec3f{0.0f, 0.0f, 0.0f});
    Vec3f centre{0.0f, 0.0f, 0.0f};
    if (first[0] > 0.0) {
      centre = Vec3f{static_cast<float>(first[1] / first[0]), static_cast<float>(first[2] / first[0]),
                     static_cast<float>(first[3] / first[0])};
    }
    return frame_from_sums(first, statistics(centre), centre);
  }
  TrackModelView model_view(const Vec3f* points, const Vec3f* point_normals) const {
    TrackModelView view;
    view.points = points;
    view.normals = point_normals;
    view.camera = camera.cast<float>();
    return view;
  }
};

Frame Tracker::Impl::frame_from_sums(const FrameSums& first, const FrameSums& second, Vec3f reference) const {
  Frame frame;
  frame.live_pixels = static_cast<std::size_t>(std::llround(first[5]));
  frame.model_points = static_cast<std::size_t>(std::llround(first[0]));
  frame.centre = reference;
  if (second[0] > 0.0) {
    // Second pass about the first pass's centroid: Σ|p − c|² directly, a small mean correction.
    const double n = second[0];
    const double mx = second[1] / n, my = second[2] / n, mz = second[3] / n;
    const double variance = second[4] / n - (mx * mx + my * my + mz * mz);
    frame.centre = Vec3f{static_cast<float>(static_cast<double>(reference.x) + mx),
                         static_cast<float>(static_cast<double>(reference.y) + my),
                         static_cast<float>(static_cast<double>(reference.z) + mz)};
    frame.scale = variance > 0.0 ? std::sqrt(variance) : 1.0;
  }
  return frame;
}

template <typename Reduce>
TrackingResult Tracker::Impl::run(const Frame& frame, const Pose& T_world_model, const Pose& guess,
                                  Reduce&& reduce) const {
  TrackingResult result;
  result.T_world_camera = guess;
  result.live_pixels = frame.live_pixels;
  auto lost = [&](std::string reason) {
    result.T_world_camera = guess;
    result.lost = true;
    result.reason = std::move(reason);
    return result;
  };
  if (frame.live_pixels == 0) return lost("the live depth map has no valid depth");
  if (frame.model_points == 0) return lost("the model raycast shows no surface");

  Pose T_model_live = T_world_model.inverse() * guess;
  TrackParams params;
  params.centre = frame.centre;
  params.inverse_scale = static_cast<float>(1.0 / frame.scale);
  params.min_normal_cos = static_cast<float>(std::cos(options.max_normal_angle_deg * M_PI / 180.0));
  bool finest_reduced = false;
  Sums last{};
  for (int level = static_cast<int>(levels.size()) - 1; level >= 0; --level) {
    params.max_distance_m = static_cast<float>(std::ldexp(options.max_distance_m, level));
    for (int iteration = 0; iteration < options.iterations[static_cast<std::size_t>(level)]; ++iteration) {
      params.T_model_live = T_model_live.to_rigid3f();
      const Sums sums = reduce(level, params);
      if (level == 0) {
        finest_reduced = true;
        last = sums;
      }
      // The next reduction's Huber scale from this one's residual RMS.
      if (options.huber_rms_factor > 0.0 && sums[kTrackCount] > 0.0) {
        params.huber_m =
            static_cast<float>(options.huber_rms_factor * std::sqrt(sums[kTrackResidual2] / sums[kTrackCount]));
      }
      const double count = sums[kTrackCount];
      if (count < 6.0) break;  // nothing to solve at this level: go finer (the tests below judge)
      const Step step = solve(sums, options.degenerate_eigen_ratio);
      if (level == 0) {
        result.condition = step.condition;
        result.degenerate_directions = step.degenerate;
      }
      if (!step.twist.allFinite()) break;
      T_model_live = step_pose(step.twist, frame) * T_model_live;
      ++result.iterations;
      if (step.twist.head<3>().norm() < options.min_translation_step_m &&
          step.twist.tail<3>().norm() / frame.scale < options.min_rotation_step_rad) {
        break;
      }
    }
  }
  const Pose estimate = T_world_model * T_model_live;
  if (finest_reduced) {
    result.inliers = static_cast<std::size_t>(std::llround(last[kTrackCount]));
    result.residual_rms_m = result.inliers > 0 ? std::sqrt(last[kTrackResidual2] / last[kTrackCount]) : 0.0;
  }
  result.inlier_fraction = static_cast<double>(result.inliers) / static_cast<double>(frame.live_pixels);
  if (result.inlier_fraction < options.min_inlier_fraction) {
    return lost(fmt::format("only {} of {} live pixels ({}) match the model within {:.0f} um and {:.0f} deg; "
                            "at least {} must",
                            result.inliers, frame.live_pixels, percent(result.inlier_fraction),
                            options.max_distance_m * 1e6, options.max_normal_angle_deg,
                            percent(options.min_inlier_fraction)));
  }
  if (result.residual_rms_m > options.max_residual_rms_m) {
    return lost(fmt::format("the point-to-plane residual RMS of the {} inliers is {:.1f} um, above the {:.1f} um allowed",
                            result.inliers, result.residual_rms_m * 1e6, options.max_residual_rms_m * 1e6));
  }
  // The correction as the scene sees it: how far the registration moves the model's centroid
  // in the camera's view (turning about an object 0.1 m away moves the camera itself ~1.7 mm
  // per degree, the surface in view far less).
  const Eigen::Vector3d centre_world =
      T_world_model * Eigen::Vector3d(frame.centre.x, frame.centre.y, frame.centre.z);
  const double correction_m = ((guess.inverse() * centre_world) - (estimate.inverse() * centre_world)).norm();
  const double correction_deg = (guess.inverse() * estimate).angle_rad() * 180.0 / M_PI;
  if (!std::isfinite(correction_m) || !std::isfinite(correction_deg) || correction_m > options.max_correction_m ||
      correction_deg > options.max_correction_deg) {
    return lost(fmt::format("the registration moves the view's centre {:.3f} mm and turns {:.3f} deg from the guess, "
                            "more than the {:.3f} mm / {:.3f} deg allowed",
                            correction_m * 1e3, correction_deg, options.max_correction_m * 1e3,
                            options.max_correction_deg));
  }
  result.T_world_camera = estimate;
  return result;
}

Tracker::Tracker(const Device& device, const CameraIntrinsics& live_camera, const TrackingOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  if (!(live_camera.fx > 0.0) || !(live_camera.fy > 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: focal lengths {} {} are not positive", live_camera.fx,
                live_camera.fy);
  }
  Impl& s = *impl_;
  s.live_camera = live_camera;
  CameraIntrinsics camera = live_camera;
  while (camera.width > options.max_model_width) {
    s.input_cameras.push_back(camera);
    camera = half_camera(camera);
  }
  const int level_count = static_cast<int>(options.iterations.size());
  if (camera.width <= 0 || camera.height <= 0 || (camera.width >> (level_count - 1)) < 8 ||
      (camera.height >> (level_count - 1)) < 8) {
    throw_error(ErrorCode::kInvalidArgument,
                "tracking: a camera of {}x{} pixels is too small for {} pyramid levels (8x8 at the coarsest)",
                camera.width, camera.height, level_count);
  }
  s.device = device;
  s.camera = camera;
  s.options = options;
  s.levels.resize(static_cast<std::size_t>(level_count));
  for (int l = 0; l < level_count; ++l) {
    Level& level = s.levels[static_cast<std::size_t>(l)];
    level.camera = l == 0 ? camera : half_camera(s.levels[static_cast<std::size_t>(l - 1)].camera);
    level.rays = compute_ray_map(level.camera);
  }
  if (device.is_cuda()) {
    require_device(device);
#if defined(SLS_HAVE_CUDA)
    SLS_CUDA_CHECK(cudaStreamCreateWithFlags(&s.stream, cudaStreamNonBlocking));
    s.depth.resize(s.levels.size());
    s.rays.resize(s.levels.size());
    s.normals.resize(s.levels.size());
    for (std::size_t l = 0; l < s.levels.size(); ++l) {
      const std::size_t pixels = s.levels[l].pixels();
      s.depth[l].allocate(pixels);
      s.rays[l].allocate(pixels);
      s.normals[l].allocate(pixels);
      s.rays[l].upload(s.levels[l].rays.rays.data(), pixels, s.stream);
    }
    if (!s.input_cameras.empty()) {
      s.live_upload.allocate(static_cast<std::size_t>(live_camera.width) * static_cast<std::size_t>(live_camera.height));
      for (std::size_t k = 1; k < s.input_cameras.size(); ++k) {
        s.input_device.emplace_back(static_cast<std::size_t>(s.input_cameras[k].width) *
                                    static_cast<std::size_t>(s.input_cameras[k].height));
      }
    }
    s.uploaded_points.allocate(s.levels[0].pixels());
    s.uploaded_normals.allocate(s.levels[0].pixels());
    s.partials.allocate(static_cast<std::size_t>(detail::kTrackPartials));
    s.device_sums.allocate(kTrackSums);
    SLS_CUDA_CHECK(cudaMallocHost(reinterpret_cast<void**>(&s.host_sums), kTrackSums * sizeof(double)));
    SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
#endif
  } else {
    for (Level& level : s.levels) {
      level.normals.assign(level.pixels(), Vec3f{0.0f, 0.0f, 0.0f});
      level.depth.assign(level.pixels(), 0.0f);
    }
    for (std::size_t k = 1; k <= s.input_cameras.size(); ++k) {
      const CameraIntrinsics& c = k < s.input_cameras.size() ? s.input_cameras[k] : s.camera;
      s.input_depth.emplace_back(static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height), 0.0f);
    }
  }
}

Tracker::~Tracker() = default;
Tracker::Tracker(Tracker&&) noexcept = default;
Tracker& Tracker::operator=(Tracker&&) noexcept = default;

const TrackingOptions& Tracker::options() const { return impl_->options; }
const CameraIntrinsics& Tracker::model_camera() const { return impl_->camera; }
const Device& Tracker::device() const { return impl_->device; }

namespace {

// Threads' partial sums added in thread order: the same result run after run (for a given
// thread count).
template <std::size_t N, typename Body>
std::array<double, N> parallel_sum(int rows, Body&& body) {
#if defined(_OPENMP)
  std::vector<std::array<double, N>> partial(static_cast<std::size_t>(omp_get_max_threads()), std::array<double, N>{});
#pragma omp parallel
  {
    std::array<double, N> local{};
#pragma omp for schedule(static)
    for (int y = 0; y < rows; ++y) body(y, local.data());
    partial[static_cast<std::size_t>(omp_get_thread_num())] = local;
  }
  std::array<double, N> total{};
  for (const auto& p : partial) {
    for (std::size_t k = 0; k < N; ++k) total[k] += p[k];
  }
  return total;
#else
  std::array<double, N> total{};
  for (int y = 0; y < rows; ++y) body(y, total.data());
  return total;
#endif
}

}  // namespace

TrackingResult Tracker::track(const Image32f& depth_m, const RaycastResult& model, const Pose& T_world_model,
                              const Pose& T_world_camera_guess) {
  Impl& s = *impl_;
  const int width = s.camera.width, height = s.camera.height;
  const std::size_t pixels = s.levels[0].pixels();
  if (depth_m.width() != s.live_camera.width || depth_m.height() != s.live_camera.height) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: the live depth map is {}x{}, the camera {}x{}",
                depth_m.width(), depth_m.height(), s.live_camera.width, s.live_camera.height);
  }
  if (model.depth_m.width() != width || model.depth_m.height() != height || model.points_camera.size() != pixels ||
      model.normals_camera.size() != pixels) {
    throw_error(ErrorCode::kInvalidArgument,
                "tracking: the model maps are {}x{} with {} points and {} normals, the camera {}x{} ({} pixels)",
                model.depth_m.width(), model.depth_m.height(), model.points_camera.size(),
                model.normals_camera.size(), width, height, pixels);
  }
  if (s.device.is_cuda()) {
#if defined(SLS_HAVE_CUDA)
    require_device(s.device);
    const float* live = nullptr;
    if (s.input_cameras.empty()) {
      s.depth[0].upload(depth_m.data(), pixels, s.stream);
      live = s.depth[0].data();
    } else {
      s.live_upload.upload(depth_m.data(), depth_m.pixel_count(), s.stream);
      live = s.live_upload.data();
    }
    s.uploaded_points.upload(model.points_camera.data(), pixels, s.stream);
    s.uploaded_normals.upload(model.normals_camera.data(), pixels, s.stream);
    return s.track_on_device(live, s.uploaded_points.data(), s.uploaded_normals.data(), T_world_model,
                             T_world_camera_guess);
#else
    throw_error(ErrorCode::kUnsupported, "tracking: CUDA asked of a build without CUDA");
#endif
  }

  // The live map halved down to ICP's finest level, then the pyramid and normals.
  const float* level_depth[8] = {};
  level_depth[0] = depth_m.data();
  for (std::size_t k = 0; k < s.input_cameras.size(); ++k) {
    const CameraIntrinsics& fine = s.input_cameras[k];
    const CameraIntrinsics& coarse = k + 1 < s.input_cameras.size() ? s.input_cameras[k + 1] : s.camera;
    halve_depth(level_depth[0], fine, s.input_depth[k].data(), coarse);
    level_depth[0] = s.input_depth[k].data();
  }
  for (std::size_t l = 0; l < s.levels.size(); ++l) {
    Level& level = s.levels[l];
    const int w = level.camera.width, h = level.camera.height;
    if (l > 0) {
      halve_depth(level_depth[l - 1], s.levels[l - 1].camera, level.depth.data(), level.camera);
      level_depth[l] = level.depth.data();
    }
    const float fx = static_cast<float>(level.camera.fx);
    const float baseline = static_cast<float>(s.options.normal_baseline_m);
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        level.normals[level.rays.index(x, y)] =
            live_normal(level_depth[l], level.rays.rays.data(), w, h, fx, baseline, x, y);
      }
    }
  }

  // The frame: live pixels, the model's centre and scale (two passes).
  auto statistics = [&](Vec3f reference) {
    return parallel_sum<kFrameSums>(height, [&](int y, double* sums) {
      for (int x = 0; x < width; ++x) {
        const std::size_t i = s.levels[0].rays.index(x, y);
        accumulate_frame_statistics(model.points_camera[i], level_depth[0][i], reference, sums);
      }
    });
  };
  const Frame frame = s.frame_from_statistics(statistics);

  const TrackModelView model_view = s.model_view(model.points_camera.data(), model.normals_camera.data());
  return s.run(frame, T_world_model, T_world_camera_guess, [&](int l, const TrackParams& params) {
    const Level& level = s.levels[static_cast<std::size_t>(l)];
    TrackLiveView live;
    live.depth = level_depth[l];
    live.rays = level.rays.rays.data();
    live.normals = level.normals.data();
    live.width = level.camera.width;
    live.height = level.camera.height;
    return parallel_sum<kTrackSums>(live.height, [&](int y, double* sums) {
      for (int x = 0; x < live.width; ++x) {
        float jacobian[6];
        float residual = 0.0f;
        if (track_pixel(live, model_view, params, x, y, jacobian, &residual)) {
          accumulate_track_row(jacobian, residual, params.huber_m, sums);
        }
      }
    });
  });
}

#if defined(SLS_HAVE_CUDA)
TrackingResult Tracker::track_device(const float* depth_device, Raycaster& raycaster, const Pose& T_world_model,
                                     const Pose& T_world_camera_guess) {
  Impl& s = *impl_;
  if (!s.device.is_cuda()) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: track_device on a tracker for {}; make it for CUDA",
                s.device.to_string());
  }
  require_device(s.device);
  if (!raycaster.device().is_cuda()) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: track_device needs a CUDA raycaster, not {}",
                raycaster.device().to_string());
  }
  if (raycaster.camera().width != s.camera.width || raycaster.camera().height != s.camera.height) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: the raycaster's camera is {}x{}, the tracker's {}x{}",
                raycaster.camera().width, raycaster.camera().height, s.camera.width, s.camera.height);
  }
  if (depth_device == nullptr) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: no live depth map (null device pointer)");
  }
  raycaster.synchronize();
  return s.track_on_device(depth_device, raycaster.points_device(), raycaster.normals_device(), T_world_model,
                         T_world_camera_guess);
}

TrackingResult Tracker::Impl::track_on_device(const float* depth_device, const Vec3f* model_points,
                                              const Vec3f* model_normals, const Pose& T_world_model,
                                              const Pose& T_world_camera_guess) {
  Impl& s = *this;
  const int width = s.camera.width, height = s.camera.height;
  const int pixels = width * height;
  // The live map halved down to ICP's finest level (into level 0's buffer), then the pyramid
  // and normals, on the device.
  for (std::size_t k = 0; k < s.input_cameras.size(); ++k) {
    const CameraIntrinsics& fine = s.input_cameras[k];
    const CameraIntrinsics& coarse = k + 1 < s.input_cameras.size() ? s.input_cameras[k + 1] : s.camera;
    float* coarse_depth = k + 1 < s.input_cameras.size() ? s.input_device[k].data() : s.depth[0].data();
    detail::launch_downsample_depth_cuda(depth_device, fine.width, fine.height, static_cast<float>(fine.fx),
                                         coarse_depth, coarse.width, coarse.height, s.stream);
    depth_device = coarse_depth;
  }
  const float* level_depth[8] = {};  // validate(): at most 8 levels
  level_depth[0] = depth_device;
  for (std::size_t l = 0; l < s.levels.size(); ++l) {
    const Level& level = s.levels[l];
    if (l > 0) {
      const Level& fine = s.levels[l - 1];
      detail::launch_downsample_depth_cuda(level_depth[l - 1], fine.camera.width, fine.camera.height,
                                           static_cast<float>(fine.camera.fx), s.depth[l].data(), level.camera.width,
                                           level.camera.height, s.stream);
      level_depth[l] = s.depth[l].data();
    }
    detail::launch_live_normals_cuda(level_depth[l], s.rays[l].data(), level.camera.width, level.camera.height,
                                     static_cast<float>(level.camera.fx),
                                     static_cast<float>(s.options.normal_baseline_m), s.normals[l].data(), s.stream);
  }
  auto download = [&](int count) {
    SLS_CUDA_CHECK(cudaMemcpyAsync(s.host_sums, s.device_sums.data(), static_cast<std::size_t>(count) * sizeof(double),
                                   cudaMemcpyDeviceToHost, s.stream));
    SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
  };
  auto statistics = [&](Vec3f reference) {
    detail::launch_frame_statistics_cuda(model_points, depth_device, pixels, reference, s.partials.data(),
                                         s.device_sums.data(), s.stream);
    download(kFrameSums);
    FrameSums sums{};
    std::copy(s.host_sums, s.host_sums + kFrameSums, sums.begin());
    return sums;
  };
  const Frame frame = s.frame_from_statistics(statistics);

  const TrackModelView model_view = s.model_view(model_points, model_normals);
  return s.run(frame, T_world_model, T_world_camera_guess, [&](int l, const TrackParams& params) {
    const Level& level = s.levels[static_cast<std::size_t>(l)];
    TrackLiveView live;
    live.depth = level_depth[l];
    live.rays = s.rays[static_cast<std::size_t>(l)].data();
    live.normals = s.normals[static_cast<std::size_t>(l)].data();
    live.width = level.camera.width;
    live.height = level.camera.height;
    detail::launch_track_cuda(live, model_view, params, s.partials.data(), s.device_sums.data(), s.stream);
    download(kTrackSums);
    Sums sums{};
    std::copy(s.host_sums, s.host_sums + kTrackSums, sums.begin());
    return sums;
  });
}
#endif

}  // namespace sls::fusion
