// HDR capture for shiny (metal) parts: a frame's pattern stack captured at 1..4 exposure
// times is fused into one stack the decoders take unchanged (per-pixel choice of exposure,
// hdr_fusion_shared.h says how and why).
//
//   HdrExposures exposures = parse_hdr_exposures("1,0.125");   // relative exposure times
//   HdrFusedStack fused = fuse_hdr_stack(images, set.size(), exposures, decode_options);
//   DecodedFrame frame = decoder.decode(fused.images);
//
// Images of a multi-exposure frame are exposure-major: the whole stack at exposure 0, then
// at exposure 1, ... (as the capture sequencer takes them and recordings store them).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "sdk/core/image.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/hdr_fusion_shared.h"

namespace sls {

// Exposure times relative to the camera's configured exposure (1: as set; 0.125: an eighth of
// it). One exposure is an ordinary capture.
struct HdrExposures {
  std::vector<double> scales{1.0};

  std::size_t count() const { return scales.size(); }
  bool is_hdr() const { return scales.size() > 1; }
  // Throws sls::Error(kInvalidArgument) naming the problem: no exposure or more than
  // kHdrMaxExposures, a scale that is not finite and positive, two equal scales.
  void validate() const;
};

// "1,0.125" -> {1, 0.125}; throws sls::Error(kInvalidArgument) for text that is not a comma
// separated list of numbers, and as validate().
HdrExposures parse_hdr_exposures(const std::string& text);

// The pattern stack as taken, checks on how the exposures relate.
struct HdrFusionOptions {
  // Refuse a frame whose exposures do not scale the light as their scales say (a camera that
  // ignored the exposure setting, stacks out of order): the median ratio of the pixels'
  // brightest samples (above black) between two exposures, over pixels unsaturated in both
  // and at least min_check_signal_fraction of full scale above black in the longer one, must
  // lie within max_ratio_error (relative) of the scales' ratio.
  bool check_exposures = true;
  double max_ratio_error = 0.25;
  double min_check_signal_fraction = 0.05;
  std::size_t min_check_pixels = 64;  // fewer: too little to judge, not checked
};

struct HdrFusedStack {
  std::vector<Image16u> images;  // one per pattern: what Decoder::decode takes
  // Per pixel, which exposure its samples come from (index into the scales as given).
  Image8u exposure_index;
  // Pixels saturated at every exposure (they decode as saturated).
  std::size_t saturated_pixels = 0;
};

// Fuses `images` (patterns x exposures, exposure-major) into one stack. Saturation and black
// level are the decoder's (DecodeOptions: saturation_dn, or 98 % of full scale). One
// exposure returns its images as they are. Throws sls::Error: kInvalidArgument for a wrong
// image count, empty or mixed sizes, bad exposures; kFormat when the check_exposures test
// fails (naming the exposures and the ratio measured).
HdrFusedStack fuse_hdr_stack(const std::vector<Image16u>& images, std::size_t patterns, const HdrExposures& exposures,
                             const DecodeOptions& decode_options = {}, const HdrFusionOptions& options = {});

// The projector's light alone, white − black (white − the black level without a black
// pattern), of the fused stack at the scale of the longest exposure: a pixel's value times
// longest / its exposure's scale, so the texture (tracking's photometric term, colour) is one
// radiometric image again. Empty when the set has no white pattern.
Image32f hdr_texture(const HdrFusedStack& fused, const HdrExposures& exposures, const DecodeLayout& layout,
                     double black_level_dn);

}  // namespace sls
