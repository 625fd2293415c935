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

// The samples (of `grid`) whose white - black contrast stands out of the noise and that no
// image saturates: where every pattern should show what the set says.
std::vector<std::size_t> lit_samples(const DecodeParams& params, const StackCheckGrid& grid,
                                     const std::uint16_t* samples) {
  const DecodeLayout& layout = params.layout;
  const DecodeThresholds& t = params.thresholds;
  const std::size_t count = grid.count();
  const std::uint16_t* white = samples + static_cast<std::size_t>(layout.white_index) * count;
  const std::uint16_t* black = samples + static_cast<std::size_t>(layout.black_index) * count;
  const auto images = static_cast<std::size_t>(layout.pattern_count);
  std::vector<std::size_t> lit;
  for (std::size_t n = 0; n < count; ++n) {
    const float w = white[n];
    const float b = black[n];
    if (!contrast_above_noise(t, w, b, w - b)) continue;
    bool saturated = false;
    for (std::size_t k = 0; k < images; ++k) saturated = saturated || samples[k * count + n] >= t.saturation_dn;
    if (!saturated) lit.push_back(n);
  }
  return lit;
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
  if (params.layout.white_index < 0 || params.layout.black_index < 0 || stack.empty()) return;
  const StackCheckGrid grid = make_stack_check_grid(stack[0].width(), stack[0].height(), limits.max_samples);
  const std::size_t count = grid.count();
  std::vector<std::uint16_t> samples(stack.size() * count);
  // An image per thread: ~720 k scattered reads of a 12 MP stack take ~5 ms on one.
  const auto images = static_cast<std::ptrdiff_t>(stack.size());
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (std::ptrdiff_t k = 0; k < images; ++k) {
    const std::uint16_t* image = stack[static_cast<std::size_t>(k)].data();
    std::uint16_t* out = samples.data() + static_cast<std::size_t>(k) * count;
    for (std::size_t n = 0; n < count; ++n) out[n] = image[grid.pixel(n)];
  }
  check_stack_samples(set, params, grid, samples.data(), limits);
}

void check_stack_samples(const PatternSet& set, const DecodeParams& params, const StackCheckGrid& grid,
                         const std::uint16_t* samples, const StackCheckLimits& limits) {
  const DecodeLayout& layout = params.layout;
  if (layout.white_index < 0 || layout.black_index < 0) return;
  const std::vector<std::size_t> pixels = lit_samples(params, grid, samples);
  if (pixels.size() < limits.min_lit_samples) return;
  const std::size_t count = grid.count();
  const std::uint16_t* white = samples + static_cast<std::size_t>(layout.white_index) * count;
  const std::uint16_t* black = samples + static_cast<std::size_t>(layout.black_index) * count;
  const auto sample = [&](int k, std::size_t n) {
    return static_cast<double>(samples[static_cast<std::size_t>(k) * count + pixels[n]]);
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
