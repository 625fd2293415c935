// Internal: what the integrator's CPU and GPU halves share (fusion/integrator.cpp,
// fusion/cuda/integrator_gpu.cpp).
#pragma once

#include <algorithm>
#include <cstddef>
#include <iterator>
#include <utility>
#include <vector>

#include "fusion/integrator.h"

namespace sls::fusion::detail {

// The entries of each parity's active-voxel list (IntegrationOptions::active_capacity, or by
// default 2^25 or the volume's voxels, whichever is fewer).
std::size_t active_capacity(const IntegrationOptions& options, std::size_t voxel_count);

// The box of voxels within η of the measured range [min_depth_m, max_depth_m].
VoxelBox band_box(const VolumeGeometry& geometry, const CameraIntrinsics& camera, const Pose& T_world_camera,
                  double min_depth_m, double max_depth_m, const IntegrationOptions& options);

// integration_depth_band's rule on its sample (the valid depths of every kDepthBandStride-th
// pixel); under kDepthBandMinSamples samples the map's whole valid range, which `range()` gives
// as [lo, hi] (hi 0: nothing valid).
template <typename Range>
std::pair<double, double> band_of_sample(std::vector<float>& sample, const Range& range) {
  if (sample.size() < kDepthBandMinSamples) {
    const auto [lo, hi] = range();
    if (!(hi > 0.0f)) return {0.0, 0.0};  // nothing measured: nothing to integrate
    return {static_cast<double>(lo), static_cast<double>(hi)};
  }
  const auto quantile = [&sample](double q) {
    auto at = sample.begin() + depth_band_quantile_index(q, sample.size());
    std::nth_element(sample.begin(), at, sample.end());
    return static_cast<double>(*at);
  };
  std::pair<double, double> band;
  depth_band_from_quantiles(quantile(kDepthBandQuantile), quantile(1.0 - kDepthBandQuantile), &band.first,
                            &band.second);
  return band;
}

}  // namespace sls::fusion::detail
