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

// The median of one slot's histogram (total: the lit pixels), at its bin's centre.
double histogram_median(const std::uint32_t* bins, std::size_t total) {
  std::size_t seen = 0;
  for (int bin = 0; bin < kStackCheckBins; ++bin) {
    seen += bins[bin];
    if (2 * seen > total) return (static_cast<double>(bin) + 0.5) / kStackCheckBinsPerUnit;
  }
  return 0.0;
}

}  // namespace

StackCheckHistograms stack_check_histograms(const StackCheckPlan& plan, const StackCheckGrid& grid,
                                            const std::vector<Image16u>& stack) {
  StackCheckHistograms result;
  const std::size_t bins = static_cast<std::size_t>(plan.slot_count) * kStackCheckBins;
  result.counts.assign(bins, 0);
  if (!plan.usable || grid.count() == 0) return result;
  std::vector<const std::uint16_t*> images(stack.size());
  for (std::size_t k = 0; k < stack.size(); ++k) images[k] = stack[k].data();
  const auto samples = static_cast<std::ptrdiff_t>(grid.count());
  std::size_t lit = 0;
  // A block of the grid per thread, each into histograms of its own, added up after (counts:
  // the result does not depend on the split).
#if defined(_OPENMP)
#pragma omp parallel reduction(+ : lit)
#endif
  {
    std::vector<std::uint32_t> mine(bins, 0);
#if defined(_OPENMP)
#pragma omp for schedule(static) nowait
#endif
    for (std::ptrdiff_t n = 0; n < samples; ++n) {
      const std::size_t pixel = grid.pixel(static_cast<std::size_t>(n));
      const auto sample = [&](int k) { return static_cast<float>(images[static_cast<std::size_t>(k)][pixel]); };
      const auto add = [&](int slot, int bin) { ++mine[static_cast<std::size_t>(slot) * kStackCheckBins + static_cast<std::size_t>(bin)]; };
      if (judge_stack_pixel(plan, sample, add)) ++lit;
    }
#if defined(_OPENMP)
#pragma omp critical(sls_stack_check_histograms)
#endif
    for (std::size_t i = 0; i < bins; ++i) result.counts[i] += mine[i];
  }
  result.lit = lit;
  return result;
}

void judge_stack_histograms(const PatternSet& set, const StackCheckPlan& plan, std::size_t lit,
                            const std::uint32_t* counts, const StackCheckLimits& limits) {
  if (!plan.usable || lit < limits.min_lit_samples) return;
  const auto median_of_slot = [&](int slot) {
    return histogram_median(counts + static_cast<std::size_t>(slot) * kStackCheckBins, lit);
  };
  // The complementary Gray pairs: each adds up to the all-on light.
  for (int p = 0; p < plan.pair_count; ++p) {
    const double error = median_of_slot(p);
    if (error > limits.max_pair_sum_error) {
      const int pattern = plan.pair_pattern[p], inverse = plan.pair_inverse[p];
      throw_error(ErrorCode::kFormat,
                  "pattern images {} ({}) and {} ({}) do not add up to the all-on light ({}): off by {:.0f} % of "
                  "the contrast on the median lit pixel (at most {:.0f} %); a pattern stuck or images out of order?",
                  pattern, pattern_label(set.patterns[static_cast<std::size_t>(pattern)]), inverse,
                  pattern_label(set.patterns[static_cast<std::size_t>(inverse)]),
                  plan.pair_count >= 2 ? "what the other complementary pairs add up to" : "white + black",
                  100.0 * error, 100.0 * limits.max_pair_sum_error);
    }
  }
  // Each phase group's images lie on one sinusoid: an image whose misfit stands out of the
  // others' is not the step it should be.
  for (int g = 0; g < plan.group_count; ++g) {
    const int steps = plan.group_steps[g];
    std::vector<double> medians(static_cast<std::size_t>(steps));
    for (int j = 0; j < steps; ++j) medians[static_cast<std::size_t>(j)] = median_of_slot(plan.group_first_slot[g] + j);
    for (int j = 0; j < steps; ++j) {
      std::vector<double> others;
      for (int k = 0; k < steps; ++k) {
        if (k != j) others.push_back(medians[static_cast<std::size_t>(k)]);
      }
      const double typical = median_of(others);
      const double misfit = medians[static_cast<std::size_t>(j)];
      if (misfit > limits.min_phase_misfit && misfit > limits.outlier_ratio * typical) {
        const int pattern = plan.group_index[g][j];
        throw_error(ErrorCode::kFormat,
                    "pattern image {} ({}) is off the sinusoid of the other phase steps by {:.0f} % of the contrast "
                    "on the median lit pixel (the others: {:.1f} %); a pattern stuck or images out of order?",
                    pattern, pattern_label(set.patterns[static_cast<std::size_t>(pattern)]), 100.0 * misfit,
                    100.0 * typical);
      }
    }
  }
}

void check_stack_behaves(const PatternSet& set, const DecodeParams& params, const std::vector<Image16u>& stack,
                         const StackCheckLimits& limits) {
  const StackCheckPlan plan = make_stack_check_plan(params);
  if (!plan.usable || stack.empty()) return;
  const StackCheckGrid grid = make_stack_check_grid(stack[0].width(), stack[0].height(), limits.max_samples);
  const StackCheckHistograms histograms = stack_check_histograms(plan, grid, stack);
  judge_stack_histograms(set, plan, histograms.lit, histograms.counts.data(), limits);
}

}  // namespace sls
