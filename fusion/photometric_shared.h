// Per-pixel code of the tracker's optional photometric term (fusion/tracker.h,
// TrackingOptions::photometric_weight), shared by the CPU and CUDA backends (DESIGN.md
// section 6): the texture pyramid, a frame's mean texture, and one reference pixel's
// frame-to-frame photometric residual with its Jacobian.
//
// Kintinuous (Whelan et al. 2013, "Robust real-time visual odometry for dense RGB-D
// mapping"): E = E_icp + w·E_rgb, one 6x6 Gauss–Newton system per iteration. Each pixel u of
// the reference frame (the previous one: its depth, texture and pose T_world_ref) with a depth
// and a significant texture gradient is back-projected, p = depth(u)·ray(u), moved into the
// live camera, p' = T_live_ref·p with T_live_ref = T_model_live⁻¹·T_model_ref, and projected
// with the full camera model (distortion included):
//   r = (gain · I_live(π(p')) − I_ref(u)) / mean_ref        (bilinear I_live)
// Intensity normalisation: the texture is the structured-light stack's white − black (the
// session's choice: no ambient light, no camera black level, so it is albedo × irradiance);
// the projector moves with the camera, so the irradiance of a point changes from frame to
// frame. `gain` is the ratio of the two frames' mean intensities over the matched pixels
// (measured by the previous reduction; the frames' means over their depth pixels for the
// first), which takes out the global change; dividing by the reference's mean makes r, the
// gradient threshold and the Huber scale unit-free (fractions of the mean intensity).
// Occlusions: a warped point whose live depth (nearest pixel) differs by more than the
// level's ICP distance is not matched.
//
// Jacobian, in the ICP's parameterisation (track_shared.h: T_model_live ← δT·T_model_live,
// δT = Tr(c)·exp([ρ, ω'/L])·Tr(−c)) so the normal matrices add: the live point is
// T_model_live⁻¹·δT⁻¹·q with q = T_model_ref·p the reference point in the model frame, so
//   dr/d[ρ, ω'] = −[h, a × h],  h = R_model_live · (dπ/dp')ᵀ · ∇I_live,  a = (q − c) / L,
// the ICP row [n, a × n] with −h for the normal.
#pragma once

#include <cmath>

#include "fusion/track_shared.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::fusion {

// The photometric reduction: the sums of kTrackSums (JᵀJ, Jᵀr, Σr² and the count over the
// selected pixels, in the same layout), then over every matched pixel (selected or not): the
// count and the sums of the live and reference intensities (the gain).
constexpr int kPhotometricMatchedCount = kTrackSums;
constexpr int kPhotometricLiveSum = kTrackSums + 1;
constexpr int kPhotometricReferenceSum = kTrackSums + 2;
constexpr int kPhotometricSums = kTrackSums + 3;
// A frame's texture over its depth pixels (accumulate_texture_statistics): Σ texture, count.
constexpr int kTextureSums = 2;

// One pixel of texture level l + 1: the mean of the 2x2 block (2x, 2y) .. (2x+1, 2y+1) of
// level l (the pixels inside the image), the same blocks as downsample_depth.
SLS_HOST_DEVICE inline float downsample_texture(const float* fine, int fine_width, int fine_height, int x, int y) {
  float sum = 0.0f;
  int count = 0;
  for (int dy = 0; dy < 2; ++dy) {
    for (int dx = 0; dx < 2; ++dx) {
      const int fx = 2 * x + dx, fy = 2 * y + dy;
      if (fx >= fine_width || fy >= fine_height) continue;
      sum += fine[static_cast<long long>(fy) * fine_width + fx];
      ++count;
    }
  }
  return count > 0 ? sum / static_cast<float>(count) : 0.0f;
}

template <typename T>
SLS_HOST_DEVICE inline void accumulate_texture_statistics(float texture, float depth, T sums[kTextureSums]) {
  if (!is_measured_depth(depth)) return;
  sums[0] += static_cast<T>(texture);
  sums[1] += T(1);
}

// Bilinear sample at (u, v), 0 <= u <= width − 2, 0 <= v <= height − 2 (the caller checks).
SLS_HOST_DEVICE inline float sample_bilinear(const float* image, int width, float u, float v) {
  const float fu = std::floor(u), fv = std::floor(v);
  const int x = static_cast<int>(fu), y = static_cast<int>(fv);
  const float ax = u - fu, ay = v - fv;
  const float* row = image + static_cast<long long>(y) * width + x;
  const float top = row[0] + ax * (row[1] - row[0]);
  const float bottom = row[width] + ax * (row[width + 1] - row[width]);
  return top + ay * (bottom - top);
}

// One level of a frame as the photometric term reads it.
struct PhotometricLevelView {
  const float* texture = nullptr;  // linear intensity (white − black), any scale
  const float* depth = nullptr;    // camera-frame z, 0 = none
  const Vec3f* rays = nullptr;     // the level's ray map (the reference's back-projection)
  int width = 0;
  int height = 0;
};

struct PhotometricParams {
  Rigid3f T_live_ref;      // the current estimate
  Rigid3f T_model_ref;     // fixed over the frame
  Mat3T<float> R_model_live;  // the current estimate's rotation
  CameraIntrinsicsF camera;   // the level's
  Vec3f centre{0.0f, 0.0f, 0.0f};  // c and 1 / L of the ICP's parameterisation
  float inverse_scale = 1.0f;
  float gain = 1.0f;               // multiplies I_live
  float inverse_mean = 1.0f;       // 1 / the reference's mean intensity
  float min_gradient = 0.0f;       // selection: |∇I_ref| / mean_ref per pixel of the level
  float max_depth_difference_m = 0.0f;  // occlusion test
  float huber = 0.0f;              // Huber scale of r (0: plain least squares)
};

