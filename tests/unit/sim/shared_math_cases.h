// One body of per-case code that the CPU loop and the CUDA kernel of test_sim_shared_cuda
// both run: the pattern, optics and noise functions the renderer will call per pixel.
#pragma once

#include <cstdint>

#include "drivers/sim/noise_shared.h"
#include "drivers/sim/optics_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/decode/pattern_shared.h"

namespace sls::sim::test {

struct CaseResult {
  std::uint32_t philox[4];
  int dn;                // sensor_response over all Poisson branches and saturation
  int dn_noiseless;
  double poisson;        // a Poisson draw of a small mean (inversion branch)
  double blurred;        // pattern_value_blurred, double, from the descriptor
  double blurred_table;  // the same from a level table
  float blurred_float;   // float, from the table
  double blurred_gamma;  // double, from the descriptor, through a projector gamma of 2.2
  double camera_sigma_px;
  double projector_sigma_cols;
};

SLS_HOST_DEVICE inline void evaluate_case(int i, int count, const PatternDesc& pattern, PatternLevelTable table,
                                          CaseResult* out) {
  const double t = static_cast<double>(i) / static_cast<double>(count);
  const double u = -20.0 + t * (pattern.extent + 40.0);
  const double sigma = 0.05 + 0.07 * static_cast<double>(i % 97);  // 0.05 .. 6.8 px
  const Philox4x32Counter c = philox4x32_10(
      {{static_cast<std::uint32_t>(i), 0x243f6a88u, static_cast<std::uint32_t>(i) * 2654435761u, 7u}},
      {{0xa4093822u, static_cast<std::uint32_t>(i)}});
  for (int w = 0; w < 4; ++w) out->philox[w] = c.v[w];
  const SensorModel sensor = default_camera_sensor();
  NoiseKey key;
  key.seed = 0x123456789ull;
  key.frame = static_cast<std::uint32_t>(i % 7);
  key.image = static_cast<std::uint32_t>(i % 22);
  key.pixel = static_cast<std::uint32_t>(i);
  const double electrons = 11.3 * static_cast<double>(i % 1000);  // 0 .. 11289 e-: every branch, saturation
  out->dn = sensor_response(sensor, electrons, key);
  out->dn_noiseless = sensor_response_noiseless(sensor, electrons);
  NoiseStream stream = make_noise_stream(key, kUserStream);
  out->poisson = poisson_sample(stream, 0.01 * static_cast<double>(i % 1000));
  out->blurred = pattern_value_blurred(pattern, u, sigma);
  out->blurred_table = pattern_value_blurred(table, u, sigma);
  out->blurred_float = pattern_value_blurred(table, static_cast<float>(u), static_cast<float>(sigma));
  out->blurred_gamma = pattern_value_blurred(pattern, u, sigma, ProjectorGammaResponse{2.2});
  const RigOptics rig = default_rig_optics();
  const double depth = 0.09 + 2e-5 * static_cast<double>(i % 1000);
  out->camera_sigma_px = defocus_sigma_px(rig.camera_lens, rig.camera_sensor, depth);
  out->projector_sigma_cols = projector_blur_sigma_px(rig.projector, depth).x;
}

// Runs evaluate_case for i = 0 .. count-1 on the GPU (device 0).
void evaluate_cases_cuda(int count, const PatternDesc& pattern, const std::uint8_t* levels, CaseResult* results);

}  // namespace sls::sim::test
