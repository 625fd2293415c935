// Software-triggered grabs of 2048 × 2048 Mono16 images (8 MiB) from a fake GigE Vision camera
// over loopback through the Aravis driver: trigger (GVCP) → fake fills and sends (GVSP over
// UDP) → reassembled by Aravis → copied into a CapturedImage. At the negotiated packet size
// and, for comparison, at Ethernet's 1400 bytes. One frame in flight at a time, as the capture
// sequencer works. The fake's image source writes nothing, so its own cost is one copy per frame.
// Run in a private network namespace, as the tests do:
//   tests/hardware-free/aravis/run_in_netns.sh build/<dir>/tests/bench/bench_aravis_camera
#include <benchmark/benchmark.h>

#include <chrono>
#include <string>

#include "drivers/aravis/aravis_camera.h"
#include "sdk/core/error.h"
#include "tests/hardware-free/aravis/fake_gige_camera.h"

namespace sls {
namespace {

void BM_AravisSoftwareTriggeredGrab(benchmark::State& state) {
  const int side = static_cast<int>(state.range(0));
  const int requested_packet_size = static_cast<int>(state.range(1));
  test::FakeGigeCameraOptions fake_options;
  fake_options.image_source = [](const test::FakeFrameRequest&, ImageView<std::uint16_t>) {};
  test::FakeGigeCamera fake(fake_options);

  drivers::AravisCameraOptions options;
  options.pixel_format = "Mono16";
  options.width = side;
  options.height = side;
  options.packet_size = requested_packet_size;  // 0: negotiated
  auto camera = drivers::AravisCamera::open(fake.address(), options);
  camera->start();
  const std::chrono::milliseconds timeout(5000);
  for (int i = 0; i < 3; ++i) {  // warm-up: stream thread, buffers touched
    camera->software_trigger();
    camera->wait_image(timeout);
  }
  std::int64_t incomplete = 0;
  for (auto _ : state) {
    camera->software_trigger();
    const drivers::CapturedImage captured = camera->wait_image(timeout);
    if (!captured.complete) ++incomplete;
    benchmark::DoNotOptimize(captured.image.data());
  }
  const std::int64_t frame_bytes = static_cast<std::int64_t>(side) * side * 2;
  state.SetItemsProcessed(state.iterations());
  state.SetBytesProcessed(state.iterations() * frame_bytes);
  state.counters["packet_size"] = camera->packet_size();
  state.counters["incomplete"] = static_cast<double>(incomplete);
  state.SetLabel(std::to_string(side) + "x" + std::to_string(side) + " Mono16, packet " +
                 std::to_string(camera->packet_size()) + " B");
}
BENCHMARK(BM_AravisSoftwareTriggeredGrab)
    ->ArgNames({"side", "packet"})
    ->Args({2048, 0})
    ->Args({2048, 1400})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MinTime(3.0);

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