enum PhotometricOutcome : int {
  kPhotometricNone = 0,     // no depth, leaves the live image, or occluded
  kPhotometricMatched = 1,  // matched (counts for the gain), texture too flat for a row
  kPhotometricRow = 2,      // matched and selected: jacobian and residual are set
};

// One reference pixel (x, y) of the level: the live and reference intensities when matched
// (for the gain), and for a selected pixel the Jacobian row d r / d[ρ, ω'] and r.
SLS_HOST_DEVICE inline int photometric_pixel(const PhotometricLevelView& ref, const PhotometricLevelView& live,
                                             const PhotometricParams& p, int x, int y, float jacobian[6],
                                             float* residual, float* live_value, float* ref_value) {
  if (x < 1 || y < 1 || x + 1 >= ref.width || y + 1 >= ref.height) return kPhotometricNone;
  const long long i = static_cast<long long>(y) * ref.width + x;
  const float z = ref.depth[i];
  if (!is_measured_depth(z)) return kPhotometricNone;
  const Vec3f ray = ref.rays[i];
  if (!(ray.z > 0.0f)) return kPhotometricNone;
  const Vec3f point_ref = z * ray;
  const Vec3f point = transform_point(p.T_live_ref, point_ref);
  Vec2f pixel;
  if (!project(p.camera, point, &pixel)) return kPhotometricNone;
  // Inside by a pixel: the bilinear samples of the central differences at u ± 1, v ± 1.
  if (!(pixel.x >= 1.0f && pixel.y >= 1.0f && pixel.x < static_cast<float>(live.width - 2) &&
        pixel.y < static_cast<float>(live.height - 2))) {
    return kPhotometricNone;
  }
  const int nearest_x = static_cast<int>(std::floor(pixel.x + 0.5f));
  const int nearest_y = static_cast<int>(std::floor(pixel.y + 0.5f));
  const float live_z = live.depth[static_cast<long long>(nearest_y) * live.width + nearest_x];
  if (!is_measured_depth(live_z) || !(std::fabs(live_z - point.z) <= p.max_depth_difference_m)) {
    return kPhotometricNone;
  }
  const float i_live = sample_bilinear(live.texture, live.width, pixel.x, pixel.y);
  const float i_ref = ref.texture[i];
  *live_value = i_live;
  *ref_value = i_ref;
  // Kintinuous uses only pixels with a significant gradient: the reference's, so the set is
  // fixed over the frame's iterations.
  const float gx_ref = 0.5f * (ref.texture[i + 1] - ref.texture[i - 1]) * p.inverse_mean;
  const float gy_ref = 0.5f * (ref.texture[i + ref.width] - ref.texture[i - ref.width]) * p.inverse_mean;
  if (!(gx_ref * gx_ref + gy_ref * gy_ref >= p.min_gradient * p.min_gradient)) return kPhotometricMatched;

  const float scale = p.gain * p.inverse_mean;
  *residual = (p.gain * i_live - i_ref) * p.inverse_mean;
  const float gx = 0.5f * scale *
                   (sample_bilinear(live.texture, live.width, pixel.x + 1.0f, pixel.y) -
                    sample_bilinear(live.texture, live.width, pixel.x - 1.0f, pixel.y));
  const float gy = 0.5f * scale *
                   (sample_bilinear(live.texture, live.width, pixel.x, pixel.y + 1.0f) -
                    sample_bilinear(live.texture, live.width, pixel.x, pixel.y - 1.0f));
  // (dπ/dp')ᵀ ∇I: pixel = K · distort(n), n = (x/z, y/z).
  const float inverse_z = 1.0f / point.z;
  const Vec2f n{point.x * inverse_z, point.y * inverse_z};
  float d[4];
  distortion_jacobian(p.camera, n, d);
  const float ex = p.camera.fx * gx, ey = p.camera.fy * gy;
  const float di_dnx = d[0] * ex + d[2] * ey, di_dny = d[1] * ex + d[3] * ey;  // Dᵀ e: dI/dn
  const Vec3f g{di_dnx * inverse_z, di_dny * inverse_z, -(di_dnx * n.x + di_dny * n.y) * inverse_z};
  const Vec3f h = p.R_model_live * g;
  const Vec3f arm = p.inverse_scale * (transform_point(p.T_model_ref, point_ref) - p.centre);
  const Vec3f rotation = cross(arm, h);
  jacobian[0] = -h.x;
  jacobian[1] = -h.y;
  jacobian[2] = -h.z;
  jacobian[3] = -rotation.x;
  jacobian[4] = -rotation.y;
  jacobian[5] = -rotation.z;
  return kPhotometricRow;
}

// Adds one reference pixel's outcome to the photometric sums (the row Huber-weighted as
// accumulate_track_row does).
template <typename T>
SLS_HOST_DEVICE inline void accumulate_photometric(int outcome, const float jacobian[6], float residual,
                                                   float live_value, float ref_value, float huber,
                                                   T sums[kPhotometricSums]) {
  if (outcome == kPhotometricNone) return;
  sums[kPhotometricMatchedCount] += T(1);
  sums[kPhotometricLiveSum] += static_cast<T>(live_value);
  sums[kPhotometricReferenceSum] += static_cast<T>(ref_value);
  if (outcome == kPhotometricRow) accumulate_track_row(jacobian, residual, huber, 0.0f, 1.0f, sums);
}

}  // namespace sls::fusion
