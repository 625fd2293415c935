// The scan session's per-frame pipeline at the paper's size: a full revolution (440 frames) of
// 4000 x 3000 depth maps of the simulated knurled screw (paper preset, depth-only mode: the
// decoder's noise model), tracked from depth alone (no ground-truth poses, no turntable
// prior), fused with GTSDF (3 iterations) into a moving 960³ volume of 10.4 µm voxels, the
// model raycast every frame. One benchmark iteration is the whole revolution; the counters
// are per-frame medians over it (the figure: track + integrate + move + raycast),
// each stage's median, the frames lost, the moves and the loop-closure drift against the
// simulator's true poses. Rendering the frames is not timed.
// Arguments: frames (0: the preset's 440), object (0 knurled screw, 1 knurled knob), the
// tracker's max_model_width (0: its default, full resolution; 2048: ICP at 2000 x 1500),
// deformation (1: online deformation beside the frame loop, then the loop closure; 0: off),
// input (0: depth maps with the decoder's noise model; 1: the 22-image pattern stacks rendered
// by the simulator, decoded by the session on the GPU — rendering is not timed, decoding is).
// fusion (0: GTSDF, the default; 1: TSDF; 2: GTSDF with κ 0.1, the default before the study of
// bench_fusion_conditions).
// prior (0: depth alone; 1: the turntable prior, each frame carrying its commanded angle, as
// `sls scan --turntable-prior`: the tracker's degenerate directions keep the turntable's motion).
// loop_frames (0: the default DeformationOptions::loop_frames; else how many of the last frames
// the loop closure registers).
// The model is measured against the exact object as `sls eval` does (C2C, edge C2C within 3
// voxels of a crease; aligned at the first pose), deformed and as tracked; and as the paper's
// Table I (`sls eval --raw-scan`): in the four image quadrants of frame 0's view against that
// view's raw scan (frame 0 decoded by a decoder of its own, or its depth map) and against the
// exact surface (counters t1_<region>_raw_um / _surface_um, region ul, ur, ll, lr, all); not timed.
// The headline is the revolution as the user waits for it: every add_frame (uploads, host
// work, moves, the deformation's share), the loop closure and the final (deformed) surface's
// extraction, summed wall time (`revolution_s`), with the per-stage medians beside it; the
// trajectory's errors (ATE, loop) as tracked and as deformed.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include <chrono>
#include <optional>

