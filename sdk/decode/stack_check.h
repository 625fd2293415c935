// A frame-level check, before decoding, that a pattern stack behaves as its pattern set says.
// The per-pixel tests of the decoder (shadow, modulation, Gray/phase consistency) cannot see
// one pattern image that is wrong everywhere (a projector stuck on a pattern, a frame mixed
// up): a stuck Gray image moves whole stripes by a period and a stuck phase image bends every
// phase, yet most pixels stay "valid" with millimetres of error. What every stack of a
// pattern set must satisfy instead, on the lit pixels of 64 evenly spaced rows (~32 k pixels):
//   - a Gray image and its complement add up to the all-on light, white + black (their
//     projector light sums to all-on whatever the blur), up to noise and blurred stripe
//     edges; with two pairs or more, to what the pairs add up to on the median (so a wrong
//     white image, which the decoder barely uses, does not condemn the stack);
//   - the N >= 4 phase images of an axis lie on one sinusoid (offset + cos + sin); an image
//     whose misfit stands out of the others' is not the step it should be.
// Sets without white and black images, Gray bits without complements and N = 3 phase steps
// carry no such redundancy and are not checked.
#pragma once

#include <cstdint>
#include <vector>

#include "sdk/core/image.h"
#include "sdk/decode/decode_shared.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/decode/stack_check_shared.h"

namespace sls {

struct StackCheckLimits {
  // A complementary Gray pair fails when the median |pattern + inverse - white - black| over
  // the lit pixels exceeds this fraction of white - black.
  double max_pair_sum_error = 0.25;
  // A phase image fails when its median misfit to the axis' sinusoid (a fraction of white -
  // black) exceeds both this floor and `outlier_ratio` times the median misfit of the axis'
  // other images (a non-linear projector or camera bends all steps alike, a wrong image one).
  double min_phase_misfit = 0.08;
  double outlier_ratio = 3.0;
  std::size_t min_lit_samples = 256;  // fewer lit pixels: too little to judge, not checked
  std::size_t max_samples = 32768;    // pixels looked at (64 evenly spaced rows: stack_check_shared.h)
};

// Throws sls::Error(kFormat) naming the pattern image(s) at fault and by how much; returns
// when the stack behaves (or cannot be judged). `stack` holds one image per pattern of `set`,
// all of one size (Decoder::decode checks that first).
void check_stack_behaves(const PatternSet& set, const DecodeParams& params, const std::vector<Image16u>& stack,
                         const StackCheckLimits& limits = {});

// The check's histograms (stack_check_shared.h): `lit` pixels judged, and for each of the plan's
// slots kStackCheckBins counts, slot after slot. CPU: check_stack_behaves fills them; GPU: the
// decoder's kernel (cuda/stack_check.cu).
struct StackCheckHistograms {
  std::size_t lit = 0;
  std::vector<std::uint32_t> counts;
};
// The grid's histograms of a stack on the host (all threads).
StackCheckHistograms stack_check_histograms(const StackCheckPlan& plan, const StackCheckGrid& grid,
                                            const std::vector<Image16u>& stack);
// The verdict from the histograms (`counts`: plan.slot_count x kStackCheckBins): throws as
// check_stack_behaves; returns with fewer than limits.min_lit_samples lit pixels.
void judge_stack_histograms(const PatternSet& set, const StackCheckPlan& plan, std::size_t lit,
                            const std::uint32_t* counts, const StackCheckLimits& limits = {});

}  // namespace sls
