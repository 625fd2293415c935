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

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::fusion {

// The reduced sums: 21 of the upper triangle of JᵀJ (row-major: (0,0) (0,1) .. (0,5) (1,1) ..),
// 6 of Jᵀr, Σr² and the inlier count.
constexpr int kTrackSums = 29;
constexpr int kTrackJtr = 21;
constexpr int kTrackResidual2 = 27;
constexpr int kTrackCount = 28;
// The frame's statistics (accumulate_frame_statistics): the model's moments for the centre
// and scale, and the live pixels with a depth.
constexpr int kFrameSums = 6;

// A depth step between neighbouring pixels larger than this many pixel footprints (z / fx)
// is a discontinuity (an occluding edge), not a slope: a 2x2 block keeps the nearest
// surface's depths and a live normal is not formed across it. 8 footprints is a face at 83°
// to the view.
constexpr float kDiscontinuityFootprints = 8.0f;

SLS_HOST_DEVICE inline bool valid_depth(float z) { return z > 0.0f && z < 3.0e38f; }

// One pixel of pyramid level l + 1 from the 2x2 block (2x, 2y) .. (2x+1, 2y+1) of level l
// (fine_width x fine_height, focal length fine_fx): the average of the block's valid depths
// within kDiscontinuityFootprints footprints of the nearest; 0 when none is valid. The coarse
// pixel's centre is the block's centre, so the coarse camera is fx/2, (cx − 0.5)/2.
SLS_HOST_DEVICE inline float downsample_depth(const float* fine, int fine_width, int fine_height, float fine_fx,
                                              int x, int y) {
  float z[4];
  int n = 0;
  float nearest = 3.0e38f;
  for (int dy = 0; dy < 2; ++dy) {
    for (int dx = 0; dx < 2; ++dx) {
      const int fx = 2 * x + dx, fy = 2 * y + dy;
      if (fx >= fine_width || fy >= fine_height) continue;
      const float value = fine[static_cast<long long>(fy) * fine_width + fx];
      if (!valid_depth(value)) continue;
      z[n++] = value;
      nearest = value < nearest ? value : nearest;
    }
  }
  if (n == 0) return 0.0f;
  const float step = kDiscontinuityFootprints * nearest / fine_fx;
  float sum = 0.0f;
  int count = 0;
  for (int i = 0; i < n; ++i) {
    if (z[i] - nearest <= step) {
      sum += z[i];
      ++count;
    }
  }
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
SLS_HOST_DEVICE inline Vec3f live_normal(const float* depth, const Vec3f* rays, int width, int height, float fx,
                                         float baseline_m, int x, int y) {
  const Vec3f none{0.0f, 0.0f, 0.0f};
  if (x < 0 || y < 0 || x >= width || y >= height) return none;
  const long long i = static_cast<long long>(y) * width + x;
  const float z = depth[i];
  if (!valid_depth(z) || !(rays[i].z > 0.0f)) return none;
  const float footprint = z / fx;
  int b = static_cast<int>(baseline_m / footprint + 0.5f);
  b = b < 1 ? 1 : (b > kMaxNormalBaselinePx ? kMaxNormalBaselinePx : b);
  if (x < b || y < b || x + b >= width || y + b >= height) return none;
  const long long neighbours[4] = {i - b, i + b, i - static_cast<long long>(b) * width,
                                   i + static_cast<long long>(b) * width};
  const float step = kDiscontinuityFootprints * footprint * static_cast<float>(b);
  Vec3f v[4];
  for (int k = 0; k < 4; ++k) {
    const float zk = depth[neighbours[k]];
    const Vec3f ray = rays[neighbours[k]];
    if (!valid_depth(zk) || !(ray.z > 0.0f) || !(std::fabs(zk - z) <= step)) return none;
    v[k] = zk * ray;
  }
  Vec3f n = cross(v[1] - v[0], v[3] - v[2]);
  const float length = norm(n);
  if (!(length > 0.0f)) return none;
  n = (1.0f / length) * n;
  if (dot(n, z * rays[i]) > 0.0f) n = -n;
  return n;
}

// The live level as the association reads it.
struct TrackLiveView {
  const float* depth = nullptr;   // camera-frame z, 0 = none
  const Vec3f* rays = nullptr;    // the level's ray map (z = 1; {0,0,0} where invalid)
  const Vec3f* normals = nullptr; // live_normal per pixel
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
};

struct TrackParams {
  Rigid3f T_model_live;         // the current estimate
  float max_distance_m = 0.0f;  // of the level
  float min_normal_cos = 0.0f;
  Vec3f centre{0.0f, 0.0f, 0.0f};  // c (model frame)
  float inverse_scale = 1.0f;      // 1 / L
  float huber_m = 0.0f;            // Huber scale of the residuals (0: plain least squares)
};

// One live pixel: associates it with the model and, for an inlier, returns the Jacobian
// row J (d r / d[ρ, ω']) and the point-to-plane residual r = n · (T p − q) in metres.
SLS_HOST_DEVICE inline bool track_pixel(const TrackLiveView& live, const TrackModelView& model, const TrackParams& p,
                                        int x, int y, float jacobian[6], float* residual) {
  const long long i = static_cast<long long>(y) * live.width + x;
  const float z = live.depth[i];
  if (!valid_depth(z)) return false;
  const Vec3f n_live = live.normals[i];
  if (n_live.x == 0.0f && n_live.y == 0.0f && n_live.z == 0.0f) return false;
  const Vec3f ray = live.rays[i];
  if (!(ray.z > 0.0f)) return false;
  const Vec3f point = transform_point(p.T_model_live, z * ray);
  Vec2f pixel;
  if (!project(model.camera, point, &pixel)) return false;
  const float u = std::floor(pixel.x + 0.5f), v = std::floor(pixel.y + 0.5f);
  if (!(u >= 0.0f && v >= 0.0f && u < static_cast<float>(model.camera.width) &&
        v < static_cast<float>(model.camera.height))) {
    return false;
  }
  const long long j = static_cast<long long>(v) * model.camera.width + static_cast<long long>(u);
  const Vec3f q = model.points[j];
  if (!(q.z > 0.0f)) return false;
  const Vec3f n = model.normals[j];
  const Vec3f difference = point - q;
  if (!(dot(difference, difference) <= p.max_distance_m * p.max_distance_m)) return false;
  if (!(dot(rotate_vector(p.T_model_live, n_live), n) >= p.min_normal_cos)) return false;
  const Vec3f arm = p.inverse_scale * (point - p.centre);
  const Vec3f rotation = cross(arm, n);
  jacobian[0] = n.x;
  jacobian[1] = n.y;
  jacobian[2] = n.z;
  jacobian[3] = rotation.x;
  jacobian[4] = rotation.y;
  jacobian[5] = rotation.z;
  *residual = dot(n, difference);
  return true;
}

// Adds one inlier's row to the sums (float per GPU thread, double on the CPU), weighted by
// Huber's function of its residual (weight 1 within huber_m, huber_m / |r| beyond): pixels a
// decoder misplaces (knurl creases, where one pixel mixes two faces) pull with a bounded force
// instead of a quadratic one. The residual sum and the count stay unweighted (the RMS test).
template <typename T>
SLS_HOST_DEVICE inline void accumulate_track_row(const float jacobian[6], float residual, float huber_m,
                                                 T sums[kTrackSums]) {
  const float magnitude = std::fabs(residual);
  const float weight = huber_m > 0.0f && magnitude > huber_m ? huber_m / magnitude : 1.0f;
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

// One pixel's contribution to the frame's statistics: the model point's moments about a
// reference (the centroid once known, so Σ|p − reference|² keeps its digits in float) and
// whether the live depth is valid. sums: count, Σdx, Σdy, Σdz, Σ|d|² of d = p − reference over
// the model points, then the live pixels with a depth.
template <typename T>
SLS_HOST_DEVICE inline void accumulate_frame_statistics(Vec3f model_point, float live_depth, Vec3f reference,
                                                        T sums[kFrameSums]) {
  if (valid_depth(live_depth)) sums[5] += T(1);
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
