// Throughput of the core file formats at real sizes: can a recording keep up with a
// 12-megapixel camera, and how fast are multi-million-point PLY clouds written and read.
// Figures go to docs/benchmarks.md with date, machine and sizes.
#include <cstdio>
#include <filesystem>
#include <random>

#include <benchmark/benchmark.h>

#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/ray_map.h"

namespace sls {
namespace {

// A 12-bit camera image of fringes with shot-like noise: what a recording stores.
Image16u fringe_image(int width, int height) {
  Image16u image(width, height);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 20.0f);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const float value = 2000.0f + 1500.0f * std::sin(static_cast<float>(x) * 0.05f) + noise(rng);
      image(x, y) = static_cast<std::uint16_t>(std::clamp(value, 0.0f, 4095.0f));
    }
  }
  return image;
}

void BM_PngEncode16(benchmark::State& state) {
  const Image16u image = fringe_image(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  PngWriteOptions options;
  options.compression_level = 1;
  std::size_t encoded_bytes = 0;
  for (auto _ : state) {
    const std::vector<std::uint8_t> encoded = encode_png(image.view(), options);
    encoded_bytes = encoded.size();
    benchmark::DoNotOptimize(encoded.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(static_cast<std::size_t>(state.iterations()) * image.size_bytes()));
  state.counters["encoded_MB"] = static_cast<double>(encoded_bytes) / 1e6;
}
BENCHMARK(BM_PngEncode16)->Args({4000, 3000})->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PngDecode16(benchmark::State& state) {
  const Image16u image = fringe_image(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const std::vector<std::uint8_t> encoded = encode_png(image.view());
  for (auto _ : state) {
    const AnyImage decoded = decode_png(encoded.data(), encoded.size(), "memory");
    benchmark::DoNotOptimize(&decoded);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(static_cast<std::size_t>(state.iterations()) * image.size_bytes()));
}
BENCHMARK(BM_PngDecode16)->Args({4000, 3000})->Unit(benchmark::kMillisecond)->UseRealTime();

PointCloud random_cloud(std::size_t count) {
  PointCloud cloud;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(-0.02f, 0.02f);
  cloud.positions.resize(count);
  cloud.normals.resize(count);
  cloud.confidence.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    cloud.positions[i] = {unit(rng), unit(rng), unit(rng)};
    cloud.normals[i] = cloud.positions[i].normalized();
    cloud.confidence[i] = 0.5f;
  }
  return cloud;
}

void BM_PlyWriteRead(benchmark::State& state) {
  const PointCloud cloud = random_cloud(static_cast<std::size_t>(state.range(0)));
  const std::string path = (std::filesystem::temp_directory_path() / "sls_bench_cloud.ply").string();
  for (auto _ : state) {
    write_ply(path, cloud);
    const PointCloud back = read_ply_cloud(path);
    benchmark::DoNotOptimize(back.positions.data());
  }
  std::filesystem::remove(path);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * state.range(0));
  state.counters["file_MB"] = static_cast<double>(cloud.size() * 28) / 1e6;
}
BENCHMARK(BM_PlyWriteRead)->Arg(10'000'000)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

void BM_RayMapCpu(benchmark::State& state) {
  CameraIntrinsics camera;
  camera.width = 4000;
  camera.height = 3000;
  camera.fx = camera.fy = 13000.0;
  camera.cx = 1999.5;
  camera.cy = 1499.5;
  camera.k1 = -0.12;
  camera.k2 = 0.3;
  camera.p1 = 2e-4;
  camera.p2 = -1e-4;
  for (auto _ : state) {
    const RayMap map = compute_ray_map(camera, Device::cpu());
    benchmark::DoNotOptimize(map.rays.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * 4000 * 3000);
}
BENCHMARK(BM_RayMapCpu)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
