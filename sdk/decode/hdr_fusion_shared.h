// Per-pixel HDR fusion (sdk/decode/hdr_fusion.h), one body for the CPU and, later, CUDA.
//
// A frame captured at K exposures holds K stacks of the same patterns. Per pixel, the fused
// stack takes every pattern image from ONE exposure: the longest whose samples at that pixel
// are all below the saturation level (the brightest unsaturated exposure), left unscaled.
// Why one exposure per pixel rather than one per image, and why unscaled:
//  - the decoder's estimates are invariant to a per-pixel scale (a phase is a ratio of
//    differences, a Gray bit a comparison, the modulation test a ratio), so a pixel's samples
//    need not share a radiometric scale with its neighbours';
//  - samples of one real exposure carry exactly the camera's noise (shot + read), so the
//    decoder's noise model (DecodeOptions: gain, read noise, black level) stays exact for
//    every fused pixel and its confidence and thresholds mean what they do for one exposure.
//    Images scaled by an exposure ratio r would carry r^2 times the read-noise variance and r
//    times the shot-noise variance that one per-frame model cannot express;
//  - mixing exposures within a pixel's stack would turn any error in the exposure ratio
//    (shutter timing, projector drift between passes) into a phase error.
// The cost: a pixel whose white saturates at the long exposure decodes all its images from
// the shorter one, where its dark images are noisier; the brightest image sets the exposure.
// Pixels saturated at every exposure keep the shortest exposure's samples: the decoder flags
// them saturated (kDecodeSaturated) as it does for a single exposure.
#pragma once

#include <cstdint>

#include "sdk/core/host_device.h"

namespace sls {

constexpr int kHdrMaxExposures = 4;

// `peak[e]`: the largest sample of the pixel over the patterns of exposure e, the exposures
// ordered longest first. Returns the index (into that order) of the longest exposure whose
// peak is below `saturation_dn`, or count - 1 (the shortest) when every one saturates.
SLS_HOST_DEVICE inline int hdr_pick_exposure(const std::uint16_t* peak, int count, float saturation_dn) {
  for (int e = 0; e < count; ++e) {
    if (static_cast<float>(peak[e]) < saturation_dn) return e;
  }
  return count - 1;
}

}  // namespace sls
