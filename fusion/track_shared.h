// Per-pixel code of the ICP tracker (fusion/tracker.h), shared by the CPU and CUDA backends
// (DESIGN.md section 6): the live depth pyramid (2x2 block average with a discontinuity
// check), live normals from the live vertex map, and the projective data association with
// the point-to-plane residual and its Jacobian, summed into the 6x6 normal equations.
//
// Frames: "live" is the camera of the live depth map (its pose is being estimated), "model"
// the camera the model maps were raycast from (T_world_model). The estimate is
// T_model_live = T_world_model⁻¹ · T_world_camera.
//
// Parameterisation of the update (left, in the model frame, about a centre c):
//   p ↦ p + ρ + (ω' / L) × (p − c),   i.e.  δT = Tr(c) · Pose::exp([ρ, ω'/L]) · Tr(−c),
//   T_model_live ← δT · T_model_live.
// c is the centroid of the model's points and L their RMS distance from it, so that the
// three rotation columns of J have the units and the size of the translation ones: the
// eigenvalues of JᵀJ are comparable and the degenerate-direction test (a ratio of them)
// means the same at any working distance. The twist's order is Pose::exp's: ρ then ω'.
#pragma once

#include <cmath>
#include <cstdint>

#include "fusion/depth_shared.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::fusion {

// The reduced sums: 21 of the upper triangle of JᵀJ (row-major: (0,0) (0,1) .. (0,5) (1,1) ..),
// 6 of Jᵀr, Σr², the inlier count and the count of matches skipped on creases.
constexpr int kTrackSums = 30;
constexpr int kTrackJtr = 21;
constexpr int kTrackResidual2 = 27;
constexpr int kTrackCount = 28;
constexpr int kTrackCreaseCount = 29;  // live pixels whose match lies on a model crease (not used)
// The frame's statistics (accumulate_frame_statistics): the model's moments for the centre
// and scale, the live pixels with a depth that can lie in the model, and those that cannot.
constexpr int kFrameSums = 7;
constexpr int kFrameLivePixels = 5;
constexpr int kFrameLiveOutside = 6;

// A depth step between neighbouring pixels larger than this many pixel footprints (z / fx)
// is a discontinuity (an occluding edge), not a slope: a 2x2 block keeps the nearest
// surface's depths and a live normal is not formed across it. 8 footprints is a face at 83°
// to the view.
constexpr float kDiscontinuityFootprints = 8.0f;

// One pixel of pyramid level l + 1 from the 2x2 block (2x, 2y) .. (2x+1, 2y+1) of level l
// (fine_width x fine_height, focal length fine_fx): the average of the block's valid depths
// within kDiscontinuityFootprints footprints of the nearest; 0 when none is valid. The coarse
// pixel's centre is the block's centre, so the coarse camera is fx/2, (cx − 0.5)/2.
// With a weight map (the live pixels' measurement weights, TrackLiveView::weights),
// *coarse_weight is the mean weight of the depths averaged (0 when none is valid).
SLS_HOST_DEVICE inline float downsample_depth(const float* fine, int fine_width, int fine_height, float fine_fx,
                                              int x, int y, const float* fine_weight = nullptr,
                                              float* coarse_weight = nullptr) {
  float z[4];
  float w[4] = {1.0f, 1.0f, 1.0f, 1.0f};
  int n = 0;
  float nearest = 3.0e38f;
  for (int dy = 0; dy < 2; ++dy) {
    for (int dx = 0; dx < 2; ++dx) {
      const int fx = 2 * x + dx, fy = 2 * y + dy;
      if (fx >= fine_width || fy >= fine_height) continue;
      const long long i = static_cast<long long>(fy) * fine_width + fx;
      const float value = fine[i];
      if (!is_measured_depth(value)) continue;
      if (fine_weight != nullptr) w[n] = fine_weight[i];
      z[n++] = value;
      nearest = value < nearest ? value : nearest;
    }
  }
  if (coarse_weight != nullptr) *coarse_weight = 0.0f;
  if (n == 0) return 0.0f;
  const float step = kDiscontinuityFootprints * nearest / fine_fx;
  float sum = 0.0f, weight_sum = 0.0f;
  int count = 0;
  for (int i = 0; i < n; ++i) {
    if (z[i] - nearest <= step) {
      sum += z[i];
      weight_sum += w[i];
      ++count;
    }
  }
  if (coarse_weight != nullptr) *coarse_weight = weight_sum / static_cast<float>(count);
  return sum / static_cast<float>(count);
}

