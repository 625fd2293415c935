// Depth frames into the volume: TSDF (α = 0) or the paper's GTSDF (DESIGN.md section 3), on
// the CPU or a CUDA GPU over the per-voxel code of integrate_shared.h.
//
//   Integrator integrator(Device::cuda(), IntegrationOptions::gtsdf());
//   IntegrationStats stats = integrator.integrate(volume, depth_m, camera, T_world_camera);
#pragma once

#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "fusion/depth_band_shared.h"
#include "fusion/integrate_shared.h"
#include "fusion/volume.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/device.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/image.h"
#include "sdk/core/pose.h"

namespace sls::fusion {

struct IntegrationOptions {
  // δ and η in voxels of the volume (so one setting fits any voxel size).
  double truncation_voxels = 4.0;   // δ: f = clamp(d / δ, -1, 1)
  double eta_voxels = 6.0;          // η > δ: hidden voxels beyond η behind the surface untouched
  int weight_max = 255;             // W cap: a moving volume keeps adapting (<= 255 for compact voxels)
  // The anisotropic term: α = λβ (0 < β <= 1/6; λ = 0 is standard TSDF).
  double lambda = 0.0;
  double beta = 1.0 / 6.0;
  double kappa = 0.2;               // κ of φ, in units of U (δ)
  Penalty penalty = Penalty::kPeronaMalik;
  int iterations = 3;               // T Gauss-Seidel sweeps (each a red and a black half-sweep)
  // Most active voxels (per parity) kept for the sweeps; beyond it, voxels keep their running
  // average (counted in IntegrationStats::overflow). 0: the smaller of the volume's voxels and 2^25.
  std::size_t active_capacity = 0;

  static IntegrationOptions tsdf();   // λ = 0
  static IntegrationOptions gtsdf();  // λ = 4, β = 1/6 (α = 2/3), κ = 0.03, Geman-McClure, T = 3
  bool is_gtsdf() const { return lambda > 0.0 && iterations > 0; }
  // The volumes these options need: GTSDF keeps the running average apart from U (TSDF
  // integrates into either kind).
  AverageStorage average_storage() const {
    return is_gtsdf() ? AverageStorage::kSeparate : AverageStorage::kInU;
  }
  // Throws sls::Error(kInvalidArgument) naming the bad value.
  void validate(VoxelFormat format) const;
  IntegrationParams params(double voxel_size_m) const;
};

// "tsdf" or "gtsdf" -> options; sls::Error(kInvalidArgument) otherwise.
IntegrationOptions parse_fusion_method(const std::string& name);
// "perona-malik", "charbonnier", "geman-mcclure".
Penalty parse_penalty(const std::string& name);
const char* penalty_name(Penalty penalty);

// The voxels a frame can change: the camera frustum between the nearest measured depth minus
// η and the farthest plus η, as an index box of the volume (empty when it misses). Voxels in
// front of that band are free space a standard TSDF would carve to +1; skipping them leaves
// their earlier value, which is what a band-limited integrator keeps (voxblox-style).
struct VoxelBox {
  int i0 = 0, j0 = 0, k0 = 0;  // first voxel
  int i1 = 0, j1 = 0, k1 = 0;  // one past the last
  bool empty() const { return i1 <= i0 || j1 <= j0 || k1 <= k0; }
  std::size_t count() const {
    return empty() ? 0 : static_cast<std::size_t>(i1 - i0) * static_cast<std::size_t>(j1 - j0) *
                             static_cast<std::size_t>(k1 - k0);
  }
};
VoxelBox frustum_voxel_box(const VolumeGeometry& geometry, const CameraIntrinsics& camera, const Pose& T_world_camera,
                           double near_m, double far_m);

// The depth band a frame is integrated over: its measured range less isolated outliers,
// [q − s/2, Q + s/2] with q, Q the 0.1 % and 99.9 % quantiles of the valid depths sampled on
// every kDepthBandStride-th pixel, and s = Q − q (under 1000 samples: [min, max]). A decoder
// outlier metres off the surface would otherwise make the frame visit the whole frustum and,
// lying behind the surface, carve free space through it. {0, 0} for a map with no valid depth.
// The constants and the rule: fusion/depth_band_shared.h.
std::pair<double, double> integration_depth_band(const Image32f& depth_m);

// The depth range a frame is integrated over (near_m, far_m: metres along the optical axis).
struct DepthBand {
  double near_m = 0.0;
  double far_m = 0.0;
};

// What a frame loop needs of a depth map beside the map itself.
struct DepthMapSummary {
  std::size_t valid_pixels = 0;       // > 0 and finite
  double near_m = 0.0, far_m = 0.0;   // integration_depth_band's
};

// The GPU memory an Integrator allocates beside a volume of `voxel_count` voxels: GTSDF's
// active-voxel lists (two parities, active_capacity entries each), their sorted copy and the
// sort's temporary storage, taken as one more list (CUB's radix sort needs about that). 0 for
// TSDF. For sizing a volume under a memory budget (ScanSessionOptions::max_gpu_bytes).
std::size_t integration_gpu_bytes(const IntegrationOptions& options, std::size_t voxel_count);

struct IntegrationStats {
  std::size_t active_voxels = 0;  // observed this frame with |A| < 1 (the sweeps' voxels)
  std::size_t overflow = 0;       // active voxels beyond the capacity (kept their average)
  std::size_t voxels_visited = 0; // the frustum box's voxels
};

class Integrator {
 public:
  // On a GPU, work is queued on `stream` (a session's; one of its own when none is given).
  Integrator(const Device& device, const IntegrationOptions& options, const GpuStream& stream = {});
  ~Integrator();
  Integrator(Integrator&&) noexcept;
  Integrator& operator=(Integrator&&) noexcept;

  const IntegrationOptions& options() const;
  const Device& device() const;

  // Integrates one depth map (camera-frame z in metres, 0 = none; the camera's size) taken
  // from T_world_camera, wherever it lives: a CPU integrator reads a host map; a GPU one reads a
  // map on its device in place (MemoryType::kDevice: the decoder's output) and uploads a host
  // map first. Over `band` when given (summarize()'s; far_m infinite: the whole frustum), else
  // over the map's integration_depth_band. The volume must live on the integrator's device.
  // Throws sls::Error(kInvalidArgument) for a depth map of another size than the camera, or one
  // on the GPU for a CPU integrator.
  IntegrationStats integrate(Volume& volume, const Image32f& depth_m, const CameraIntrinsics& camera,
                             const Pose& T_world_camera, std::optional<DepthBand> band = std::nullopt);
  // A depth map's valid pixels and integration band, summarised where it lives: on the host
  // as integration_depth_band; on the GPU (a GPU integrator) from the same every
  // kDepthBandStride-th pixel (that sample, 0.4 MB at 12 megapixels, comes down; the 48 MB map
  // does not), waiting for it.
  DepthMapSummary summarize(const Image32f& depth_m);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The frame's view for the kernels: intrinsics in float and T_camera_volume.
DepthFrameView make_depth_frame_view(const float* depth_m, const CameraIntrinsics& camera, const Pose& T_world_camera,
                                     const VolumeGeometry& geometry);

}  // namespace sls::fusion