#include "drivers/sim/renderer.h"
#include "sdk/eval/evaluate.h"
#include "sdk/eval/evaluate_regions.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
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
  options.integration =
      state.range(5) == 1 ? fusion::IntegrationOptions::tsdf() : fusion::IntegrationOptions::gtsdf();
  if (state.range(5) == 2) options.integration.kappa = 0.1;  // the default before the conditions study
  options.voxel_size_m = 10.4e-6;
  options.volume_size_m = Eigen::Vector3d::Constant(960 * options.voxel_size_m * (1.0 - 1e-9));
  if (state.range(2) > 0) options.tracking.max_model_width = static_cast<int>(state.range(2));
  options.deformation.enabled = state.range(3) != 0;
  options.turntable_prior = state.range(6) != 0;
  if (state.range(7) > 0) options.deformation.loop_frames = static_cast<int>(state.range(7));
  const bool patterns = state.range(4) != 0;
  using Clock = std::chrono::steady_clock;
  const auto seconds_since = [](Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
  };
  for (auto _ : state) {
    session::ScanSession scan(rig.calibration(), patterns ? &rig.patterns : nullptr, options);
    std::vector<double> pipeline, track, integrate, move, raycast, condition, inliers, deform, total;
    double frames_s = 0.0;
    std::vector<StampedPose> truth;
    std::vector<double> move_resample, move_ship, move_assemble, move_points;  // frames that moved
    double degenerate = 0.0;
    int lost = 0;
    std::string first_lost;
    Image32f raw_scan;  // frame 0's depth map, for Table I
    for (int k = 0; k < frames; ++k) {
      renderer.set_frame(k);
      session::ScanFrame frame;
      frame.index = k;
      frame.timestamp_ns = static_cast<std::int64_t>(k) * 333'333'333;
      if (options.turntable_prior) frame.turntable_angle_deg = rig.commanded_angle_deg(k);
      if (patterns) {
        for (int j = 0; j < static_cast<int>(rig.patterns.size()); ++j) frame.images.push_back(renderer.render_pattern(j));
      } else {
        frame.depth_m = renderer.render_depth();
      }
      truth.push_back({static_cast<double>(frame.timestamp_ns) * 1e-9, rig.T_object_camera(k)});
      if (k == 0) {
        raw_scan = patterns ? Decoder(rig.patterns, rig.calibration(), device, options.decode).decode(frame.images).depth_m
                            : *frame.depth_m;
      }
      const Clock::time_point start = Clock::now();
      const session::FrameReport report = scan.add_frame(frame);
      frames_s += seconds_since(start);
      total.push_back(report.times.total_ms());
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
      deform.push_back(t.deform_ms);
      if (report.move.moved) move_resample.push_back(report.move.resample_ms);
      if (const fusion::MoveStats* ship = report.ship()) {
        move_ship.push_back(ship->ship_ms);
        move_assemble.push_back(ship->ship_assemble_ms);
        move_points.push_back(static_cast<double>(ship->shipped_points));
      }
    }
    // The end of the revolution: the loop closure (with deformation) and the final surface.
    Clock::time_point start = Clock::now();
    if (scan.deformation_enabled()) {
      try {
        const session::LoopClosureReport loop = scan.close_loop();
        state.counters["loop_closure_ms"] = loop.ms;
        state.counters["loop_solve_ms"] = loop.solve.ms;
      } catch (const Error& error) {
        state.SetLabel(std::string("loop closure failed: ") + error.what());
      }
    }
    const double loop_s = seconds_since(start);
    start = Clock::now();
    const fusion::ExtractedSurface surface = scan.final_surface();
    const double extract_s = seconds_since(start);
    state.SetIterationTime(frames_s + loop_s + extract_s);
    state.counters["revolution_s"] = frames_s + loop_s + extract_s;
    state.counters["frames_s"] = frames_s;
    state.counters["extract_s"] = extract_s;
    state.counters["points"] = static_cast<double>(surface.cloud.size());
    if (scan.deformation_enabled()) {
      // The map deformation's share of the extraction: the same surface as tracked (not part
      // of the revolution's time).
      start = Clock::now();
      const fusion::ExtractedSurface tracked = scan.final_surface_undeformed();
      state.counters["extract_undeformed_s"] = seconds_since(start);
      state.counters["points_undeformed"] = static_cast<double>(tracked.cloud.size());
    }
    state.counters["frame_total_median_ms"] = median(total);
    state.counters["deform_frame_ms"] = median(deform);
    // All of the frame loop's deformation work (keyframes, shipped parts, the reference
    // raycast), slow frames included.
    state.counters["deform_frames_s"] = std::accumulate(deform.begin(), deform.end(), 0.0) * 1e-3;
    if (scan.deformation_enabled()) {
      const session::DeformationStatus status = scan.deformation_status(true);
      std::vector<double> jobs;
      for (const session::KeyframeSolve& k : scan.keyframe_solves()) jobs.push_back(k.ms);
      state.counters["worker_job_ms"] = median(jobs);
      state.counters["worker_s"] = status.worker_ms * 1e-3;
      state.counters["nodes"] = static_cast<double>(status.nodes);
      state.counters["constraints"] = static_cast<double>(status.constraints);
    }
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
    // Drift over the revolution: the first-to-last motion against the true one (the loop
    // error), and the ATE, as tracked and as deformed (sls eval's definitions).
    const auto errors = [&](const std::vector<StampedPose>& trajectory, const char* suffix) {
      const std::optional<eval::TrajectoryErrors> e = eval::trajectory_errors(trajectory, truth);
      if (!e) return;
      state.counters[std::string("loop_error_um") + suffix] = e->loop_closure_error_m * 1e6;
      state.counters[std::string("loop_error_deg") + suffix] = e->loop_closure_error_rad * 180.0 / M_PI;
      state.counters[std::string("ate_um") + suffix] = e->ate_rmse_m * 1e6;
    };
    errors(scan.trajectory_undeformed(), "");
    if (scan.deformation_enabled()) errors(scan.trajectory(), "_closed");
    {
      // The model against the exact object (not timed): world -> object by the first pose.
      const auto c2c = [&](const fusion::ExtractedSurface& model, const std::vector<StampedPose>& trajectory,
                           const char* suffix) {
        if (trajectory.empty() || model.cloud.empty()) return;
        const Pose T_object_world = rig.T_object_camera(0) * trajectory.front().T_world_camera.inverse();
        std::vector<Eigen::Vector3d> points(model.cloud.size());
        for (std::size_t i = 0; i < points.size(); ++i) {
          points[i] = T_object_world * model.cloud.positions[i].cast<double>();
        }
        const eval::SurfaceErrors e = eval::surface_errors(points, scene, 3.0 * options.voxel_size_m);
        state.counters[std::string("c2c_mean_um") + suffix] = e.all.mean_m * 1e6;
        state.counters[std::string("c2c_rms_um") + suffix] = e.all.rms_m * 1e6;
        state.counters[std::string("c2c_p95_um") + suffix] = e.all.p95_m * 1e6;
        state.counters[std::string("c2c_max_um") + suffix] = e.all.max_m * 1e6;
        state.counters[std::string("c2c_edge_um") + suffix] = e.edge.mean_m * 1e6;
        const eval::ViewRegionErrors t1 = eval::view_region_errors(
            model.cloud, raw_scan, rig.calibration().camera, trajectory.front().T_world_camera, &scene, T_object_world);
        const char* const names[4] = {"ul", "ur", "ll", "lr"};
        for (std::size_t q = 0; q <= 4; ++q) {
          const eval::RegionErrors& region = q < 4 ? t1.regions[q] : t1.all;
          const std::string key = std::string("t1_") + (q < 4 ? names[q] : "all");
          state.counters[key + "_raw_um" + suffix] = region.to_raw_scan.mean_m * 1e6;
          state.counters[key + "_surface_um" + suffix] = region.to_surface.mean_m * 1e6;
        }
      };
      if (scan.deformation_enabled()) {
        c2c(surface, scan.trajectory(), "_closed");
        c2c(scan.final_surface_undeformed(), scan.trajectory_undeformed(), "");
      } else {
        c2c(surface, scan.trajectory_undeformed(), "");
      }
    }
  }
}
BENCHMARK(BM_ScanPipeline)
    ->Args({0, 0, 0, 1, 0, 0, 0, 0})
    ->Args({0, 1, 0, 1, 0, 0, 0, 0})
    ->Args({0, 0, 0, 0, 0, 0, 0, 0})
    ->Args({0, 1, 0, 0, 0, 0, 0, 0})
    ->Args({0, 0, 2048, 1, 0, 0, 0, 0})
    ->Args({0, 1, 2048, 1, 0, 0, 0, 0})
    ->Args({0, 0, 0, 1, 1, 0, 0, 0})
    ->Args({0, 1, 0, 1, 1, 0, 0, 0})
    // Table I: TSDF against GTSDF from pattern stacks, without deformation as the paper's.
    ->Args({0, 0, 0, 0, 1, 0, 0, 0})
    ->Args({0, 0, 0, 0, 1, 1, 0, 0})
    ->Args({0, 0, 0, 0, 1, 2, 0, 0})
    // With the turntable prior: the screw's axial slide, which depth alone cannot see.
    ->Args({0, 0, 0, 1, 0, 0, 1, 0})
    ->Args({0, 1, 0, 1, 0, 0, 1, 0})
    ->Args({0, 0, 0, 1, 1, 0, 1, 0})
    ->Args({0, 1, 0, 1, 1, 0, 1, 0})
    ->ArgNames({"frames", "object", "model_width", "deformation", "input", "fusion", "prior", "loop_frames"})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