// The unit normal of the live vertex map at (x, y) (vertex = depth × ray), facing the camera,
// from the cross product of the central differences (x+b, y) − (x−b, y) and (x, y+b) − (x, y−b),
// where the half-baseline b (pixels, 1..kMaxNormalBaselinePx) spans about baseline_m on the
// surface: at 3 µm pixels one-pixel differences turn µm depth noise into tens of degrees of
// normal noise; a physical baseline keeps the normal test meaningful at every resolution.
// {0,0,0} when a depth is missing, the baseline leaves the image, or a difference crosses a
// discontinuity. fx: the level's focal length.
constexpr int kMaxNormalBaselinePx = 16;
// The half-baseline b in pixels at depth z (footprint z / fx): baseline_m rounded, 1..kMaxNormalBaselinePx.
SLS_HOST_DEVICE inline int normal_baseline_px(float z, float fx, float baseline_m) {
  const int b = static_cast<int>(baseline_m / (z / fx) + 0.5f);
  return b < 1 ? 1 : (b > kMaxNormalBaselinePx ? kMaxNormalBaselinePx : b);
}

// A vertex map read as live_normal reads it: point(i), {0,0,0} (z = 0) where there is none.
struct DepthRayPoints {  // a depth map along its ray map
  const float* depth;
  const Vec3f* rays;
  SLS_HOST_DEVICE Vec3f operator()(long long i) const {
    const float z = depth[i];
    const Vec3f ray = rays[i];
    if (!is_measured_depth(z) || !(ray.z > 0.0f)) return Vec3f{0.0f, 0.0f, 0.0f};
    return z * ray;
  }
};
struct PointMap {  // a raycast's points (camera frame)
  const Vec3f* points;
  SLS_HOST_DEVICE Vec3f operator()(long long i) const { return points[i]; }
};

// The normal of a vertex map (rays with z = 1, so a point's z is its depth) over the baseline:
// live_normal's body for any map.
template <typename Points>
SLS_HOST_DEVICE inline Vec3f baseline_normal(const Points& point_at, int width, int height, float fx,
                                             float baseline_m, int x, int y) {
  const Vec3f none{0.0f, 0.0f, 0.0f};
  if (x < 0 || y < 0 || x >= width || y >= height) return none;
  const long long i = static_cast<long long>(y) * width + x;
  const Vec3f p = point_at(i);
  const float z = p.z;
  if (!is_measured_depth(z)) return none;
  const float footprint = z / fx;
  const int b = normal_baseline_px(z, fx, baseline_m);
  if (x < b || y < b || x + b >= width || y + b >= height) return none;
  const long long neighbours[4] = {i - b, i + b, i - static_cast<long long>(b) * width,
                                   i + static_cast<long long>(b) * width};
  const float step = kDiscontinuityFootprints * footprint * static_cast<float>(b);
  Vec3f v[4];
  for (int k = 0; k < 4; ++k) {
    v[k] = point_at(neighbours[k]);
    if (!is_measured_depth(v[k].z) || !(std::fabs(v[k].z - z) <= step)) return none;
  }
  Vec3f n = cross(v[1] - v[0], v[3] - v[2]);
  const float length = norm(n);
  if (!(length > 0.0f)) return none;
  n = (1.0f / length) * n;
  if (dot(n, p) > 0.0f) n = -n;
  return n;
}

