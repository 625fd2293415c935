// Long runs (issue 19): a simulated turntable revolution (ci preset at 240 x 180, 24 frames of
// 15°, depth maps of the knurled knob, turntable prior, a 1e6-voxel moving volume: the soak
// test's scan, test_scan_soak.cpp) replayed 20 times back to back on the default device.
// Argument: 0 a new ScanSession per revolution (many scans in one process), 1 one session fed
// revolution after revolution (a long scan; online deformation off: its graph grows by design)
// shipping every pass (RevisitPolicy::kKeep), 2 the same merging revisits from the start
// (kMerge: one copy of revisited surface), 3 the session's default (kAfterFirstRevolution: every
// pass of the first revolution, then merged) with online deformation on, as a scan runs.
// Counters per revolution r: rss_mib_rNN (VmRSS after it; for mode 0 after the session and
// its model are gone), heap_mib_rNN (bytes held on the heap, mallinfo2), ms_rNN (median
// ms/frame, the session's stages), model_mib_rNN for one session (its model, shipped parts and
// volume, cloud and mesh), and gpu_mib_rNN with a CUDA device (cudaMemGetInfo).
// Writing the recording is not timed.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "sdk/core/device.h"
#include "sdk/core/recording.h"
#include "sdk/session/scan_session.h"
#include "tests/support/model_size.h"
#include "tests/support/process_memory.h"

namespace sls {
namespace {

constexpr int kRevolutions = 20;
constexpr int kFrames = 24;
using test::gpu_used_mib;
using test::heap_mib;
using test::median;
using test::rss_mib;


void BM_Soak(benchmark::State& state) {
  const bool one_session = state.range(0) >= 1;
  const Device device = default_device();
  const std::string folder =
      (std::filesystem::temp_directory_path() / ("sls_bench_soak_" + std::to_string(::getpid()))).string();
  std::filesystem::remove_all(folder);
  sim::SimRecordingOptions sim_options;
  sim_options.object = "knurled-knob";
  sim_options.rig.preset = "ci";
  sim_options.rig.frames = kFrames;
  sim_options.rig.camera_width = 240;
  sim_options.depth_mode = true;
  sim::write_sim_recording(folder, sim_options, Device::cpu(), {});
  const RecordingReader rec = RecordingReader::open(folder);
  session::ScanSessionOptions options;
  options.device = device;
  options.max_voxels = 1e6;
  options.turntable_prior = true;
  const int mode = static_cast<int>(state.range(0));
  if (mode == 1 || mode == 2) options.deformation.enabled = false;
  if (mode == 1) options.revisits = session::RevisitPolicy::kKeep;
  if (mode == 2) options.revisits = session::RevisitPolicy::kMerge;
  const std::int64_t period_ns = rec.frame(rec.frame_count() - 1).timestamp_ns - rec.frame(0).timestamp_ns +
                                 (rec.frame(1).timestamp_ns - rec.frame(0).timestamp_ns);
  std::size_t fused = 0, frames = 0;
  for (auto _ : state) {
    std::unique_ptr<session::ScanSession> long_session;
    if (one_session) long_session = std::make_unique<session::ScanSession>(rec.calibration(), nullptr, options);
    for (int r = 0; r < kRevolutions; ++r) {
      std::vector<double> ms;
      {
        std::unique_ptr<session::ScanSession> scan;
        if (!one_session) scan = std::make_unique<session::ScanSession>(rec.calibration(), nullptr, options);
        session::ScanSession& s = one_session ? *long_session : *scan;
        for (std::size_t i = 0; i < rec.frame_count(); ++i) {
          const FrameInfo& info = rec.frame(i);
          session::ScanFrame frame;
          const int rr = one_session ? r : 0;  // a new scan starts again at frame 0
          frame.index = info.index + rr * kFrames;
          frame.timestamp_ns = info.timestamp_ns + rr * period_ns;
          if (info.turntable_angle_deg) frame.turntable_angle_deg = *info.turntable_angle_deg + 360.0 * rr;
          frame.depth_m = rec.load_depth_m(i);
          const session::FrameReport report = s.add_frame(frame);
          ms.push_back(report.times.total_ms());
          fused += report.status == session::FrameStatus::kFused ? 1 : 0;
          ++frames;
        }
        if (!one_session) benchmark::DoNotOptimize(s.final_surface());
      }
      char name[32];
      std::snprintf(name, sizeof name, "rss_mib_r%02d", r);
      state.counters[name] = rss_mib();
      std::snprintf(name, sizeof name, "heap_mib_r%02d", r);
      state.counters[name] = heap_mib();
      std::snprintf(name, sizeof name, "ms_r%02d", r);
      state.counters[name] = median(ms);
      if (one_session) {
        std::snprintf(name, sizeof name, "model_mib_r%02d", r);
        state.counters[name] = test::model_mib(long_session->final_surface_undeformed());
      }
      if (device.is_cuda()) {
        std::snprintf(name, sizeof name, "gpu_mib_r%02d", r);
        state.counters[name] = gpu_used_mib();
      }
    }
  }
  state.counters["fused_fraction"] = frames > 0 ? static_cast<double>(fused) / static_cast<double>(frames) : 0.0;
  std::filesystem::remove_all(folder);
}
BENCHMARK(BM_Soak)->Arg(0)->Arg(1)->Arg(2)->Arg(3)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
