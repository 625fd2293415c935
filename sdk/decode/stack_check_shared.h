// The stack check (stack_check.h), shared by the CPU and the GPU (cuda/stack_check.cu).
//
// Which pixels it reads: `rows` evenly spaced rows (the centres of `rows` equal bands), every
// `stride`-th pixel of each. Rows, not a scattered grid: each image is then read in runs of
// contiguous memory (a grid over 22 images of 12 MP was one cache miss per sample, 74 ms a
// frame); 64 of them, so that an object covering a tenth of the view still has six rows across
// it.
//
// What it does with each: judge_stack_pixel adds, for a lit pixel, one value per complementary
// Gray pair and per phase step to that pair's or step's histogram of fractions of the contrast;
// the host then takes their medians (judge_stack_histograms). Per pixel and into histograms, so
// that the GPU judges a 12-megapixel stack where it lands and only the histograms come down.
// Plain structs only: nvcc compiles this.
#pragma once

#include <cmath>
#include <cstddef>

#include "sdk/core/math_shared.h"
#include "sdk/decode/decode_shared.h"

namespace sls {

struct StackCheckGrid {
  int width = 0;     // of the images
  int height = 0;
  int rows = 0;      // sampled rows
  int columns = 0;   // samples per row
  int stride = 1;    // pixels between a row's samples
  SLS_HOST_DEVICE std::size_t count() const {
    return static_cast<std::size_t>(rows) * static_cast<std::size_t>(columns);
  }
  // The image pixel of sample n (row-major over rows, then columns).
  SLS_HOST_DEVICE std::size_t pixel(std::size_t n) const {
    const std::size_t r = n / static_cast<std::size_t>(columns);
    const std::size_t c = n % static_cast<std::size_t>(columns);
    const std::size_t y = (2 * r + 1) * static_cast<std::size_t>(height) / (2 * static_cast<std::size_t>(rows));
    return y * static_cast<std::size_t>(width) + c * static_cast<std::size_t>(stride);
  }
};

// At most `max_samples` pixels (and at least one per row) of a width x height image.
inline StackCheckGrid make_stack_check_grid(int width, int height, std::size_t max_samples) {
  StackCheckGrid grid;
  grid.width = width;
  grid.height = height;
  if (width <= 0 || height <= 0) return grid;
  const auto w = static_cast<std::size_t>(width);
  grid.rows = height < 64 ? height : 64;
  const std::size_t per_row = max_samples / static_cast<std::size_t>(grid.rows) > 0
                                  ? max_samples / static_cast<std::size_t>(grid.rows)
                                  : 1;
  const std::size_t stride = (w + per_row - 1) / per_row;
  grid.stride = static_cast<int>(stride > 0 ? stride : 1);
  grid.columns = static_cast<int>((w + static_cast<std::size_t>(grid.stride) - 1) / static_cast<std::size_t>(grid.stride));
  return grid;
}

// The histograms' bins: fractions of the contrast in steps of 1/512 (far finer than the limits
// they are held against), up to 4 (beyond counts as 4).
constexpr int kStackCheckBins = 4 * 512;
constexpr double kStackCheckBinsPerUnit = 512.0;
constexpr int kStackCheckMaxPairs = 2 * kDecodeMaxGrayBits;
constexpr int kStackCheckMaxGroups = 2 * kDecodeMaxPhaseGroups;

SLS_HOST_DEVICE inline int stack_check_bin(double fraction) {
  const double bin = fraction > 0.0 ? fraction * kStackCheckBinsPerUnit : 0.0;
  return bin < static_cast<double>(kStackCheckBins - 1) ? static_cast<int>(bin) : kStackCheckBins - 1;
}

// What the check compares in a pattern set, and where each comparison's histogram is: one per
// complementary Gray pair (both axes, in bit order), then one per step of each phase group of
// four steps or more (three fit any three values). `usable` false: a set without white and
// black carries no such redundancy.
struct StackCheckPlan {
  bool usable = false;
  int images = 0;
  int white = -1, black = -1;
  DecodeThresholds thresholds;
  int pair_count = 0;
  int pair_pattern[kStackCheckMaxPairs] = {};
  int pair_inverse[kStackCheckMaxPairs] = {};
  int group_count = 0;
  int group_steps[kStackCheckMaxGroups] = {};
  int group_first_slot[kStackCheckMaxGroups] = {};
  int group_index[kStackCheckMaxGroups][kDecodeMaxPhaseSteps] = {};
  float group_cos[kStackCheckMaxGroups][kDecodeMaxPhaseSteps] = {};
  float group_sin[kStackCheckMaxGroups][kDecodeMaxPhaseSteps] = {};
  int slot_count = 0;  // histograms
};

inline StackCheckPlan make_stack_check_plan(const DecodeParams& params) {
  const DecodeLayout& layout = params.layout;
  StackCheckPlan plan;
  plan.usable = layout.white_index >= 0 && layout.black_index >= 0;
  plan.images = layout.pattern_count;
  plan.white = layout.white_index;
  plan.black = layout.black_index;
  plan.thresholds = params.thresholds;
  for (const AxisCode& axis : layout.axes) {
    for (int g = 0; axis.extent > 0 && g < axis.gray_count; ++g) {
      if (axis.gray_inverse_index[g] < 0) continue;
      plan.pair_pattern[plan.pair_count] = axis.gray_index[g];
      plan.pair_inverse[plan.pair_count] = axis.gray_inverse_index[g];
      ++plan.pair_count;
    }
  }
  plan.slot_count = plan.pair_count;
  for (const AxisCode& axis : layout.axes) {
    for (int group = 0; axis.extent > 0 && group < axis.phase_group_count; ++group) {
      const PhaseGroup& phase = axis.phase[group];
      if (phase.count < 4) continue;
      const int g = plan.group_count++;
      plan.group_steps[g] = phase.count;
      plan.group_first_slot[g] = plan.slot_count;
      for (int j = 0; j < phase.count; ++j) {
        plan.group_index[g][j] = phase.index[j];
        plan.group_cos[g][j] = phase.cos_step[j];
        plan.group_sin[g][j] = phase.sin_step[j];
      }
      plan.slot_count += phase.count;
    }
  }
  return plan;
}

// The median of a few values (one pixel's pair sums), sorting them in place: the element
// std::nth_element would put in the middle.
SLS_HOST_DEVICE inline double median_of_few(double* values, int count) {
  for (int i = 1; i < count; ++i) {
    const double value = values[i];
    int j = i;
    for (; j > 0 && values[j - 1] > value; --j) values[j] = values[j - 1];
    values[j] = value;
  }
  return count > 0 ? values[count / 2] : 0.0;
}

// One pixel of a usable plan, `sample(k)` its value in image k (DN): false when it is not lit
// (white - black within the noise, or an image saturated); else add(slot, bin) for
//   - each complementary pair: |pattern + inverse - all-on| as a fraction of the contrast, the
//     all-on light being what the pairs add up to on their median (two pairs or more: a wrong
//     white image, which the decoder barely uses, does not condemn the stack) or white + black;
//   - each phase step: its misfit to the least-squares sinusoid of its group (steps equally
//     spaced: the sums are the fit), in the same unit.
template <typename Sample, typename Add>
SLS_HOST_DEVICE inline bool judge_stack_pixel(const StackCheckPlan& plan, const Sample& sample, const Add& add) {
  const float white = sample(plan.white), black = sample(plan.black);
  if (!contrast_above_noise(plan.thresholds, white, black, white - black)) return false;
  for (int k = 0; k < plan.images; ++k) {
    if (sample(k) >= plan.thresholds.saturation_dn) return false;
  }
  const auto pair_sum = [&](int p) {
    return static_cast<double>(sample(plan.pair_pattern[p])) + static_cast<double>(sample(plan.pair_inverse[p]));
  };
  double all_on = static_cast<double>(white) + static_cast<double>(black);
  if (plan.pair_count >= 2) {
    double sums[kStackCheckMaxPairs];
    for (int p = 0; p < plan.pair_count; ++p) sums[p] = pair_sum(p);
    all_on = median_of_few(sums, plan.pair_count);
  }
  const double dark = static_cast<double>(black);
  const double contrast = all_on - 2.0 * dark;
  const double inverse_contrast = 1.0 / (contrast > 1.0 ? contrast : 1.0);
  for (int p = 0; p < plan.pair_count; ++p) add(p, stack_check_bin(std::fabs(pair_sum(p) - all_on) * inverse_contrast));
  for (int g = 0; g < plan.group_count; ++g) {
    const int steps = plan.group_steps[g];
    double x[kDecodeMaxPhaseSteps];
    double mean = 0.0, c = 0.0, s = 0.0;
    for (int j = 0; j < steps; ++j) {
      x[j] = (static_cast<double>(sample(plan.group_index[g][j])) - dark) * inverse_contrast;
      mean += x[j];
      c += x[j] * static_cast<double>(plan.group_cos[g][j]);
      s += x[j] * static_cast<double>(plan.group_sin[g][j]);
    }
    mean /= steps;
    c *= 2.0 / steps;
    s *= 2.0 / steps;
    for (int j = 0; j < steps; ++j) {
      const double fitted =
          mean + c * static_cast<double>(plan.group_cos[g][j]) + s * static_cast<double>(plan.group_sin[g][j]);
      add(plan.group_first_slot[g] + j, stack_check_bin(std::fabs(x[j] - fitted)));
    }
  }
  return true;
}

}  // namespace sls
