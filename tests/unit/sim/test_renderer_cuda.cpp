// The CUDA renderer equals the CPU renderer: geometry, pattern images (same noise draws) and
// depth-only maps, with uniform and varying albedo and a non-linear projector. Skipped without a GPU.
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include <gtest/gtest.h>

#include "drivers/sim/renderer.h"
#include "tests/support/test_support.h"
#include "tests/unit/sim/sim_test_rig.h"

namespace sls::sim {
namespace {

// The chessboard and the textured knob take the pixel-footprint path (the albedo integrated
// over each pixel, render_shared.h); the plain knurled objects the point sample.
Scene textured_knob() {
  KnurledKnobParameters parameters;
  parameters.albedo = {0.5, 0.3, 1e-3};
  return make_knurled_knob_scene(parameters);
}

TEST(RendererCuda, EqualsCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const std::pair<const char*, Scene> scenes[] = {{"knurled-screw", make_scene("knurled-screw")},
                                                  {"knurled-knob", make_scene("knurled-knob")},
                                                  {"chessboard", make_scene("chessboard")},
                                                  {"charuco (synthetic markers)", make_chessboard_scene(synthetic_charuco())},
                                                  {"textured knurled-knob", textured_knob()},
                                                  {"knurled-screw, projector gamma 2.2", make_scene("knurled-screw")}};
  for (const auto& [object, scene] : scenes) {
    SimRig rig = small_rig(scene, 400);
    if (std::string(object).find("gamma") != std::string::npos) rig.optics.projector.gamma = 2.2;
    Renderer cpu(rig, scene, Device::cpu());
    Renderer gpu(rig, scene, Device::cuda());
    cpu.set_frame(3);
    gpu.set_frame(3);
    const GroundTruthFrame cpu_truth = cpu.ground_truth();
    const GroundTruthFrame gpu_truth = gpu.ground_truth();
    std::size_t mask_differences = 0;
    double worst_depth = 0.0, worst_projector = 0.0;
    for (std::size_t i = 0; i < cpu_truth.valid.pixel_count(); ++i) {
      if (cpu_truth.valid.data()[i] != gpu_truth.valid.data()[i]) {
        ++mask_differences;
        continue;
      }
      worst_depth = std::max(worst_depth, static_cast<double>(std::abs(cpu_truth.depth_m.data()[i] - gpu_truth.depth_m.data()[i])));
      if (cpu_truth.valid.data()[i]) {
        worst_projector = std::max(worst_projector, static_cast<double>(std::abs(cpu_truth.projector_u.data()[i] -
                                                                                 gpu_truth.projector_u.data()[i])));
      }
    }
    EXPECT_LE(mask_differences, cpu_truth.valid.pixel_count() / 10000) << object;
    EXPECT_LT(worst_depth, 1e-9) << object;
    EXPECT_LT(worst_projector, 1e-3) << object;
    std::printf("%s: %zu mask differences, worst depth %.3g m, worst projector u %.3g px\n", object,
                mask_differences, worst_depth, worst_projector);
    for (int pattern = 0; pattern < static_cast<int>(rig.patterns.size()); ++pattern) {
      const Image16u a = cpu.render_pattern(pattern);
      const Image16u b = gpu.render_pattern(pattern);
      // The same noise draws: equal digital numbers, except where a float-rounded mean
      // straddles a rounding boundary between the backends (odds ~1e-8 per pixel) and the
      // shot-noise sampler then draws afresh; and ±1 DN where the analog value straddles a
      // quantisation step.
      std::size_t differing = 0, beyond_one = 0;
      for (std::size_t i = 0; i < a.pixel_count(); ++i) {
        const int difference = std::abs(static_cast<int>(a.data()[i]) - static_cast<int>(b.data()[i]));
        differing += difference != 0 ? 1u : 0u;
        beyond_one += difference > 1 ? 1u : 0u;
      }
      EXPECT_LE(beyond_one, 2u) << object << " pattern " << pattern << ": " << differing << " differing";
      EXPECT_LE(differing, a.pixel_count() / 1000) << object << " pattern " << pattern;
      std::printf("%s pattern %d: %zu of %zu pixels differ, %zu by more than 1 DN\n", object, pattern, differing,
                  a.pixel_count(), beyond_one);
    }
    const Image32f cpu_depth = cpu.render_depth();
    const Image32f gpu_depth = gpu.render_depth();
    double worst_noisy = 0.0;
    for (std::size_t i = 0; i < cpu_depth.pixel_count(); ++i) {
      if (cpu_truth.valid.data()[i] && gpu_truth.valid.data()[i]) {
        worst_noisy = std::max(worst_noisy, static_cast<double>(std::abs(cpu_depth.data()[i] - gpu_depth.data()[i])));
      }
    }
    EXPECT_LT(worst_noisy, 1e-7) << object;
  }
}

}  // namespace
}  // namespace sls::sim
