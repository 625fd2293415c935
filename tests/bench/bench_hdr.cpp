// HDR on the simulator's knurled screw (issue 21's acceptance, docs/benchmarks.md): valid
// fraction and depth RMS against the ground truth of the painted (Lambertian) screw at one
// exposure, the metal screw at one exposure, and the metal screw fused from several
// (sdk/decode/hdr_fusion.h). The figures are counters; the time is the render + decode.
//   bench_hdr [--benchmark_filter=...]   environment: SLS_BENCH_HDR_WIDTH (default 800: the
//   demo preset's camera), SLS_BENCH_HDR_FRAMES (frames of the 120 of a revolution, evenly
//   spaced; default 2)
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <string>

#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "sdk/decode/decode_metrics.h"
#include "sdk/decode/hdr_fusion.h"

namespace sls {
namespace {

int env_int(const char* name, int fallback) {
  const char* value = std::getenv(name);
  return value != nullptr ? std::atoi(value) : fallback;
}

void run(benchmark::State& state, const std::string& material, const std::string& exposures_text) {
  const sim::Scene scene = sim::make_scene("knurled-screw");
  sim::RigOptions options;
  options.preset = "demo";
  options.camera_width = env_int("SLS_BENCH_HDR_WIDTH", 800);
  sim::SimRig rig = sim::make_rig(options, scene);
  if (!sim::surface_material_by_name(material.c_str(), &rig.material)) state.SkipWithError("unknown material");
  const HdrExposures exposures = parse_hdr_exposures(exposures_text);
  const int frames = env_int("SLS_BENCH_HDR_FRAMES", 2);
  const int revolution = rig.turntable.steps_per_revolution;
  DecodeErrorStats total;
  std::size_t saturated = 0, pixels = 0;
  for (auto _ : state) {
    sim::Renderer renderer(rig, scene, Device::cpu());
    Decoder decoder(rig.patterns, rig.calibration(), Device::cpu());
    for (int k = 0; k < frames; ++k) {
      renderer.set_frame(k * revolution / frames);
      std::vector<Image16u> images;
      for (std::size_t e = 0; e < exposures.count(); ++e) {
        for (int j = 0; j < static_cast<int>(rig.patterns.size()); ++j) {
          images.push_back(renderer.render_pattern(j, exposures.scales[e], static_cast<int>(e)));
        }
      }
      const HdrFusedStack fused = fuse_hdr_stack(images, rig.patterns.size(), exposures);
      const DecodedFrame decoded = decoder.decode(fused.images);
      const sim::GroundTruthFrame truth = renderer.ground_truth();
      total.accumulate(compare_with_ground_truth(decoded, truth.projector_u, truth.depth_m, truth.valid));
      for (std::size_t i = 0; i < decoded.mask.pixel_count(); ++i) {
        saturated += truth.valid.data()[i] != 0 && (decoded.mask.data()[i] & kDecodeSaturated) != 0;
      }
      pixels += decoded.mask.pixel_count();
    }
  }
  state.counters["valid_fraction"] = total.valid_fraction();
  state.counters["depth_rms_um"] = total.depth_rms_um();
  state.counters["projector_rms_px"] = total.projector_rms_px();
  state.counters["saturated_of_truth"] =
      total.truth_valid > 0 ? static_cast<double>(saturated) / static_cast<double>(total.truth_valid) : 0.0;
  state.counters["truth_valid"] = static_cast<double>(total.truth_valid);
  state.counters["width"] = rig.camera.width;
  state.counters["frames"] = frames;
}

const int registered = [] {
  struct Case {
    const char* name;
    const char* material;
    const char* exposures;
  };
  for (const Case& c : {Case{"painted/1", "painted", "1"}, Case{"metal/1", "metal", "1"},
                        Case{"metal/1,0.25", "metal", "1,0.25"}, Case{"metal/4,1,0.25", "metal", "4,1,0.25"}}) {
    benchmark::RegisterBenchmark((std::string("BM_HdrScrew/") + c.name).c_str(),
                                 [c](benchmark::State& state) { run(state, c.material, c.exposures); })
        ->Iterations(1)
        ->Unit(benchmark::kSecond);
  }
  return 0;
}();

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
