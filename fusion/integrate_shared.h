// Per-voxel TSDF / GTSDF integration, shared by the CPU and CUDA integrators (DESIGN.md
// sections 3 and 6). For frame n, a voxel at camera-frame depth z that projects (with the
// SLS camera model, distortion included) to pixel p:
//   d = D_n(p) - z,  f = clamp(d / δ, -1, 1),  ω = [D_n(p) valid and d >= -η]
//   A <- (W·A + ω f) / (W + ω),  W <- min(W + ω, W_max)        (the running average: TSDF)
// and, for GTSDF, T red-black Gauss-Seidel sweeps over the voxels observed this frame near
// the surface (ω = 1, |A| < 1), starting from U = A:
//   U <- (A + α Σ_ξ b_ξ U_ξ) / (1 + α Σ_ξ b_ξ),  b_ξ = φ'(s) / 2s,  s = |U_ξ - U|
// over the 6 axis neighbours ξ that have been observed (W > 0). Neighbours of a voxel have
// the other parity of i + j + k, so each half-sweep is race-free. α = 0 is exactly TSDF.
// A is the plain average of the raw f, the data term of the paper's functional (2), so a
// GTSDF volume keeps it in its own array (VolumeView::average): averaging the smoothed U of
// the last frame instead, as the printed eq. (12) reads, would smooth each voxel again on
// every one of its ~100 observations (fusion/README.md has the figures). A TSDF volume's A
// is its U.
#pragma once

#include <cmath>
#include <cstdint>

#include "fusion/depth_shared.h"
#include "fusion/volume_shared.h"
#include "sdk/core/camera_model_shared.h"

