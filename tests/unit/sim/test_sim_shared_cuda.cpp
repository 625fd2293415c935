// CPU and CUDA run the same shared per-pixel code (DESIGN.md section 6): the Philox words and
// the noisy digital numbers must be identical, the blurred pattern values and blur sigmas
// equal to rounding (CUDA's libm and its FMA contraction differ from the host's by ulps).
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/decode/pattern_set.h"
#include "tests/support/test_support.h"
#include "tests/unit/sim/shared_math_cases.h"

namespace sls::sim::test {
namespace {

TEST(SimSharedCuda, CudaEqualsCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const PatternSet set = make_gray_phase_pattern_set();
  const int count = 1 << 20;
  for (std::size_t index : {std::size_t{0}, std::size_t{12}, std::size_t{17}}) {  // white, gray bit 4, phase step 3
    const PatternDesc& pattern = set.patterns[index];
    const std::vector<std::uint8_t> levels = pattern_levels(pattern);
    std::vector<CaseResult> gpu(static_cast<std::size_t>(count));
    evaluate_cases_cuda(count, pattern, levels.data(), gpu.data());
    const PatternLevelTable table{levels.data(), pattern.extent};
    std::size_t dn_mismatches = 0, philox_mismatches = 0, poisson_mismatches = 0;
    double blurred = 0, blurred_float = 0, sigma = 0;
    for (int i = 0; i < count; ++i) {
      CaseResult cpu;
      evaluate_case(i, count, pattern, table, &cpu);
      const CaseResult& g = gpu[static_cast<std::size_t>(i)];
      for (int w = 0; w < 4; ++w) {
        if (cpu.philox[w] != g.philox[w]) ++philox_mismatches;
      }
      if (cpu.dn != g.dn || cpu.dn_noiseless != g.dn_noiseless) ++dn_mismatches;
      if (cpu.poisson != g.poisson) ++poisson_mismatches;
      blurred = std::fmax(blurred, std::fmax(std::fabs(cpu.blurred - g.blurred), std::fabs(cpu.blurred_table - g.blurred_table)));
      blurred = std::fmax(blurred, std::fabs(cpu.blurred_gamma - g.blurred_gamma));
      blurred_float = std::fmax(blurred_float, std::fabs(static_cast<double>(cpu.blurred_float - g.blurred_float)));
      sigma = std::fmax(sigma, std::fmax(std::fabs(cpu.camera_sigma_px - g.camera_sigma_px) / cpu.camera_sigma_px,
                                         std::fabs(cpu.projector_sigma_cols - g.projector_sigma_cols) /
                                             cpu.projector_sigma_cols));
    }
    std::printf("%s: %d cases, Philox mismatches %zu, DN mismatches %zu, Poisson mismatches %zu, blurred double %.3g, "
                "float %.3g, sigma (relative) %.3g\n",
                pattern_label(pattern).c_str(), count, philox_mismatches, dn_mismatches, poisson_mismatches, blurred,
                blurred_float, sigma);
    EXPECT_EQ(philox_mismatches, 0u);
    EXPECT_EQ(dn_mismatches, 0u);
    EXPECT_EQ(poisson_mismatches, 0u);
    EXPECT_LT(blurred, 1e-14);
    EXPECT_LT(blurred_float, 2e-6);
    EXPECT_LT(sigma, 1e-12);  // nvcc contracts a*b+c into FMAs: ulp-level differences, amplified near focus
  }
}

}  // namespace
}  // namespace sls::sim::test