SLS_HOST_DEVICE inline Vec3f live_normal(const float* depth, const Vec3f* rays, int width, int height, float fx,
                                         float baseline_m, int x, int y) {
  return baseline_normal(DepthRayPoints{depth, rays}, width, height, fx, baseline_m, x, y);
}

SLS_HOST_DEVICE inline bool has_normal(const Vec3f& n) { return n.x != 0.0f || n.y != 0.0f || n.z != 0.0f; }

// Whether the model pixel (x, y) lies within radius_m of a crease (TrackingOptions::
// crease_angle_deg, crease_radius_m): its normal and the normal radius_m away in any of the 8
// directions are further apart than the crease angle (dot < min_cos), the normals taken over
// the baseline from the model's points (baseline_normal: `normals`). Point-to-plane ICP takes
// the surface to be planar around each match; near a crease neither the decoder's depth (a
// pixel's blur, and the projector's, mix the two faces' codes, pulling the point off both)
// nor the model's (the TSDF rounds a crease over its truncation band) is, and their errors
// move with the view, so those matches pull the pose systematically. The model's points are
// averaged over many frames; its raycast normals (the TSDF's gradient over one voxel) and the
// live map are not: 3 um of noise on 10 um voxels turns those by ~17 degrees, and would mark
// smooth surface too. False where the pixel has no normal; neighbours without one are not
// compared. The radius in pixels is at most kMaxCreaseRadiusPx.
constexpr int kMaxCreaseRadiusPx = 64;
SLS_HOST_DEVICE inline bool near_crease(const Vec3f* normals, const Vec3f* points, int width, int height, float fx,
                                        float radius_m, float min_cos, int x, int y) {
  const long long i = static_cast<long long>(y) * width + x;
  const Vec3f n = normals[i];
  if (!has_normal(n)) return false;
  int r = static_cast<int>(radius_m / (points[i].z / fx) + 0.5f);
  r = r < 1 ? 1 : (r > kMaxCreaseRadiusPx ? kMaxCreaseRadiusPx : r);
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const int xx = x + dx * r, yy = y + dy * r;
      if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= width || yy >= height) continue;
      const Vec3f m = normals[static_cast<long long>(yy) * width + xx];
      if (has_normal(m) && dot(n, m) < min_cos) return true;
    }
  }
  return false;
}

// The live level as the association reads it.
struct TrackLiveView {
  const float* depth = nullptr;   // camera-frame z, 0 = none
  const Vec3f* rays = nullptr;    // the level's ray map (z = 1; {0,0,0} where invalid)
  const Vec3f* normals = nullptr; // live_normal per pixel
  // Per-pixel measurement weights (the decoder's confidence, an inverse predicted variance
  // scaled to [0, 1]), or null for all 1.
  const float* weights = nullptr;
  int width = 0;
  int height = 0;
};

// The model maps (a raycast from T_world_model), always the finest level: coarse live levels
// associate against the full-resolution model (projecting with the finest camera), which costs
// nothing extra and keeps the coarse steps as accurate as the model allows.
struct TrackModelView {
  const Vec3f* points = nullptr;   // model camera frame, {0,0,0} = none
  const Vec3f* normals = nullptr;  // unit, facing the model camera
  CameraIntrinsicsF camera;        // the finest camera (size = the maps' size)
  const std::uint8_t* creases = nullptr;  // near_crease per pixel (1: not matched), or null
};

struct TrackParams {
  Rigid3f T_model_live;         // the current estimate
  float max_distance_m = 0.0f;  // of the level
  float min_normal_cos = 0.0f;
  Vec3f centre{0.0f, 0.0f, 0.0f};  // c (model frame)
  float inverse_scale = 1.0f;      // 1 / L
  float huber_m = 0.0f;            // Huber scale of the residuals (0: none)
  float tukey_m = 0.0f;            // Tukey's biweight scale c of the residuals (0: none; before Huber's)
};

