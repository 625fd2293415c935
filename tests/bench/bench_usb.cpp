// Round trips of the USB device drivers through real libusb to the emulated devices
// (umockdev): what the protocol layers cost on top of the USB stack, and what a capture
// sequencer pays per projector or turntable command. Run under umockdev-wrapper:
//   umockdev-wrapper build/<dir>/tests/bench/bench_usb
// The emulated devices answer at once, so these are host-side costs (libusb, usbdevfs as
// umockdev emulates it, the codecs); a real DLPC350 polls its HID endpoints every 1 ms.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <memory>

#include "drivers/dlpc350/dlpc350_projector.h"
#include "drivers/headctl/head_controller.h"
#include "firmware-interface/models/dlpc350_model.h"
#include "firmware-interface/models/headctl_model.h"
#include "firmware-interface/models/umockdev/emulated_usb_bus.h"
#include "sdk/decode/pattern_set.h"

namespace sls {
namespace {

struct Bench {
  Bench() {
    bus = std::make_unique<fwif::models::EmulatedUsbBus>();
    bus->plug(projector_model, 1, 2);
    bus->plug(head_model, 1, 3);
  }
  std::unique_ptr<fwif::models::EmulatedUsbBus> bus;
  std::shared_ptr<fwif::models::Dlpc350Model> projector_model = std::make_shared<fwif::models::Dlpc350Model>();
  std::shared_ptr<fwif::models::HeadctlModel> head_model = std::make_shared<fwif::models::HeadctlModel>();
};

void BM_Dlpc350ReadRoundTrip(benchmark::State& state) {
  Bench bench;
  auto projector = drivers::Dlpc350Projector::open("dlpc350://");
  for (auto _ : state) benchmark::DoNotOptimize(projector->power());
}
BENCHMARK(BM_Dlpc350ReadRoundTrip)->Unit(benchmark::kMicrosecond);

// 66-byte MBOX_DATA write: two reports, one acknowledgement.
void BM_Dlpc350TwoReportWrite(benchmark::State& state) {
  Bench bench;
  auto projector = drivers::Dlpc350Projector::open("dlpc350://");
  std::vector<fwif::dlpc350::LutEntry> entries(22);
  std::vector<std::uint8_t> images(8);
  for (auto _ : state) projector->write_luts({22, false, 22, 8}, entries, images);
  state.SetLabel("PAT_CONFIG + 2 mailboxes = 9 commands");
}
BENCHMARK(BM_Dlpc350TwoReportWrite)->Unit(benchmark::kMicrosecond);

void BM_Dlpc350ShowPattern(benchmark::State& state) {
  Bench bench;
  auto projector = drivers::Dlpc350Projector::open("dlpc350://");
  projector->load_patterns(make_gray_phase_pattern_set());
  int index = 0;
  for (auto _ : state) {
    projector->show_pattern(index);
    index = (index + 1) % 22;
  }
}
BENCHMARK(BM_Dlpc350ShowPattern)->Unit(benchmark::kMillisecond);

void BM_Dlpc350LoadPatterns(benchmark::State& state) {
  Bench bench;
  auto projector = drivers::Dlpc350Projector::open("dlpc350://");
  const PatternSet set = make_gray_phase_pattern_set();
  for (auto _ : state) projector->load_patterns(set);
}
BENCHMARK(BM_Dlpc350LoadPatterns)->Unit(benchmark::kMillisecond);

void BM_HeadctlRoundTrip(benchmark::State& state) {
  Bench bench;
  auto board = drivers::HeadController::open("headctl://");
  for (auto _ : state) benchmark::DoNotOptimize(board->turntable_status());
}
BENCHMARK(BM_HeadctlRoundTrip)->Unit(benchmark::kMicrosecond);

void BM_HeadctlFireTrigger(benchmark::State& state) {
  Bench bench;
  auto board = drivers::HeadController::open("headctl://");
  board->configure_trigger({0, true, fwif::headctl::Polarity::kActiveHigh, 100, 0});
  for (auto _ : state) {
    state.PauseTiming();
    board->arm_triggers({0x01, fwif::headctl::TriggerSource::kHost, 1, 0});
    state.ResumeTiming();
    benchmark::DoNotOptimize(board->fire_trigger());
  }
}
BENCHMARK(BM_HeadctlFireTrigger)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace sls

int main(int argc, char** argv) {
  if (!sls::fwif::models::umockdev_preload_active()) {
    std::fprintf(stderr, "bench_usb: run it under umockdev-wrapper\n");
    return 2;
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
