// Per-voxel resampling of the moving volume (DESIGN.md sections 3 and 6), shared by the CPU
// loop and the CUDA kernel (fusion/moving_volume.cpp, fusion/cuda/resample.cu): voxel
// (i, j, k) of the volume at its new pose takes the old volume's field at its centre.
//
//   g  = G * (i, j, k)           the centre in the old volume's grid coordinates (voxel centres
//                                at integers; G = the old-from-new transform in grid units)
//   U  = Σ_c w_c U_c / Σ_c w_c   over the 8 old voxels c around g that are observed (W_c > 0),
//                                w_c their trilinear weights (renormalised: the unobserved ones
//                                take no part, so U is never pulled towards a made-up value)
//   A  = Σ_c w_c A_c / Σ_c w_c   the same for the running average, where the volume keeps it
//   W  = round(Σ_c w_c W_c / Σ_c w_c), at least 1: the weights carried, interpolated the same
//                                way and rounded to a whole count in both formats (weights are
//                                observation counts; uint8 in the compact format)
//
// The rule for "observed": the observed corners must carry at least half of the trilinear
// weight (Σ_c w_c >= kResampleMinSupport = 0.5). Then W >= 1 always (an observed corner
// contributes meaningfully exactly when the voxel is kept), and the observed region neither
// grows nor shrinks over repeated moves: along one axis the 0.5 rule puts its border half way
// between the last observed voxel centre and the next, which is where the old volume's own
// box ends (a voxel whose centre lies outside the old volume's box is never observed).
// Otherwise the voxel is unobserved: W = 0, U = 1.
// A voxel kept with |U| < 1 flags its surface bricks (VolumeView::mark_surface), as the
// integrator does; the destination's flags are cleared before a resample.
//
// Grid coordinates within kResampleSnap of an integer are snapped to it, so a move by whole
// voxels without rotation copies every voxel bit for bit.
#pragma once

#include <cmath>

#include "fusion/volume_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::fusion {

constexpr float kResampleMinSupport = 0.5f;
constexpr float kResampleSnap = 1e-4f;  // voxels

SLS_HOST_DEVICE inline float snap_to_grid(float g) {
  const float nearest = std::floor(g + 0.5f);
  return std::fabs(g - nearest) < kResampleSnap ? nearest : g;
}

// Resamples voxel (i, j, k) of `to` from `from` (same voxel size); grid_from_to maps `to`'s
// grid coordinates to `from`'s. F is `from`'s format: its 24 reads test none.
template <VoxelFormat F>
SLS_HOST_DEVICE inline void resample_voxel_from(const VolumeView& from, const VolumeView& to,
                                                const Rigid3f& grid_from_to, int i, int j, int k) {
  const std::size_t out = to.index(i, j, k);
  const Vec3f g = transform_point(grid_from_to, Vec3f{static_cast<float>(i), static_cast<float>(j),
                                                      static_cast<float>(k)});
  const float gx = snap_to_grid(g.x), gy = snap_to_grid(g.y), gz = snap_to_grid(g.z);
  // Far outside (or not finite): no corner can be in the old volume (also keeps the int casts defined).
  if (!(gx > -1.0f && gy > -1.0f && gz > -1.0f && gx < static_cast<float>(from.nx) &&
        gy < static_cast<float>(from.ny) && gz < static_cast<float>(from.nz))) {
    to.set_u(out, 1.0f);
    to.set_average(out, 1.0f);
    to.set_w(out, 0.0f);
    return;
  }
  const float fx = std::floor(gx), fy = std::floor(gy), fz = std::floor(gz);
  const int i0 = static_cast<int>(fx), j0 = static_cast<int>(fy), k0 = static_cast<int>(fz);
  const float tx = gx - fx, ty = gy - fy, tz = gz - fz;
  float support = 0.0f, sum_u = 0.0f, sum_a = 0.0f, sum_w = 0.0f;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    const float weight = (dx != 0 ? tx : 1.0f - tx) * (dy != 0 ? ty : 1.0f - ty) * (dz != 0 ? tz : 1.0f - tz);
    if (!(weight > 0.0f) || !from.contains(i0 + dx, j0 + dy, k0 + dz)) continue;
    const std::size_t index = from.index(i0 + dx, j0 + dy, k0 + dz);
    const float w = from.w_as<F>(index);
    if (!(w > 0.0f)) continue;
    support += weight;
    sum_u += weight * from.u_as<F>(index);
    sum_a += weight * from.average_as<F>(index);
    sum_w += weight * w;
  }
  if (!(support >= kResampleMinSupport)) {
    to.set_u(out, 1.0f);
    to.set_average(out, 1.0f);
    to.set_w(out, 0.0f);
    return;
  }
  const float inverse_support = 1.0f / support;  // one division for the three averages
  const float u = std::fmax(-1.0f, std::fmin(1.0f, sum_u * inverse_support));
  const float w = std::fmax(1.0f, std::floor(sum_w * inverse_support + 0.5f));
  to.set_u(out, u);
  to.set_average(out, std::fmax(-1.0f, std::fmin(1.0f, sum_a * inverse_support)));
  to.set_w(out, w);
  if (std::fabs(u) < 1.0f) to.mark_surface(i, j, k);
}

SLS_HOST_DEVICE inline void resample_voxel(const VolumeView& from, const VolumeView& to, const Rigid3f& grid_from_to,
                                           int i, int j, int k) {
  if (from.format == VoxelFormat::kFloat32) {
    resample_voxel_from<VoxelFormat::kFloat32>(from, to, grid_from_to, i, j, k);
  } else {
    resample_voxel_from<VoxelFormat::kCompact>(from, to, grid_from_to, i, j, k);
  }
}

}  // namespace sls::fusion
