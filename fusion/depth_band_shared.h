// The depth band a frame is integrated over (integration_depth_band, fusion/integrator.h): the
// rule on its sample of valid depths, for the host's sample and the GPU's sorted one alike.
#pragma once

#include <cstddef>

#include "sdk/core/host_device.h"

namespace sls::fusion {

constexpr std::size_t kDepthBandStride = 127;     // every 127th pixel is sampled
constexpr double kDepthBandQuantile = 1e-3;       // q and Q: the 0.1 % and 99.9 % quantiles
constexpr std::size_t kDepthBandMinSamples = 1000;  // fewer valid samples: the map's [min, max]

// The pixels sampled of a map of `pixels`: 0, kDepthBandStride, 2 kDepthBandStride, ...
SLS_HOST_DEVICE inline std::size_t depth_band_samples(std::size_t pixels) {
  return (pixels + kDepthBandStride - 1) / kDepthBandStride;
}

// The position of quantile q among n > 0 ascending valid samples.
SLS_HOST_DEVICE inline std::ptrdiff_t depth_band_quantile_index(double q, std::size_t n) {
  return static_cast<std::ptrdiff_t>(q * static_cast<double>(n - 1));
}

// [q − s/2, Q + s/2] with s = Q − q, its near end at least 1 µm.
SLS_HOST_DEVICE inline void depth_band_from_quantiles(double q_lo, double q_hi, double* near_m, double* far_m) {
  const double half_span = 0.5 * (q_hi - q_lo);
  const double near = q_lo - half_span;
  *near_m = 1e-6 < near ? near : 1e-6;
  *far_m = q_hi + half_span;
}

}  // namespace sls::fusion
