// The Tracker: its options, the Gauss–Newton loop and its lost-frame tests, and the CPU path
// (the CUDA path: cuda/tracker_gpu.cpp).
#include "fusion/tracker.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include "fusion/tracker_internal.h"

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace sls::fusion {

using namespace tracking_detail;

Matrix6d tracking_detail::normal_matrix(const double* sums) {
  Matrix6d a;
  int k = 0;
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c) {
      a(r, c) = sums[k];
      a(c, r) = sums[k];
      ++k;
    }
  }
  return a;
}

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
  if (!(tukey_rms_factor >= 0.0) || !std::isfinite(tukey_rms_factor)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: tukey_rms_factor {} must be 0 or positive", tukey_rms_factor);
  }
  if (max_model_width < 16) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: max_model_width {} (at least 16 pixels)", max_model_width);
  }
  if (!(normal_baseline_m > 0.0) || !std::isfinite(normal_baseline_m)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: normal_baseline_m {} must be positive", normal_baseline_m);
  }
  if (!(crease_radius_m > 0.0) || !std::isfinite(crease_radius_m)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: crease_radius_m {} must be positive", crease_radius_m);
  }
  if (!(crease_angle_deg >= 0.0 && crease_angle_deg < 180.0)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: crease_angle_deg {} outside [0, 180) (0 = off)",
                crease_angle_deg);
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
  if (!(photometric_weight >= 0.0 && photometric_weight <= 1e6)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: photometric_weight {} outside [0, 1e6] (0 = off)",
                photometric_weight);
  }
  if (!(photometric_min_gradient >= 0.0) || !std::isfinite(photometric_min_gradient)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: photometric_min_gradient {} must be 0 or positive",
                photometric_min_gradient);
  }
}

namespace {

// body(x, y) for every pixel of a width x height map, rows spread over the CPU's threads (the
// CPU launcher of the per-pixel bodies in track_shared.h and photometric_shared.h).
template <typename Body>
void for_each_pixel(int width, int height, const Body& body) {
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) body(x, y);
  }
}

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

// The solved step of one Gauss–Newton iteration.
struct Step {
  Vector6d twist = Vector6d::Zero();  // [ρ, ω'] of track_shared.h
  int degenerate = 0;
  double condition = 0.0;
};

Step solve(const Sums& sums, double degenerate_ratio) {
  const Matrix6d a = normal_matrix(sums.data());
  Vector6d b;
  for (int r = 0; r < 6; ++r) b(r) = sums[static_cast<std::size_t>(kTrackJtr + r)];
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

// Adds the photometric normal equations (JᵀJ and Jᵀr) to the ICP's in `system`, scaled so that
// their largest eigenvalue is `weight` times the ICP one's (TrackingOptions::photometric_weight:
// the two terms' units, metres and intensity, drop out). False when either is empty.
bool add_photometric(Sums& system, const PhotometricSums& photometric, double weight) {
  if (photometric[kTrackCount] < 6.0) return false;
  const Eigen::SelfAdjointEigenSolver<Matrix6d> icp(normal_matrix(system.data()), Eigen::EigenvaluesOnly);
  const Eigen::SelfAdjointEigenSolver<Matrix6d> rgb(normal_matrix(photometric.data()), Eigen::EigenvaluesOnly);
  const double icp_largest = icp.eigenvalues()(5), rgb_largest = rgb.eigenvalues()(5);
  if (!(icp_largest > 0.0) || !(rgb_largest > 0.0) || !std::isfinite(rgb_largest)) return false;
  const double scale = weight * icp_largest / rgb_largest;
  for (int k = 0; k < kTrackJtr + 6; ++k) {
    system[static_cast<std::size_t>(k)] += scale * photometric[static_cast<std::size_t>(k)];
  }
  return true;
}

// A depth map at `fine`'s size halved into `coarse`'s, and its weight map when fine_weight is
// given (downsample_depth per coarse pixel; the CPU side of launch_downsample_depth_cuda).
void halve_depth(const float* fine_depth, const float* fine_weight, const CameraIntrinsics& fine, float* coarse_depth,
                 float* coarse_weight, const CameraIntrinsics& coarse) {
  const float fine_fx = static_cast<float>(fine.fx);
  for_each_pixel(coarse.width, coarse.height, [&](int x, int y) {
    const std::size_t i =
        static_cast<std::size_t>(y) * static_cast<std::size_t>(coarse.width) + static_cast<std::size_t>(x);
    coarse_depth[i] = downsample_depth(fine_depth, fine.width, fine.height, fine_fx, x, y, fine_weight,
                                       fine_weight != nullptr ? &coarse_weight[i] : nullptr);
  });
}

// A texture at `fine`'s size halved into `coarse`'s (downsample_texture per coarse pixel).
void halve_texture(const float* fine_texture, const CameraIntrinsics& fine, float* coarse_texture,
                   const CameraIntrinsics& coarse) {
  for_each_pixel(coarse.width, coarse.height, [&](int x, int y) {
    coarse_texture[static_cast<std::size_t>(y) * static_cast<std::size_t>(coarse.width) +
                   static_cast<std::size_t>(x)] = downsample_texture(fine_texture, fine.width, fine.height, x, y);
  });
}

}  // namespace

