// Decode accuracy against ground truth (DESIGN.md section 4): projector-coordinate error in
// projector pixels and depth error in µm over the pixels both the truth and the decoder call
// valid, and the fraction of truly valid pixels the decoder recovers.
#pragma once

#include <cstddef>

#include "sdk/core/image.h"
#include "sdk/decode/decoder.h"

namespace sls {

struct DecodeErrorStats {
  std::size_t truth_valid = 0;     // pixels the ground truth calls visible and lit
  std::size_t compared = 0;        // ... of which the decoder also decoded (mask ok)
  std::size_t false_valid = 0;     // decoded where the truth says not valid (e.g. shadow edges)
  double projector_sum_squares = 0.0;  // px²
  double projector_max_px = 0.0;
  double depth_sum_squares = 0.0;      // m²
  double depth_max_m = 0.0;

  double projector_rms_px() const;
  double depth_rms_um() const;
  double valid_fraction() const;   // compared / truth_valid
  // Adds another frame's statistics (for totals over a recording).
  void accumulate(const DecodeErrorStats& other);
};

// Compares a decoded frame with the truth (same size, else sls::Error kInvalidArgument):
// true projector column coordinate (NaN where not lit), true depth (m), valid mask (non-zero:
// visible and lit).
DecodeErrorStats compare_with_ground_truth(const DecodedFrame& decoded, const Image32f& true_projector_u,
                                           const Image32f& true_depth_m, const Image8u& true_valid);

}  // namespace sls
