// Ray-scene intersections of the knurled screw and knob on one core, the simulator's inner
// loop (before: the informal throughput prints of test_scene.cpp): rays as a camera 0.1 m away
// casts them at the knurl, in double and (the screw's GPU path) float.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "drivers/sim/scene.h"
#include "tests/unit/sim/scene_test_support.h"

namespace sls::sim {
namespace {

using namespace scene_test;  // NOLINT(google-build-using-namespace): the shared rays

constexpr int kRays = 20000;

// Casts every ray per iteration through `intersect_one`, which returns whether it hit.
template <typename RayType, typename IntersectOne>
void cast_rays(benchmark::State& state, const std::vector<RayType>& rays, IntersectOne intersect_one) {
  int hits = 0;
  for (auto _ : state) {
    for (const RayType& r : rays) hits += intersect_one(r) ? 1 : 0;
  }
  benchmark::DoNotOptimize(hits);
  state.SetItemsProcessed(state.iterations() * kRays);
}

void BM_IntersectScrewDouble(benchmark::State& state) {
  const Scene scene = make_scene("knurled-screw");
  std::mt19937 rng(8);
  std::vector<Ray> rays;
  for (int i = 0; i < kRays; ++i) rays.push_back(random_screw_ray(rng, scene.shape().screw, 0.1));
  cast_rays(state, rays, [&](const Ray& r) {
    Hit h;
    return intersect(scene.shape(), r, 0.0, 1.0, &h);
  });
}
BENCHMARK(BM_IntersectScrewDouble)->Unit(benchmark::kMillisecond);

void BM_IntersectScrewFloat(benchmark::State& state) {
  const Scene scene = make_scene("knurled-screw");
  const SceneShapeT<float> shape = scene.shape_float();
  std::mt19937 rng(8);
  std::vector<RayT<float>> rays;
  for (int i = 0; i < kRays; ++i) rays.push_back(to_float(random_screw_ray(rng, scene.shape().screw, 0.1)));
  cast_rays(state, rays, [&](const RayT<float>& r) {
    HitT<float> h;
    return intersect(shape, r, 0.0f, 1.0f, &h);
  });
}
BENCHMARK(BM_IntersectScrewFloat)->Unit(benchmark::kMillisecond);

void BM_IntersectKnob(benchmark::State& state) {
  const Scene scene = make_scene("knurled-knob");
  std::mt19937 rng(15);
  std::vector<Ray> rays;
  for (int i = 0; i < kRays; ++i) rays.push_back(random_knob_ray(rng, scene.shape().knob, 0.1));
  cast_rays(state, rays, [&](const Ray& r) {
    Hit h;
    return scene.intersect(r, 0.0, 1.0, &h);
  });
}
BENCHMARK(BM_IntersectKnob)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sls::sim

BENCHMARK_MAIN();
