#include "sdk/decode/stack_check.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "sdk/core/error.h"

namespace sls {
namespace {

double median_of(std::vector<double>& values) {
  if (values.empty()) return 0.0;
  auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// The median of many non-negative fractions of the contrast, to 1/512 of it (far finer than the
// limits it is held against), in one pass and without sorting tens of thousands of values per
// image (nth_element over each was most of the check's time).
class MedianOfFractions {
 public:
  void add(double value) {
    const double bin = std::min(std::max(value, 0.0) * kBinsPerUnit, static_cast<double>(kBins - 1));
    ++counts_[static_cast<std::size_t>(bin)];
    ++total_;
  }
  double median() const {
    std::size_t seen = 0;
    for (std::size_t bin = 0; bin < counts_.size(); ++bin) {
      seen += counts_[bin];
      if (2 * seen > total_) return (static_cast<double>(bin) + 0.5) / kBinsPerUnit;
    }
    return 0.0;
  }

 private:
  static constexpr double kBinsPerUnit = 512.0;
  static constexpr int kBins = 4 * 512;  // up to 4x the contrast; beyond counts as 4
  std::vector<std::size_t> counts_ = std::vector<std::size_t>(kBins, 0);
  std::size_t total_ = 0;
};

// Pixels on 64 evenly spaced rows (every k-th pixel of each) whose white - black contrast stands
// out of the noise and that no image saturates: where every pattern should show what the set
// says. Rows, not a scattered grid: each image is then read in runs of contiguous memory (a
// grid over 22 images of 12 MP was one cache miss per sample, 74 ms a frame); 64 of them, so an
// object covering a tenth of the view still has six rows across it.
std::vector<std::size_t> lit_samples(const DecodeParams& params, const std::vector<Image16u>& stack,
                                     std::size_t max_samples) {
  const DecodeLayout& layout = params.layout;
  const DecodeThresholds& t = params.thresholds;
  const auto width = static_cast<std::size_t>(stack[0].width());
  const auto height = static_cast<std::size_t>(stack[0].height());
  const std::size_t rows = std::min<std::size_t>(height, 64);
  const std::size_t per_row = std::max<std::size_t>(1, max_samples / rows);
  const std::size_t stride = std::max<std::size_t>(1, (width + per_row - 1) / per_row);
  const std::uint16_t* white = stack[static_cast<std::size_t>(layout.white_index)].data();
  const std::uint16_t* black = stack[static_cast<std::size_t>(layout.black_index)].data();
  std::vector<std::size_t> pixels;
  for (std::size_t r = 0; r < rows; ++r) {
    const std::size_t y = (2 * r + 1) * height / (2 * rows);  // row centres of `rows` equal bands
    for (std::size_t i = y * width, end = i + width; i < end; i += stride) {
      const float w = white[i];
      const float b = black[i];
      if (!contrast_above_noise(t, w, b, w - b)) continue;
      bool saturated = false;
      for (const Image16u& image : stack) saturated = saturated || image.data()[i] >= t.saturation_dn;
      if (!saturated) pixels.push_back(i);
    }
  }
  return pixels;
}

// One phase group's images lie on one sinusoid (see the file comment of stack_check.h).
template <typename Level>
void check_phase_group(const PatternSet& set, const PhaseGroup& axis, const Level& level, std::size_t pixel_count,
                       const StackCheckLimits& limits) {
  const int steps = axis.count;
  if (steps < 4) return;  // three steps fit any three values: nothing to check
  // Least-squares sinusoid per pixel (steps equally spaced: the sums are the fit), then each
  // image's misfit.
  std::vector<MedianOfFractions> misfits(static_cast<std::size_t>(steps));
  std::vector<double> x(static_cast<std::size_t>(steps)), cosines(x.size()), sines(x.size());
  for (int j = 0; j < steps; ++j) {
    cosines[static_cast<std::size_t>(j)] = static_cast<double>(axis.cos_step[j]);
    sines[static_cast<std::size_t>(j)] = static_cast<double>(axis.sin_step[j]);
  }
  for (std::size_t n = 0; n < pixel_count; ++n) {
    double mean = 0.0, c = 0.0, s = 0.0;
    for (int j = 0; j < steps; ++j) {
      x[static_cast<std::size_t>(j)] = level(axis.index[j], n);
      mean += x[static_cast<std::size_t>(j)];
      c += x[static_cast<std::size_t>(j)] * cosines[static_cast<std::size_t>(j)];
      s += x[static_cast<std::size_t>(j)] * sines[static_cast<std::size_t>(j)];
    }
    mean /= steps;
    c *= 2.0 / steps;
    s *= 2.0 / steps;
    for (int j = 0; j < steps; ++j) {
      const double fitted =
          mean + c * cosines[static_cast<std::size_t>(j)] + s * sines[static_cast<std::size_t>(j)];
      misfits[static_cast<std::size_t>(j)].add(std::abs(x[static_cast<std::size_t>(j)] - fitted));
    }
  }
  std::vector<double> medians(static_cast<std::size_t>(steps));
  for (int j = 0; j < steps; ++j) medians[static_cast<std::size_t>(j)] = misfits[static_cast<std::size_t>(j)].median();
  for (int j = 0; j < steps; ++j) {
    std::vector<double> others;
    for (int k = 0; k < steps; ++k) {
      if (k != j) others.push_back(medians[static_cast<std::size_t>(k)]);
    }
    const double typical = median_of(others);
    const double misfit = medians[static_cast<std::size_t>(j)];
    if (misfit > limits.min_phase_misfit && misfit > limits.outlier_ratio * typical) {
      const int pattern = axis.index[j];
      throw_error(ErrorCode::kFormat,
                  "pattern image {} ({}) is off the sinusoid of the other phase steps by {:.0f} % of the contrast "
                  "on the median lit pixel (the others: {:.1f} %); a pattern stuck or images out of order?",
                  pattern, pattern_label(set.patterns[static_cast<std::size_t>(pattern)]), 100.0 * misfit,
                  100.0 * typical);
    }
  }
}

}  // namespace

void check_stack_behaves(const PatternSet& set, const DecodeParams& params, const std::vector<Image16u>& stack,
                         const StackCheckLimits& limits) {
  const DecodeLayout& layout = params.layout;
  if (layout.white_index < 0 || layout.black_index < 0) return;
  const std::vector<std::size_t> pixels = lit_samples(params, stack, limits.max_samples);
  if (pixels.size() < limits.min_lit_samples) return;
  const std::uint16_t* white = stack[static_cast<std::size_t>(layout.white_index)].data();
  const std::uint16_t* black = stack[static_cast<std::size_t>(layout.black_index)].data();
  const auto sample = [&](int k, std::size_t n) {
    return static_cast<double>(stack[static_cast<std::size_t>(k)].data()[pixels[n]]);
  };
  // The complementary Gray pairs: each adds up to the all-on light (white + black). With two
  // or more, their per-pixel median is that light even when one pair, or the white image
  // itself, is wrong; each pair is judged against it.
  std::vector<std::pair<int, int>> pairs;
  for (const AxisCode& axis : layout.axes) {
    for (int g = 0; axis.extent > 0 && g < axis.gray_count; ++g) {
      if (axis.gray_inverse_index[g] >= 0) pairs.emplace_back(axis.gray_index[g], axis.gray_inverse_index[g]);
    }
  }
  std::vector<double> all_on(pixels.size()), sums(pairs.size());
  for (std::size_t n = 0; n < pixels.size(); ++n) {
    for (std::size_t p = 0; p < pairs.size(); ++p) sums[p] = sample(pairs[p].first, n) + sample(pairs[p].second, n);
    all_on[n] = pairs.size() >= 2 ? median_of(sums) : static_cast<double>(white[pixels[n]]) + black[pixels[n]];
  }
  std::vector<double> inverse_contrast(pixels.size());
  for (std::size_t n = 0; n < pixels.size(); ++n) {
    inverse_contrast[n] = 1.0 / std::max(all_on[n] - 2.0 * black[pixels[n]], 1.0);
  }
  const auto level = [&](int k, std::size_t n) { return (sample(k, n) - black[pixels[n]]) * inverse_contrast[n]; };
  for (const auto& [pattern, inverse] : pairs) {
    MedianOfFractions errors;
    for (std::size_t n = 0; n < pixels.size(); ++n) {
      errors.add(std::abs(sample(pattern, n) + sample(inverse, n) - all_on[n]) * inverse_contrast[n]);
    }
    const double error = errors.median();
    if (error > limits.max_pair_sum_error) {
      throw_error(ErrorCode::kFormat,
                  "pattern images {} ({}) and {} ({}) do not add up to the all-on light ({}): off by {:.0f} % of "
                  "the contrast on the median lit pixel (at most {:.0f} %); a pattern stuck or images out of order?",
                  pattern, pattern_label(set.patterns[static_cast<std::size_t>(pattern)]), inverse,
                  pattern_label(set.patterns[static_cast<std::size_t>(inverse)]),
                  pairs.size() >= 2 ? "what the other complementary pairs add up to" : "white + black",
                  100.0 * error, 100.0 * limits.max_pair_sum_error);
    }
  }
  for (const AxisCode& axis : layout.axes) {
    for (int group = 0; axis.extent > 0 && group < axis.phase_group_count; ++group) {
      check_phase_group(set, axis.phase[group], level, pixels.size(), limits);
    }
  }
}

}  // namespace sls