// What track_pixel made of a live pixel.
enum TrackOutcome : int {
  kTrackNoMatch = 0,  // no depth, normal or weight, or no model point within the distance and angle
  kTrackInlier = 1,
  kTrackOnCrease = 2,  // it projects onto a model pixel near a crease (TrackModelView::creases)
};

// One live pixel, `i` = y · width + x (its index in the live maps): associates it with the
// model and, for an inlier, returns the Jacobian row J (d r / d[ρ, ω']), the point-to-plane
// residual r = n · (T p − q) in metres and the pixel's measurement weight. Indices are 32-bit
// (a map holds < 2^31 pixels; the tracker refuses larger): a GPU thread then neither divides
// to find its (x, y) nor multiplies in 64 bits.
SLS_HOST_DEVICE inline int track_pixel(const TrackLiveView& live, const TrackModelView& model, const TrackParams& p,
                                       int i, float jacobian[6], float* residual, float* weight) {
  const float z = live.depth[i];
  if (!is_measured_depth(z)) return kTrackNoMatch;
  const Vec3f n_live = live.normals[i];
  if (!has_normal(n_live)) return kTrackNoMatch;
  *weight = live.weights != nullptr ? live.weights[i] : 1.0f;
  if (!(*weight > 0.0f && *weight < 3.0e38f)) return kTrackNoMatch;  // 0, negative, NaN, inf: not a measurement
  const Vec3f ray = live.rays[i];
  if (!(ray.z > 0.0f)) return kTrackNoMatch;
  const Vec3f point = transform_point(p.T_model_live, z * ray);
  Vec2f pixel;
  if (!project(model.camera, point, &pixel)) return kTrackNoMatch;
  const float u = std::floor(pixel.x + 0.5f), v = std::floor(pixel.y + 0.5f);
  if (!(u >= 0.0f && v >= 0.0f && u < static_cast<float>(model.camera.width) &&
        v < static_cast<float>(model.camera.height))) {
    return kTrackNoMatch;
  }
  const int j = static_cast<int>(v) * model.camera.width + static_cast<int>(u);
  const Vec3f q = model.points[j];
  if (!(q.z > 0.0f)) return kTrackNoMatch;
  if (model.creases != nullptr && model.creases[j] != 0) return kTrackOnCrease;
  const Vec3f n = model.normals[j];
  const Vec3f difference = point - q;
  if (!(dot(difference, difference) <= p.max_distance_m * p.max_distance_m)) return kTrackNoMatch;
  if (!(dot(rotate_vector(p.T_model_live, n_live), n) >= p.min_normal_cos)) return kTrackNoMatch;
  const Vec3f arm = p.inverse_scale * (point - p.centre);
  const Vec3f rotation = cross(arm, n);
  jacobian[0] = n.x;
  jacobian[1] = n.y;
  jacobian[2] = n.z;
  jacobian[3] = rotation.x;
  jacobian[4] = rotation.y;
  jacobian[5] = rotation.z;
  *residual = dot(n, difference);
  return kTrackInlier;
}

// The robust weight of a residual: Tukey's biweight (1 − (r/c)²)² within c and 0 beyond when
// tukey_m = c > 0, else Huber's (1 within huber_m, huber_m / |r| beyond) when huber_m > 0,
// else 1. Pixels a decoder misplaces (remnants of crease errors, the edges of the projector's
// shadows: tens of µm off) pull with a bounded force under Huber's and with none under Tukey's.
SLS_HOST_DEVICE inline float robust_weight(float residual, float huber_m, float tukey_m) {
  const float magnitude = std::fabs(residual);
  if (tukey_m > 0.0f) {
    const float q = magnitude / tukey_m;
    return q < 1.0f ? (1.0f - q * q) * (1.0f - q * q) : 0.0f;
  }
  return huber_m > 0.0f && magnitude > huber_m ? huber_m / magnitude : 1.0f;
}

