// The families of issue 21 decode the same on the CUDA decoder as on the CPU (one body of
// per-pixel code, decode_shared.h and multi_frequency_shared.h): each shipped description
// (samples/patterns/) and reversed, offset, multi-period, row variants, noisy, on the knurled
// screw. Skipped without a GPU.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/rig.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/pattern_families.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

void compare_backends(const PatternSet& set) {
  const sim::Scene scene = sim::make_knurled_screw_scene();
  sim::RigOptions options;
  options.preset = "ci";
  options.camera_width = 400;
  sim::SimRig rig = sim::make_rig(options, scene);
  sim::use_pattern_set(rig, set);
  sim::Renderer renderer(rig, scene, Device::cpu());
  renderer.set_frame(0);
  std::vector<Image16u> stack;
  for (std::size_t k = 0; k < set.size(); ++k) stack.push_back(renderer.render_pattern(static_cast<int>(k)));
  DecodeOptions decode_options;
  decode_options.min_depth_m = 0.09;
  decode_options.max_depth_m = 0.11;
  Decoder cpu(set, rig.calibration(), Device::cpu(), decode_options);
  Decoder gpu(set, rig.calibration(), Device::cuda(), decode_options);
  const DecodedFrame a = cpu.decode(stack);
  const DecodedFrame b = gpu.decode(stack);
  std::size_t mask_differences = 0, compared = 0;
  double worst_u = 0.0, worst_v = 0.0;
  for (std::size_t i = 0; i < a.mask.pixel_count(); ++i) {
    if (a.mask.data()[i] != b.mask.data()[i]) {
      ++mask_differences;
      continue;
    }
    if (a.mask.data()[i] != kDecodeOk) continue;
    ++compared;
    worst_u = std::max(worst_u, std::fabs(static_cast<double>(a.projector_u.data()[i] - b.projector_u.data()[i])));
    if (std::isfinite(a.projector_v.data()[i])) {
      worst_v = std::max(worst_v, std::fabs(static_cast<double>(a.projector_v.data()[i] - b.projector_v.data()[i])));
    }
  }
  std::printf("[families-cuda] %s: %zu px compared, %zu mask differences, max |du| %.2e, |dv| %.2e px\n",
              set.name.c_str(), compared, mask_differences, worst_u, worst_v);
  EXPECT_LE(mask_differences, a.mask.pixel_count() / 10000) << set.name;
  EXPECT_GT(compared, 1000u) << set.name;
  EXPECT_LT(worst_u, 1e-3) << set.name;
  EXPECT_LT(worst_v, 1e-3) << set.name;
}

TEST(PatternFamiliesCuda, CpuAndCudaAgreeOnEveryShippedDescription) {
  SLS_REQUIRE_CUDA_DEVICE();
  for (const char* file : {"slscan_gray_phase.json", "opencv_graycode_1024x768.json",
                           "complementary_gray_phase_shift.json", "multi_period_gray_phase_shift.json"}) {
    compare_backends(load_pattern_description(std::string(SLS_SOURCE_DIR) + "/samples/patterns/" + file));
  }
  PhaseShiftOptions variant;
  variant.rows = true;
  variant.reversed = true;
  variant.offset_rad = 0.7;
  variant.periods_px = {120.0, 19.5};
  variant.gray_inverse = false;
  variant.gray_threshold = GrayThresholdMode::kPhaseMean;
  compare_backends(make_phase_shift_pattern_set(variant));
}

// Heterodyne and micro phase shifting (multi_frequency_shared.h): the shipped descriptions, and
// rows and columns with reversed, offset phases.
TEST(PatternFamiliesCuda, CpuAndCudaAgreeOnHeterodyneAndMicroPhase) {
  SLS_REQUIRE_CUDA_DEVICE();
  for (const char* file : {"heterodyne_3freq.json", "micro_phase_shifting.json"}) {
    compare_backends(load_pattern_description(std::string(SLS_SOURCE_DIR) + "/samples/patterns/" + file));
  }
  PhaseShiftOptions heterodyne;
  heterodyne.unwrap = PhaseUnwrap::kHeterodyne;
  heterodyne.rows = true;
  heterodyne.reversed = true;
  heterodyne.offset_rad = 0.3;
  heterodyne.periods_px = {1000.0 / 70.0, 1000.0 / 64.0, 1000.0 / 59.0};
  heterodyne.row_periods_px = {60.0, 1200.0 / 19.0};
  compare_backends(make_phase_shift_pattern_set(heterodyne));
  MicroPhaseOptions micro;
  micro.rows = true;
  micro.steps = 4;
  micro.reversed = true;
  micro.offset_rad = -0.4;
  micro.row_periods_px = {23.75, 22.2125, 21.625, 21.4375, 20.0, 21.9875};
  compare_backends(make_micro_phase_pattern_set(micro));
}

}  // namespace
}  // namespace sls