Frame Tracker::Impl::frame_from_sums(const FrameSums& first, const FrameSums& second, Vec3f reference) const {
  Frame frame;
  frame.live_pixels = static_cast<std::size_t>(std::llround(first[kFrameLivePixels]));
  frame.live_pixels_outside = static_cast<std::size_t>(std::llround(first[kFrameLiveOutside]));
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

TrackingResult Tracker::Impl::run(const Frame& frame, const Pose& T_world_model, const Pose& guess, const Reduce& reduce,
                                  const PhotometricSetup* photometric,
                                  const ReducePhotometric& reduce_photometric) const {
  TrackingResult result;
  result.T_world_camera = guess;
  result.live_pixels = frame.live_pixels;
  result.live_pixels_outside_model = frame.live_pixels_outside;
  auto lost = [&](std::string reason) {
    result.T_world_camera = guess;
    result.lost = true;
    result.reason = std::move(reason);
    return result;
  };
  if (frame.live_pixels == 0 && frame.live_pixels_outside > 0) {
    result.too_little_overlap = true;
    return lost(fmt::format("none of the {} live pixels with a depth lies inside the model's volume at the guessed pose",
                            frame.live_pixels_outside));
  }
  if (frame.live_pixels == 0) return lost("the live depth map has no valid depth");
  if (frame.model_points == 0) {
    result.too_little_overlap = true;
    return lost("the model raycast shows no surface");
  }

  Pose T_model_live = T_world_model.inverse() * guess;
  TrackParams params;
  params.centre = frame.centre;
  params.inverse_scale = static_cast<float>(1.0 / frame.scale);
  params.min_normal_cos = static_cast<float>(std::cos(options.max_normal_angle_deg * M_PI / 180.0));
  bool finest_reduced = false;
  Sums last{};
  PriorStep finest_prior;  // with a pose prior: its last step at the finest level
  PhotometricParams photo;
  if (photometric != nullptr) {
    photo.T_model_ref = photometric->T_model_ref.to_rigid3f();
    photo.centre = frame.centre;
    photo.inverse_scale = params.inverse_scale;
    photo.gain = static_cast<float>(photometric->ref_mean / photometric->live_mean);  // until measured
    photo.inverse_mean = static_cast<float>(1.0 / photometric->ref_mean);
    photo.min_gradient = static_cast<float>(options.photometric_min_gradient);
  }
  for (int level = static_cast<int>(levels.size()) - 1; level >= 0; --level) {
    params.max_distance_m = static_cast<float>(std::ldexp(options.max_distance_m, level));
    for (int iteration = 0; iteration < options.iterations[static_cast<std::size_t>(level)]; ++iteration) {
      params.T_model_live = T_model_live.to_rigid3f();
      const Sums sums = reduce(level, params);
      if (level == 0) {
        finest_reduced = true;
        last = sums;
      }
      // The next reduction's robust scale from this one's residual RMS.
      if (sums[kTrackCount] > 0.0) {
        const double rms = std::sqrt(sums[kTrackResidual2] / sums[kTrackCount]);
        params.tukey_m = static_cast<float>(options.tukey_rms_factor * rms);
        params.huber_m = options.tukey_rms_factor > 0.0 ? 0.0f : static_cast<float>(options.huber_rms_factor * rms);
      }
      const double count = sums[kTrackCount];
      if (count < 6.0) break;  // nothing to solve at this level: go finer (the tests below judge)
      Sums system = sums;
      if (photometric != nullptr) {
        // The photometric term at the same estimate, on the level's texture pyramid.
        photo.camera = levels[static_cast<std::size_t>(level)].camera.cast<float>();
        photo.max_depth_difference_m = params.max_distance_m;
        photo.R_model_live = params.T_model_live.rotation;
        photo.T_live_ref = (T_model_live.inverse() * photometric->T_model_ref).to_rigid3f();
        const PhotometricSums p = reduce_photometric(level, photo);
        const double rows = p[kTrackCount];
        // The next reduction's brightness ratio and Huber scale from this one.
        if (p[kPhotometricLiveSum] > 0.0 && p[kPhotometricReferenceSum] > 0.0) {
          photo.gain = static_cast<float>(p[kPhotometricReferenceSum] / p[kPhotometricLiveSum]);
        }
        if (options.huber_rms_factor > 0.0 && rows > 0.0) {
          photo.huber = static_cast<float>(options.huber_rms_factor * std::sqrt(p[kTrackResidual2] / rows));
        }
        if (level == 0) {
          result.photometric_pixels = static_cast<std::size_t>(std::llround(rows));
          result.photometric_rms = rows > 0.0 ? std::sqrt(p[kTrackResidual2] / rows) : 0.0;
          result.photometric_gain = photo.gain;
        }
        if (add_photometric(system, p, options.photometric_weight)) result.photometric = true;
      }
      Step step;
      if (pose_prior != nullptr) {  // with s² of this reduction's residuals (pose_prior.h)
        const PriorStep p = solve_with_pose_prior(system.data(), *pose_prior, sums[kTrackResidual2] / count,
                                                  T_world_model, T_model_live, frame.scale, options.degenerate_eigen_ratio);
        step = {p.twist, p.degenerate, p.condition};
        if (level == 0) finest_prior = p;
      } else {
        step = solve(system, options.degenerate_eigen_ratio);
      }
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
  if (pose_prior != nullptr) report_pose_prior(*pose_prior, estimate, finest_prior, &result);
  if (photometric != nullptr && !result.photometric) {
    result.photometric_skipped = "too few reference pixels with a texture gradient matched the live frame";
  }
  if (finest_reduced) {
    result.inliers = static_cast<std::size_t>(std::llround(last[kTrackCount]));
    result.crease_pixels = static_cast<std::size_t>(std::llround(last[kTrackCreaseCount]));
    result.residual_rms_m = result.inliers > 0 ? std::sqrt(last[kTrackResidual2] / last[kTrackCount]) : 0.0;
  }
  // Of the live pixels ICP could use: those whose match lies on a crease are set aside.
  const std::size_t usable = frame.live_pixels - std::min(result.crease_pixels, frame.live_pixels);
  result.inlier_fraction = usable > 0 ? static_cast<double>(result.inliers) / static_cast<double>(usable) : 0.0;
  if (result.inlier_fraction < options.min_inlier_fraction) {
    result.too_little_overlap = true;
    return lost(fmt::format("only {} of {} live pixels ({}) match the model within {:.0f} um and {:.0f} deg "
                            "({} more fell on creases{}); at least {} must",
                            result.inliers, usable, percent(result.inlier_fraction), options.max_distance_m * 1e6,
                            options.max_normal_angle_deg, result.crease_pixels,
                            frame.live_pixels_outside > 0
                                ? fmt::format(", {} lie outside the model's volume and are not counted",
                                              frame.live_pixels_outside)
                                : std::string(),
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

Tracker::Tracker(const Device& device, const CameraIntrinsics& live_camera, const TrackingOptions& options,
                 const GpuStream& stream)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  if (!(live_camera.fx > 0.0) || !(live_camera.fy > 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: focal lengths {} {} are not positive", live_camera.fx,
                live_camera.fy);
  }
  // Pixels are indexed in 32 bits (track_shared.h).
  if (static_cast<long long>(live_camera.width) * live_camera.height > std::numeric_limits<int>::max()) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: a camera of {}x{} pixels is too large (at most 2^31 - 1 pixels)",
                live_camera.width, live_camera.height);
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
  s.photometric_on = options.photometric_weight > 0.0;
  s.levels.resize(static_cast<std::size_t>(level_count));
  for (int l = 0; l < level_count; ++l) {
    Level& level = s.levels[static_cast<std::size_t>(l)];
    level.camera = l == 0 ? camera : half_camera(s.levels[static_cast<std::size_t>(l - 1)].camera);
    level.shared_rays = shared_ray_map(level.camera, device);
    level.rays = &level.shared_rays->host;
  }
  s.gpu_stream = GpuStream::or_create(stream, device);
  if (device.is_cuda()) {
    s.allocate_on_device();
  } else {
    if (s.crease_test()) {
      s.crease_normals.assign(s.levels[0].pixels(), Vec3f{0.0f, 0.0f, 0.0f});
      s.crease_mask.assign(s.levels[0].pixels(), 0);
    }
    for (Level& level : s.levels) {
      level.normals.assign(level.pixels(), Vec3f{0.0f, 0.0f, 0.0f});
      level.depth.assign(level.pixels(), 0.0f);
      if (options.weight_by_confidence) level.weight.assign(level.pixels(), 0.0f);
    }
    for (std::size_t k = 1; k <= s.input_cameras.size(); ++k) {
      const CameraIntrinsics& c = k < s.input_cameras.size() ? s.input_cameras[k] : s.camera;
      s.input_depth.emplace_back(static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height), 0.0f);
      if (options.weight_by_confidence) {
        s.input_weight.emplace_back(static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height), 0.0f);
      }
      if (s.photometric_on) {
        s.input_texture.emplace_back(static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height), 0.0f);
      }
    }
    if (s.photometric_on) {
      for (const Level& level : s.levels) s.texture.emplace_back(level.pixels(), 0.0f);
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

void Tracker::Impl::depth_pyramid(const float* depth_in, const float* weight_in, const float* level_depth[8],
                                  const float* level_weight[8], bool with_normals) {
  // The live map (and its weights) halved down to ICP's finest level, then the pyramid and
  // normals.
  const bool weighted = weight_in != nullptr;
  level_depth[0] = depth_in;
  level_weight[0] = weight_in;
  for (std::size_t k = 0; k < input_cameras.size(); ++k) {
    const CameraIntrinsics& fine = input_cameras[k];
    const CameraIntrinsics& coarse = k + 1 < input_cameras.size() ? input_cameras[k + 1] : camera;
    halve_depth(level_depth[0], level_weight[0], fine, input_depth[k].data(),
                weighted ? input_weight[k].data() : nullptr, coarse);
    level_depth[0] = input_depth[k].data();
    if (weighted) level_weight[0] = input_weight[k].data();
  }
  for (std::size_t l = 0; l < levels.size(); ++l) {
    Level& level = levels[l];
    const int w = level.camera.width, h = level.camera.height;
    if (l > 0) {
      halve_depth(level_depth[l - 1], level_weight[l - 1], levels[l - 1].camera, level.depth.data(),
                  weighted ? level.weight.data() : nullptr, level.camera);
      level_depth[l] = level.depth.data();
      level_weight[l] = weighted ? level.weight.data() : nullptr;
    }
    if (!with_normals) continue;
    const float fx = static_cast<float>(level.camera.fx);
    const float baseline = static_cast<float>(options.normal_baseline_m);
    const float* depth_l = level_depth[l];
    for_each_pixel(w, h, [&](int x, int y) {
      level.normals[level.rays->index(x, y)] = live_normal(depth_l, level.rays->rays.data(), w, h, fx, baseline, x, y);
    });
  }
}

void Tracker::Impl::texture_pyramid(const float* texture_in, const float* level_texture[8]) {
  level_texture[0] = texture_in;
  for (std::size_t k = 0; k < input_cameras.size(); ++k) {
    const CameraIntrinsics& fine = input_cameras[k];
    const CameraIntrinsics& coarse = k + 1 < input_cameras.size() ? input_cameras[k + 1] : camera;
    halve_texture(level_texture[0], fine, input_texture[k].data(), coarse);
    level_texture[0] = input_texture[k].data();
  }
  for (std::size_t l = 1; l < levels.size(); ++l) {
    halve_texture(level_texture[l - 1], levels[l - 1].camera, texture[l].data(), levels[l].camera);
    level_texture[l] = texture[l].data();
  }
}

double Tracker::Impl::texture_mean(const float* texture0, const float* depth0) const {
  const int width = camera.width;
  const TextureSums sums = parallel_sum<kTextureSums>(camera.height, [&](int y, double* out) {
    for (int x = 0; x < width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
      accumulate_texture_statistics(texture0[i], depth0[i], out);
    }
  });
  return sums[1] > 0.0 ? sums[0] / sums[1] : 0.0;
}

TrackingResult Tracker::track(const Image32f& depth_m, const RaycastResult& model, const Pose& T_world_model,
                              const Pose& T_world_camera_guess, const Image32f* texture,
                              const Image32f* confidence, const PosePrior* prior,
                              const VolumeGeometry* model_volume) {
  Impl& s = *impl_;
  const Impl::CallScope call_scope(s, prior, model_volume);
  const int width = s.camera.width, height = s.camera.height;
  const std::size_t pixels = s.levels[0].pixels();
  if (depth_m.width() != s.live_camera.width || depth_m.height() != s.live_camera.height) {
    throw_error(ErrorCode::kInvalidArgument, "tracking: the live depth map is {}x{}, the camera {}x{}",
                depth_m.width(), depth_m.height(), s.live_camera.width, s.live_camera.height);
  }
  if (model.depth_m.width() != width || model.depth_m.height() != height ||
      model.points_camera.pixel_count() != pixels || model.normals_camera.pixel_count() != pixels) {
    throw_error(ErrorCode::kInvalidArgument,
                "tracking: the model maps are {}x{} with {} points and {} normals, the camera {}x{} ({} pixels)",
                model.depth_m.width(), model.depth_m.height(), model.points_camera.pixel_count(),
                model.normals_camera.pixel_count(), width, height, pixels);
  }
  if (texture != nullptr) s.check_size(*texture, "live texture");
  if (confidence != nullptr) s.check_size(*confidence, "live confidence map");
  // With photometric_weight 0 the texture is not used at all, nor the confidence without
  // weight_by_confidence.
  const Image32f* live_texture = s.photometric_on ? texture : nullptr;
  const Image32f* live_weight = s.options.weight_by_confidence ? confidence : nullptr;
  if (s.device.is_cuda()) {
    return s.track_gpu(depth_m, model.points_camera, model.normals_camera, T_world_model, T_world_camera_guess,
                       live_texture, live_weight);
  }
  s.check_on_host(depth_m, "live depth map");
  s.check_on_host(model.points_camera, "model's point map");
  s.check_on_host(model.normals_camera, "model's normal map");
  if (live_texture != nullptr) s.check_on_host(*live_texture, "live texture");
  if (live_weight != nullptr) s.check_on_host(*live_weight, "live confidence map");

  const float* level_depth[8] = {};  // validate(): at most 8 levels
  const float* level_weight[8] = {};
  s.depth_pyramid(depth_m.data(), live_weight != nullptr ? live_weight->data() : nullptr, level_depth, level_weight,
                  true);

  // The frame: live pixels, the model's centre and scale (two passes).
  const TrackRegion region = s.region(T_world_camera_guess);
  auto statistics = [&](Vec3f reference) {
    return parallel_sum<kFrameSums>(height, [&](int y, double* sums) {
      for (int x = 0; x < width; ++x) {
        const std::size_t i = s.levels[0].rays->index(x, y);
        accumulate_frame_statistics(model.points_camera.data()[i], level_depth[0][i], s.levels[0].rays->rays[i], region,
                                    reference, sums);
      }
    });
  };
  const Frame frame = s.frame_from_statistics(statistics);

  TrackModelView model_view = s.model_view(model.points_camera.data(), model.normals_camera.data());
  if (s.crease_test()) {
    const float fx = static_cast<float>(s.camera.fx), baseline = static_cast<float>(s.options.normal_baseline_m);
    const float min_cos = s.crease_min_cos(), radius = static_cast<float>(s.options.crease_radius_m);
    const Vec3f* points = model.points_camera.data();
    for_each_pixel(width, height, [&](int x, int y) {
      s.crease_normals[s.levels[0].rays->index(x, y)] = baseline_normal(PointMap{points}, width, height, fx, baseline, x, y);
    });
    for_each_pixel(width, height, [&](int x, int y) {
      s.crease_mask[s.levels[0].rays->index(x, y)] =
          near_crease(s.crease_normals.data(), points, width, height, fx, radius, min_cos, x, y) ? 1 : 0;
    });
    model_view.creases = s.crease_mask.data();
  }
  auto reduce = [&](int l, const TrackParams& params) {
    const Level& level = s.levels[static_cast<std::size_t>(l)];
    TrackLiveView live;
    live.depth = level_depth[l];
    live.rays = level.rays->rays.data();
    live.normals = level.normals.data();
    live.weights = level_weight[l];
    live.width = level.camera.width;
    live.height = level.camera.height;
    return parallel_sum<kTrackSums>(live.height, [&](int y, double* sums) {
      const int row = y * live.width;
      for (int x = 0; x < live.width; ++x) accumulate_track_pixel(live, model_view, params, row + x, sums);
    });
  };

  // The photometric term: the live texture's pyramid against the reference frame's.
  const float* level_texture[8] = {};
  double live_mean = 0.0;
  if (live_texture != nullptr) {
    s.texture_pyramid(live_texture->data(), level_texture);
    live_mean = s.texture_mean(level_texture[0], level_depth[0]);
  }
  std::string skipped;
  const std::optional<PhotometricSetup> setup =
      s.photometric_setup(live_texture != nullptr, live_mean, T_world_model, &skipped);
  Impl::ReducePhotometric reduce_photometric;
  if (setup) {
    reduce_photometric = [&](int l, const PhotometricParams& params) {
      const Level& level = s.levels[static_cast<std::size_t>(l)];
      PhotometricLevelView ref, live;
      ref.texture = s.reference_frame.texture[static_cast<std::size_t>(l)].data();
      ref.depth = s.reference_frame.depth[static_cast<std::size_t>(l)].data();
      ref.rays = level.rays->rays.data();
      ref.width = live.width = level.camera.width;
      ref.height = live.height = level.camera.height;
      live.texture = level_texture[l];
      live.depth = level_depth[l];
      live.rays = ref.rays;
      return parallel_sum<kPhotometricSums>(ref.height, [&](int y, double* sums) {
        for (int x = 0; x < ref.width; ++x) {
          float jacobian[6];
          float residual = 0.0f, live_value = 0.0f, ref_value = 0.0f;
          const int outcome = photometric_pixel(ref, live, params, x, y, jacobian, &residual, &live_value, &ref_value);
          accumulate_photometric(outcome, jacobian, residual, live_value, ref_value, params.huber, sums);
        }
      });
    };
  }
  TrackingResult result = s.run(frame, T_world_model, T_world_camera_guess, reduce, setup ? &*setup : nullptr,
                                reduce_photometric);
  if (!skipped.empty()) result.photometric_skipped = skipped;
  // A frame registered with a texture is the next frame's reference.
  if (live_texture != nullptr && live_mean > 0.0 && std::isfinite(live_mean) && !result.lost) {
    s.keep_reference(level_depth, level_texture, live_mean, result.T_world_camera);
  }
  return result;
}

}  // namespace sls::fusion