// Adds one inlier's row to the sums (float per GPU thread, double on the CPU), weighted by
// its measurement weight times robust_weight of its residual. The residual sum and the count
// stay unweighted (the RMS test, the next reduction's scales).
template <typename T>
SLS_HOST_DEVICE inline void accumulate_track_row(const float jacobian[6], float residual, float huber_m, float tukey_m,
                                                 float measurement_weight, T sums[kTrackSums]) {
  const float weight = measurement_weight * robust_weight(residual, huber_m, tukey_m);
  int k = 0;
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c) {
      sums[k++] += static_cast<T>(weight * jacobian[r]) * static_cast<T>(jacobian[c]);
    }
  }
  for (int r = 0; r < 6; ++r) sums[kTrackJtr + r] += static_cast<T>(weight * jacobian[r]) * static_cast<T>(residual);
  sums[kTrackResidual2] += static_cast<T>(residual) * static_cast<T>(residual);
  sums[kTrackCount] += T(1);
}

// One live pixel's part of a reduction (both backends' loop body): its row when it is an
// inlier, a count when its match is on a crease.
template <typename T>
SLS_HOST_DEVICE inline void accumulate_track_pixel(const TrackLiveView& live, const TrackModelView& model,
                                                   const TrackParams& params, int i, T sums[kTrackSums]) {
  float jacobian[6];
  float residual = 0.0f, weight = 1.0f;
  const int outcome = track_pixel(live, model, params, i, jacobian, &residual, &weight);
  if (outcome == kTrackInlier) {
    accumulate_track_row(jacobian, residual, params.huber_m, params.tukey_m, weight, sums);
  } else if (outcome == kTrackOnCrease) {
    sums[kTrackCreaseCount] += T(1);
  }
}

// Where the model can be: the box of the volume it was raycast from (a volume's corner and
// edge lengths, its axes), and the guess that places a live pixel's point in it. What lies
// outside the box is in no raycast of it, so such a pixel cannot match whatever the pose: the
// overlap test counts only the pixels inside (a volume smaller than the view is not a lost
// frame for seeing more than it holds). active = false: every live pixel can match.
struct TrackRegion {
  bool active = false;
  Rigid3f T_volume_live;  // the guess, in the volume's frame (its corner, its axes)
  Vec3f size_m{0.0f, 0.0f, 0.0f};
};

SLS_HOST_DEVICE inline bool inside_region(const TrackRegion& region, Vec3f ray, float live_depth) {
  if (!region.active) return true;
  const Vec3f p = transform_point(region.T_volume_live, live_depth * ray);
  return p.x >= 0.0f && p.y >= 0.0f && p.z >= 0.0f && p.x <= region.size_m.x && p.y <= region.size_m.y &&
         p.z <= region.size_m.z;
}

// One pixel's contribution to the frame's statistics: the model point's moments about a
// reference (the centroid once known, so Σ|p − reference|² keeps its digits in float) and
// whether the live depth is valid, and inside the region (the pixel's ray: its point is
// ray · depth). sums: count, Σdx, Σdy, Σdz, Σ|d|² of d = p − reference over the model
// points, then the live pixels with a depth inside the region, then those outside.
template <typename T>
SLS_HOST_DEVICE inline void accumulate_frame_statistics(Vec3f model_point, float live_depth, Vec3f live_ray,
                                                        const TrackRegion& region, Vec3f reference,
                                                        T sums[kFrameSums]) {
  if (is_measured_depth(live_depth)) {
    sums[inside_region(region, live_ray, live_depth) ? kFrameLivePixels : kFrameLiveOutside] += T(1);
  }
  if (!(model_point.z > 0.0f)) return;
  const Vec3f d = model_point - reference;
  sums[0] += T(1);
  sums[1] += static_cast<T>(d.x);
  sums[2] += static_cast<T>(d.y);
  sums[3] += static_cast<T>(d.z);
  sums[4] += static_cast<T>(d.x) * static_cast<T>(d.x) + static_cast<T>(d.y) * static_cast<T>(d.y) +
             static_cast<T>(d.z) * static_cast<T>(d.z);
}

}  // namespace sls::fusion