namespace sls::fusion {

// φ of the anisotropic term (the paper does not name one): b(s) = φ'(s) / 2s.
enum class Penalty : std::int32_t {
  kPeronaMalik = 0,   // Lorentzian: b = 1 / (1 + s²/κ²)
  kCharbonnier = 1,   // b = 1 / sqrt(1 + s²/κ²)
  kGemanMcClure = 2,  // b = 1 / (1 + s²/κ²)²
};

struct IntegrationParams {
  float truncation_m = 0.0f;          // δ
  float inverse_truncation_m = 0.0f;  // 1/δ: the per-voxel f = d/δ as a product, not a division
  float eta_m = 0.0f;                 // η > δ: voxels farther than η behind the surface are not updated
  float weight_max = 255.0f;          // W cap (255 for the compact format's uint8 weights)
  float alpha = 0.0f;                 // λβ; 0 = standard TSDF
  float kappa = 0.03f;                // κ, in units of U
  Penalty penalty = Penalty::kPeronaMalik;
};

// The depth frame as kernels see it: camera-frame z per pixel (metres, 0 = no measurement),
// row-major width x height, and where the camera is.
struct DepthFrameView {
  const float* depth_m = nullptr;
  int width = 0;
  int height = 0;
  CameraIntrinsicsF intrinsics{};
  Rigid3f T_camera_volume{};
};

// One voxel observed this frame near the surface: its index and running average A.
struct ActiveVoxel {
  std::uint32_t index;
  float average;
};

// The running-average update of voxel (i, j, k). Returns true when the voxel is active for
// the anisotropic sweeps (observed this frame and |A| < 1), with A in *average.
template <VoxelFormat F>
SLS_HOST_DEVICE inline bool integrate_voxel_as(const VolumeView& v, const IntegrationParams& p,
                                               const DepthFrameView& frame, int i, int j, int k, float* average) {
  const Vec3f point_camera = transform_point(frame.T_camera_volume, v.voxel_centre(i, j, k));
  Vec2f pixel;
  if (!project(frame.intrinsics, point_camera, &pixel)) return false;
  // Nearest pixel (pixel centres at integers).
  const float px = std::floor(pixel.x + 0.5f), py = std::floor(pixel.y + 0.5f);
  if (!(px >= 0.0f && py >= 0.0f && px < static_cast<float>(frame.width) && py < static_cast<float>(frame.height))) {
    return false;
  }
  // The pixel's index in 32 bits (a frame has < 2^31 pixels), its read by the read-only path.
  const float measured = load_read_only(
      frame.depth_m + (static_cast<std::uint32_t>(py) * static_cast<std::uint32_t>(frame.width) +
                       static_cast<std::uint32_t>(px)));
  if (!is_measured_depth(measured)) return false;
  const float d = measured - point_camera.z;
  if (d < -p.eta_m) return false;  // hidden behind the surface: no information
  const float f = std::fmax(-1.0f, std::fmin(1.0f, d * p.inverse_truncation_m));
  const std::size_t index = v.index(i, j, k);
  // W and A read together (A is not needed where W = 0, but a read costs less than waiting
  // for W before issuing it).
  const float weight = v.w_as<F>(index);
  const float stored = v.average_as<F>(index);
  const float previous = weight > 0.0f ? stored : 0.0f;
  const float a = (weight * previous + f) / (weight + 1.0f);
  v.set_average_as<F>(index, a);
  v.set_w_as<F>(index, std::fmin(weight + 1.0f, p.weight_max));
  *average = a;
  const bool near_surface = std::fabs(a) < 1.0f;
  v.set_u_as<F>(index, a);  // GTSDF's sweeps start from A
  if (near_surface) v.mark_surface(i, j, k);
  return near_surface;
}

SLS_HOST_DEVICE inline bool integrate_voxel(const VolumeView& v, const IntegrationParams& p,
                                            const DepthFrameView& frame, int i, int j, int k, float* average) {
  return v.format == VoxelFormat::kFloat32 ? integrate_voxel_as<VoxelFormat::kFloat32>(v, p, frame, i, j, k, average)
                                           : integrate_voxel_as<VoxelFormat::kCompact>(v, p, frame, i, j, k, average);
}

// Written with q = κ² / (κ² + s²), which is 1 / (1 + s²/κ²) by one division where that takes
// two (a sweep computes it for each of ~6 neighbours of millions of voxels).
SLS_HOST_DEVICE inline float penalty_weight(Penalty penalty, float s, float kappa) {
  const float kappa_squared = kappa * kappa;
  const float q = kappa_squared / (kappa_squared + s * s);
  switch (penalty) {
    case Penalty::kCharbonnier:
      return std::sqrt(q);
    case Penalty::kGemanMcClure:
      return q * q;
    case Penalty::kPeronaMalik:
    default:
      return q;
  }
}

// One Gauss-Seidel step of an active voxel: its new U from A and its observed neighbours.
// The voxel's (i, j, k) from its 32-bit index by 32-bit divisions, and its neighbours' indices
// by the strides: a 64-bit division is a long subroutine on a GPU, and this runs for millions
// of voxels per half-sweep (the same voxels and the same arithmetic on U as index() gives).
template <VoxelFormat F>
SLS_HOST_DEVICE inline float relax_voxel_as(const VolumeView& v, const IntegrationParams& p, ActiveVoxel voxel) {
  const std::uint32_t nx = static_cast<std::uint32_t>(v.nx);
  const std::uint32_t plane = nx * static_cast<std::uint32_t>(v.ny);  // a volume holds at most 2^32 voxels (volume.cpp)
  const std::uint32_t k = voxel.index / plane;
  const std::uint32_t rest = voxel.index - k * plane;
  const std::uint32_t j = rest / nx;
  const std::uint32_t i = rest - j * nx;
  const std::size_t index = voxel.index;
  // The 6 axis neighbours in index()'s order: -i, +i, -j, +j, -k, +k, each where the volume has it.
  const bool has[6] = {i > 0u,
                       i + 1u < nx,
                       j > 0u,
                       j + 1u < static_cast<std::uint32_t>(v.ny),
                       k > 0u,
                       k + 1u < static_cast<std::uint32_t>(v.nz)};
  const std::size_t stride[3] = {1u, nx, plane};
  // Every read first (the voxel itself stands in for a neighbour the volume lacks), the sums
  // after in the same order: a GPU thread has the 13 reads in flight together.
  const float u = v.u_as<F>(index);
  float neighbour_w[6], neighbour_u[6];
  for (int n = 0; n < 6; ++n) {
    const std::size_t neighbour =
        !has[n] ? index : (n & 1) != 0 ? index + stride[n >> 1] : index - stride[n >> 1];
    neighbour_w[n] = v.w_as<F>(neighbour);
    neighbour_u[n] = v.u_as<F>(neighbour);
  }
  float numerator = voxel.average;
  float denominator = 1.0f;
  for (int n = 0; n < 6; ++n) {
    if (!has[n] || !(neighbour_w[n] > 0.0f)) continue;
    const float un = neighbour_u[n];
    const float b = p.alpha * penalty_weight(p.penalty, std::fabs(un - u), p.kappa);
    numerator += b * un;
    denominator += b;
  }
  return numerator / denominator;
}

SLS_HOST_DEVICE inline float relax_voxel(const VolumeView& v, const IntegrationParams& p, ActiveVoxel voxel) {
  return v.format == VoxelFormat::kFloat32 ? relax_voxel_as<VoxelFormat::kFloat32>(v, p, voxel)
                                           : relax_voxel_as<VoxelFormat::kCompact>(v, p, voxel);
}

// Element n of a half-sweep over one parity's active voxels (both backends' parallel_for).
SLS_HOST_DEVICE inline void relax_active_voxel(const VolumeView& v, const IntegrationParams& p,
                                               const ActiveVoxel* active, std::size_t n) {
  const ActiveVoxel voxel = active[n];
  v.set_u(voxel.index, relax_voxel(v, p, voxel));
}

// Red (0) or black (1): the parity of i + j + k.
SLS_HOST_DEVICE inline int voxel_parity(int i, int j, int k) { return (i + j + k) & 1; }

}  // namespace sls::fusion
