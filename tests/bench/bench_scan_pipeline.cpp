// The scan session's per-frame pipeline at the paper's size: a full revolution (440 frames) of
// 4000 x 3000 depth maps of the simulated knurled screw (paper preset, depth-only mode: the
// decoder's noise model), tracked from depth alone (no ground-truth poses, no turntable
// prior), fused with GTSDF (3 iterations) into a moving 960³ volume of 10.4 µm voxels, the
// model raycast every frame. One benchmark iteration is the whole revolution; the counters
// are per-frame medians over it (the figure: track + integrate + move + raycast),
// each stage's median, the frames lost, the moves and the loop-closure drift against the
// simulator's true poses. Rendering the frames is not timed.
// Arguments: frames (0: the preset's 440), object (0 knurled screw, 1 knurled knob), the
// tracker's max_model_width (0: its default, full resolution; 2048: ICP at 2000 x 1500).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "drivers/sim/renderer.h"
#include "sdk/core/device.h"
#include "sdk/session/scan_session.h"

namespace sls {
namespace {

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

void BM_ScanPipeline(benchmark::State& state) {
  const Device device = default_device();
  if (!device.is_cuda()) {
    state.SkipWithError("no CUDA GPU: the paper-size pipeline needs one");
    return;
  }
  sim::RigOptions rig_options;
  rig_options.preset = "paper";
  rig_options.frames = static_cast<int>(state.range(0));
  const sim::Scene scene = sim::make_scene(state.range(1) == 0 ? "knurled-screw" : "knurled-knob");
  const sim::SimRig rig = sim::make_rig(rig_options, scene);
  sim::Renderer renderer(rig, scene, device);
  const int frames = rig.turntable.steps_per_revolution;

  session::ScanSessionOptions options;
  options.device = device;
  options.integration = fusion::IntegrationOptions::gtsdf();
  options.voxel_size_m = 10.4e-6;
  options.volume_size_m = Eigen::Vector3d::Constant(960 * options.voxel_size_m * (1.0 - 1e-9));
  if (state.range(2) > 0) options.tracking.max_model_width = static_cast<int>(state.range(2));
  for (auto _ : state) {
    session::ScanSession scan(rig.calibration(), nullptr, options);
    std::vector<double> pipeline, track, integrate, move, raycast, condition, inliers;
    std::vector<double> move_resample, move_ship, move_assemble, move_points;  // frames that moved
    double degenerate = 0.0;
    int lost = 0;
    std::string first_lost;
    for (int k = 0; k < frames; ++k) {
      renderer.set_frame(k);
      session::ScanFrame frame;
      frame.index = k;
      frame.timestamp_ns = static_cast<std::int64_t>(k) * 333'333'333;
      frame.depth_m = renderer.render_depth();
      const session::FrameReport report = scan.add_frame(frame);
      if (report.status != session::FrameStatus::kFused) {
        if (lost == 0) first_lost = "frame " + std::to_string(k) + ": " + report.reason;
        ++lost;
        continue;
      }
      if (k == 0) continue;  // no tracking yet
      const session::StageTimes& t = report.times;
      pipeline.push_back(t.track_ms + t.integrate_ms + t.move_ms + t.raycast_ms);
      track.push_back(t.track_ms);
      if (report.tracking) {
        condition.push_back(report.tracking->condition);
        inliers.push_back(report.tracking->inlier_fraction);
        degenerate += report.tracking->degenerate_directions;
      }
      integrate.push_back(t.integrate_ms);
      move.push_back(t.move_ms);
      raycast.push_back(t.raycast_ms);
      if (report.move.moved) {
        move_resample.push_back(report.move.resample_ms);
        move_ship.push_back(report.move.ship_ms);
        move_assemble.push_back(report.move.ship_assemble_ms);
        move_points.push_back(static_cast<double>(report.move.shipped_points));
      }
    }
    state.SetIterationTime(0.0);
    state.counters["median_ms"] = median(pipeline);
    state.counters["track_ms"] = median(track);
    state.counters["integrate_ms"] = median(integrate);
    state.counters["move_ms"] = median(move);
    state.counters["max_move_ms"] = move.empty() ? 0.0 : *std::max_element(move.begin(), move.end());
    state.counters["raycast_ms"] = median(raycast);
    // A move's parts (medians over the frames that moved).
    state.counters["move_resample_ms"] = median(move_resample);
    state.counters["move_ship_ms"] = median(move_ship);
    state.counters["move_ship_assemble_ms"] = median(move_assemble);
    state.counters["move_shipped_points"] = median(move_points);
    state.counters["lost"] = lost;
    state.counters["condition"] = median(condition);
    state.counters["inliers"] = median(inliers);
    state.counters["degenerate"] = degenerate / static_cast<double>(std::max<std::size_t>(condition.size(), 1));
    state.counters["moves"] = static_cast<double>(scan.moves());
    if (!first_lost.empty()) state.SetLabel("first lost " + first_lost);
    const std::vector<StampedPose> trajectory = scan.trajectory();
    if (trajectory.size() >= 2) {
      // Drift over the revolution: the first-to-last motion against the true one.
      const Pose truth = rig.T_object_camera(0).inverse() * rig.T_object_camera(frames - 1);
      const Pose estimate = trajectory.front().T_world_camera.inverse() * trajectory.back().T_world_camera;
      const Pose error = truth.inverse() * estimate;
      state.counters["loop_error_um"] = error.translation().norm() * 1e6;
      state.counters["loop_error_deg"] = error.angle_rad() * 180.0 / M_PI;
    }
  }
}
BENCHMARK(BM_ScanPipeline)
    ->Args({0, 0, 0})
    ->Args({0, 1, 0})
    ->Args({0, 0, 2048})
    ->Args({0, 1, 2048})
    ->ArgNames({"frames", "object", "model_width"})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
