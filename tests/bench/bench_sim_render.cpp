// The simulator's renderer at the paper's size (4000x3000 camera, knurled screw): the
// per-frame trace and one pattern image, on the CPU and on CUDA (resident in device memory,
// as a GPU pipeline would decode it), beside a device-to-device copy of the same bytes for
// scale. Figures go to docs/benchmarks.md.
#include <benchmark/benchmark.h>

#include "drivers/sim/renderer.h"
#include "sdk/core/device.h"

#if defined(SLS_HAVE_CUDA)
#include "sdk/core/cuda/device_buffer.h"
#endif

namespace sls::sim {
namespace {

Renderer make_renderer(const Device& device, int width) {
  RigOptions options;
  options.preset = "paper";
  options.camera_width = width;
  const Scene scene = make_scene("knurled-screw");
  return Renderer(make_rig(options, scene), scene, device);
}

Device device_for(std::int64_t flag) { return flag != 0 ? Device::cuda(0) : Device::cpu(); }

bool skip_without_gpu(benchmark::State& state) {
  if (state.range(0) != 0 && cuda_device_count() == 0) {
    state.SkipWithError("no CUDA device");
    return true;
  }
  return false;
}

void BM_SimTraceFrame(benchmark::State& state) {
  if (skip_without_gpu(state)) return;
  Renderer renderer = make_renderer(device_for(state.range(0)), static_cast<int>(state.range(1)));
  int frame = 0;
  for (auto _ : state) {
    renderer.set_frame(frame++ % 440);
    renderer.synchronize();
  }
  state.counters["Mpixel"] = static_cast<double>(renderer.rig().camera.width * renderer.rig().camera.height) / 1e6;
}

void BM_SimRenderPattern(benchmark::State& state) {
  if (skip_without_gpu(state)) return;
  Renderer renderer = make_renderer(device_for(state.range(0)), static_cast<int>(state.range(1)));
  renderer.set_frame(0);
  const int patterns = static_cast<int>(renderer.rig().patterns.size());
  int pattern = 0;
  renderer.render_pattern_resident(0);  // warm-up
  renderer.synchronize();
  for (auto _ : state) {
    renderer.render_pattern_resident(pattern++ % patterns);
    renderer.synchronize();
  }
  state.counters["Mpixel"] = static_cast<double>(renderer.rig().camera.width * renderer.rig().camera.height) / 1e6;
}

// Args: {cuda?, camera width}. The CPU runs a smaller image too, so CI-sized numbers exist.
BENCHMARK(BM_SimTraceFrame)->Args({1, 4000})->Args({0, 800})->Args({0, 4000})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SimRenderPattern)->Args({1, 4000})->Args({0, 800})->Args({0, 4000})->Unit(benchmark::kMillisecond)->UseRealTime();

#if defined(SLS_HAVE_CUDA)
// The bandwidth yardstick: copy 4000x3000 x 40 bytes (the per-pixel geometry the pattern
// kernels read) device to device.
void BM_DeviceToDeviceCopy(benchmark::State& state) {
  if (cuda_device_count() == 0) {
    state.SkipWithError("no CUDA device");
    return;
  }
  const std::size_t bytes = 4000ull * 3000ull * 40ull;
  DeviceBuffer<unsigned char> source(bytes), destination(bytes);
  SLS_CUDA_CHECK(cudaMemset(source.data(), 1, bytes));
  for (auto _ : state) {
    SLS_CUDA_CHECK(cudaMemcpy(destination.data(), source.data(), bytes, cudaMemcpyDeviceToDevice));
    SLS_CUDA_CHECK(cudaDeviceSynchronize());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(2 * bytes));
}
BENCHMARK(BM_DeviceToDeviceCopy)->Unit(benchmark::kMillisecond)->UseRealTime();
#endif

}  // namespace
}  // namespace sls::sim

BENCHMARK_MAIN();
