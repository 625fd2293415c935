// sls bench: the user-facing benchmark (issue 18): a simulated turntable revolution at a preset's
// size through the scan session as a user waits for it — each frame's pattern stack (or depth
// map) rendered into host memory first, not timed, then decoded, tracked, fused, the volume
// moved and the model raycast (every add_frame: uploads, host work, moves, the deformation's
// share), the loop closure and the final (deformed) model extracted into host memory, timed.
// It prints the end-to-end seconds of the revolution with the per-stage medians and totals
// beside them, the slowest frames, and on a GPU its memory in use and the device-to-device copy
// bandwidth measured in the same run (the ceiling a memory-bound kernel is judged against) with
// each hot kernel's GPU time and achieved bandwidth as a fraction of it (sdk/core/kernel_profile.h:
// CUDA events around the launches, bytes by each launcher's traffic model).
// After the timed part, the model's accuracy against the simulator's exact truth (sls eval's
// C2C, edge C2C, ATE and loop-closure error), so a run under a GPU memory budget can be
// compared with one without on accuracy as well as speed.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <future>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/rig.h"
#include "drivers/sim/scene.h"
#include "samples/sls/commands.h"
#include "sdk/eval/evaluate.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/kernel_profile.h"
#include "sdk/core/memory_type.h"
#include "sdk/core/serial_worker.h"
#include "sdk/core/stopwatch.h"
#include "sdk/core/trajectory.h"
#include "sdk/session/scan_session.h"
#include "sdk/session/scan_setup.h"

namespace sls::cli {
namespace {

struct BenchOptions {
  std::string preset = "demo";
  std::string object = "knurled-screw";
  int frames = 0;
  std::string input = "patterns";
  bool turntable_prior = false;
  std::string deformation = "on";
  std::string upload_ahead = "on";
  std::string stack_memory = "auto";
  std::string background_shipping = "on";
  double max_gpu_memory = 0.0;
  std::string device;
};

// The value at fraction q of the sorted values (0: the smallest, 1: the largest).
double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const std::size_t i = static_cast<std::size_t>(std::lround(q * static_cast<double>(values.size() - 1)));
  return values[std::min(i, values.size() - 1)];
}

double sum(const std::vector<double>& values) {
  double total = 0.0;
  for (const double v : values) total += v;
  return total;
}

// The frames' timestamps: the paper's 3 Hz.
constexpr std::int64_t kBenchFrameInterval_ns = 333'333'333;
// The model's points evaluated at most, beyond it a deterministic stride over them: a bound on
// the evaluation's time, above the paper preset's model (~6 M points, all evaluated: 6 M points
// on the knurled screw took 2.6 s on 2 busy cores, on the knob 9.3 s; OpenMP over points).
constexpr std::size_t kBenchMaxEvaluatedPoints = 8'000'000;

// The model's accuracy against the simulator's exact truth, as `sls eval` measures a result
// (evaluate.h): the session's world frame (the first fused frame's camera frame as tracked)
// moved onto the object frame by aligning that frame's pose to its true one, then the points'
// C2C and edge C2C (edge band: sls eval's default of 3 voxels), the trajectory's ATE and
// loop-closure error against the rig's true poses matched by timestamp. Figures in µm and
// degrees; null where there is nothing to measure (no creases, fewer than two fused frames).
nlohmann::json bench_accuracy(const session::ScanSession& session, const PointCloud& cloud, const sim::SimRig& rig,
                              const sim::Scene& scene, int frames, double voxel_size_m) {
  constexpr double kMicrometres = 1e6;
  const double degrees_per_radian = 180.0 / std::acos(-1.0);
  const auto um = [&](const eval::DistanceStats& stats, double eval::DistanceStats::*field) {
    return stats.count > 0 ? nlohmann::json(stats.*field * kMicrometres) : nlohmann::json(nullptr);
  };
  const double edge_band_m = eval::EvalOptions{}.edge_band_voxels * voxel_size_m;
  nlohmann::json accuracy = {{"points", cloud.size()},
                             {"evaluated_points", 0},
                             {"edge_band_um", edge_band_m * kMicrometres},
                             {"c2c_mean_um", nullptr},
                             {"c2c_rms_um", nullptr},
                             {"c2c_p95_um", nullptr},
                             {"c2c_max_um", nullptr},
                             {"c2c_edge_mean_um", nullptr},
                             {"ate_rmse_um", nullptr},
                             {"ate_max_um", nullptr},
                             {"loop_closure_error_um", nullptr},
                             {"loop_closure_error_deg", nullptr}};
  const std::vector<StampedPose> estimated = session.trajectory();  // deformed, as sls scan writes it
  std::vector<StampedPose> truth;
  for (int k = 0; k < frames; ++k) {
    truth.push_back({static_cast<double>(static_cast<std::int64_t>(k) * kBenchFrameInterval_ns) * 1e-9,
                     rig.T_object_camera(k)});
  }
  std::string why;
  const std::optional<eval::TrajectoryErrors> trajectory = eval::trajectory_errors(estimated, truth, &why);
  if (trajectory) {
    accuracy["ate_rmse_um"] = trajectory->ate_rmse_m * kMicrometres;
    accuracy["ate_max_um"] = trajectory->ate_max_m * kMicrometres;
    accuracy["ate_frames"] = trajectory->matched_frames;
    accuracy["loop_closure_error_um"] = trajectory->loop_closure_error_m * kMicrometres;
    accuracy["loop_closure_error_deg"] = trajectory->loop_closure_error_rad * degrees_per_radian;
  } else {
    accuracy["trajectory_note"] = why;
  }
  // The first fused frame: its tracked (deformed) pose against its true one.
  const std::vector<session::FrameReport>& reports = session.frames();
  const auto first = std::find_if(reports.begin(), reports.end(), [](const session::FrameReport& report) {
    return report.status == session::FrameStatus::kFused;
  });
  if (first == reports.end() || estimated.empty() || cloud.empty()) return accuracy;
  const Pose T_object_world = rig.T_object_camera(first->index) * estimated.front().T_world_camera.inverse();
  const std::size_t stride = (cloud.size() + kBenchMaxEvaluatedPoints - 1) / kBenchMaxEvaluatedPoints;
  std::vector<Eigen::Vector3d> points;
  points.reserve(cloud.size() / stride + 1);
  for (std::size_t n = 0; n < cloud.size(); n += stride) {
    points.push_back(T_object_world * cloud.positions[n].cast<double>());
  }
  const eval::SurfaceErrors errors = eval::surface_errors(points, scene, edge_band_m);
  accuracy["evaluated_points"] = points.size();
  accuracy["c2c_mean_um"] = um(errors.all, &eval::DistanceStats::mean_m);
  accuracy["c2c_rms_um"] = um(errors.all, &eval::DistanceStats::rms_m);
  accuracy["c2c_p95_um"] = um(errors.all, &eval::DistanceStats::p95_m);
  accuracy["c2c_max_um"] = um(errors.all, &eval::DistanceStats::max_m);
  accuracy["c2c_edge_mean_um"] =
      errors.has_creases ? um(errors.edge, &eval::DistanceStats::mean_m) : nlohmann::json(nullptr);
  return accuracy;
}

// "n/a" for a null figure, else the number with `decimals` and `unit`.
std::string bench_figure(const nlohmann::json& value, int decimals, const char* unit) {
  return value.is_number() ? fmt::format("{:.{}f}{}", value.get<double>(), decimals, unit) : std::string("n/a");
}

nlohmann::json run_bench(const Context& context, const BenchOptions& options, const Device& device) {
  sim::RigOptions rig_options;
  rig_options.preset = options.preset;
  rig_options.frames = options.frames;
  const sim::Scene scene = sim::make_scene(options.object);
  const sim::SimRig rig = sim::make_rig(rig_options, scene);
  sim::Renderer renderer(rig, scene, device);
  // As a camera delivers a GPU scan's images (drivers::Camera::set_image_memory).
  const bool pinned_stacks = options.stack_memory == "pinned" || (options.stack_memory == "auto" && device.is_cuda());
  renderer.set_image_memory(pinned_stacks ? MemoryType::kPinned : MemoryType::kHost);
  const int frames = rig.turntable.steps_per_revolution;
  const bool patterns = options.input == "patterns";

  session::ScanSessionOptions session_options;
  session_options.device = device;
  session_options.max_voxels = session::automatic_max_voxels(device);
  if (options.preset == "paper") {
    // The paper's volume: 960³ voxels over 10 mm (Table II's set-up).
    session_options.voxel_size_m = 10.4e-6;
    session_options.volume_size_m = Eigen::Vector3d::Constant(960 * session_options.voxel_size_m * (1.0 - 1e-9));
  }
  session_options.max_gpu_bytes = options.max_gpu_memory;
  session_options.ship_in_background = options.background_shipping == "on";
  session_options.turntable_prior = options.turntable_prior;
  session_options.deformation.enabled = options.deformation == "on";
  session::ScanSession session(rig.calibration(), patterns ? &rig.patterns : nullptr, session_options);

  const ProgressCallback progress = context.progress_callback("bench");
  std::vector<double> frame_ms, decode, track, integrate, move, raycast, deform;
  std::vector<double> upload_wait;  // after its own work, each frame waiting for the next stack's upload
  std::vector<double> move_resample, move_ship, move_assemble;  // of the frames whose volume moved
  double render_s = 0.0, frames_s = 0.0;
  int lost = 0;
  int unverified = 0;  // fused at the turntable prior: too little overlap with the model to track
  const auto render = [&](int k) {
    const SteadyClock::time_point start = SteadyClock::now();
    renderer.set_frame(k);
    session::ScanFrame frame;
    frame.index = k;
    frame.timestamp_ns = static_cast<std::int64_t>(k) * kBenchFrameInterval_ns;
    frame.turntable_angle_deg = rig.commanded_angle_deg(k);
    if (patterns) {
      for (int j = 0; j < static_cast<int>(rig.patterns.size()); ++j) frame.images.push_back(renderer.render_pattern(j));
    } else {
      frame.depth_m = renderer.render_depth();
    }
    render_s += ms_since(start) * 1e-3;
    return frame;
  };
  // Frame k + 1 is rendered before frame k is timed, so that its stack can be uploaded while
  // frame k is fused (ScanSession::prefetch, as run_pipeline does live); a frame's time runs
  // until both are done.
  const bool upload_ahead = options.upload_ahead == "on" && session.uploads_ahead();
  session::ScanFrame next = render(0);
  // What the images got (a pinned request falls back to pageable where none can be had).
  MemoryType stack_memory = next.images.empty() ? MemoryType::kHost : next.images.front().memory_type();
  // What the GPU holds before the scan's first frame (the renderer, the decoder), and the most
  // from here to the final model.
  const GpuAllocations before_scan = gpu_allocations();
  reset_gpu_allocation_peak();
  // Each hot kernel's GPU time and traffic, from the first frame to the final model.
  if (device.is_cuda()) set_kernel_profiling(true);
  SerialWorker uploader;  // the uploads ahead on one thread, as run_pipeline's
  for (int k = 0; k < frames; ++k) {
    report_progress(progress, {"bench", static_cast<std::size_t>(k), static_cast<std::size_t>(frames), ""});
    const session::ScanFrame frame = std::move(next);
    next = k + 1 < frames ? render(k + 1) : session::ScanFrame{};
    if (!next.images.empty()) stack_memory = next.images.front().memory_type();
    const SteadyClock::time_point start = SteadyClock::now();
    std::future<bool> ahead;
    const WaitOnExit<bool> wait_upload(ahead);  // before `next` moves, also when add_frame throws
    if (upload_ahead && k + 1 < frames) {
      ahead = uploader.submit([&session, &next] { return session.prefetch(next); });
    }
    const session::FrameReport report = session.add_frame(frame);
    double waited_ms = 0.0;
    if (ahead.valid()) {
      const SteadyClock::time_point fused = SteadyClock::now();
      ahead.get();
      waited_ms = ms_since(fused);
    }
    upload_wait.push_back(waited_ms);
    const double ms = ms_since(start);
    frames_s += ms * 1e-3;
    frame_ms.push_back(ms);
    if (report.status != session::FrameStatus::kFused) ++lost;
    if (report.status == session::FrameStatus::kFused && report.unverified) ++unverified;
    const session::StageTimes& t = report.times;
    decode.push_back(t.decode_ms);
    track.push_back(t.track_ms);
    integrate.push_back(t.integrate_ms);
    move.push_back(t.move_ms);
    raycast.push_back(t.raycast_ms);
    deform.push_back(t.deform_ms);
    if (report.move.moved) move_resample.push_back(report.move.resample_ms);
    if (const fusion::MoveStats* ship = report.ship()) {
      move_ship.push_back(ship->ship_ms);
      move_assemble.push_back(ship->ship_assemble_ms);
    }
  }
  report_progress(progress, {"bench", static_cast<std::size_t>(frames), static_cast<std::size_t>(frames), ""});
  SteadyClock::time_point start = SteadyClock::now();
  nlohmann::json loop = nullptr;
  if (session.deformation_enabled()) {
    try {
      const session::LoopClosureReport closed = session.close_loop();
      loop = {{"closed", true}, {"ms", closed.ms}, {"solve_ms", closed.solve.ms}, {"constraints", closed.constraints}};
    } catch (const Error& error) {
      if (error.code() != ErrorCode::kInvalidArgument) throw;
      loop = {{"closed", false}, {"reason", error.what()}};
    }
  }
  const double loop_s = ms_since(start) * 1e-3;
  start = SteadyClock::now();
  session::ModelTimes model_times;
  const fusion::ExtractedSurface model = session.final_surface(&model_times);
  const double extract_s = ms_since(start) * 1e-3;
  const GpuAllocations scan_allocations = gpu_allocations();
  const std::vector<KernelFigures> kernels = kernel_profile();
  set_kernel_profiling(false);

  const auto stage = [](const std::vector<double>& ms) {
    return nlohmann::json{{"median_ms", quantile(ms, 0.5)}, {"total_s", sum(ms) * 1e-3}};
  };
  const fusion::VolumeGeometry& geometry = session.volume_geometry();
  nlohmann::json result = {
      {"preset", options.preset},
      {"object", options.object},
      {"input", options.input},
      {"upload_ahead", upload_ahead},
      {"stack_memory", memory_type_name(stack_memory)},
      {"background_shipping", device.is_cuda() && session_options.ship_in_background},
      {"device", device.to_string()},
      {"frames", frames},
      {"frames_fused", session.fused_count()},
      {"frames_lost", lost},
      {"frames_unverified", unverified},
      {"camera", {{"width", rig.calibration().camera.width}, {"height", rig.calibration().camera.height}}},
      {"images_per_frame", patterns ? rig.patterns.size() : 0},
      {"volume",
       {{"voxels", {geometry.nx, geometry.ny, geometry.nz}},
        {"voxel_size_m", geometry.voxel_size_m},
        {"bytes", session.volume_bytes()},
        {"moves", session.moves()},
        // A move's parts, over the moves: the resampling, the shipping of the surface that
        // leaves (on a GPU beside the frame loop, collected before the next keyframe or move;
        // a ship the frames did not collect is not counted), and of that the host's assembly
        // of its points and triangles (GPU).
        {"move_stages",
         {{"resample", stage(move_resample)}, {"ship", stage(move_ship)}, {"ship_assemble", stage(move_assemble)}}}}},
      {"end_to_end_s", frames_s + loop_s + extract_s},
      {"frames_s", frames_s},
      {"loop_closure_s", loop_s},
      {"extract_s", extract_s},
      // The final model's parts (ScanSession::ModelTimes), seconds.
      {"extract_stages",
       {{"wait_ship_s", model_times.volume.wait_ship_ms * 1e-3},
        // Found beside the loop closure (MovingVolume::prepare_final_surface): its own time,
        // and what the final model still waited for it.
        {"volume_surface_s", model_times.volume.extract_ms * 1e-3},
        {"volume_surface_beside_loop_closure", model_times.volume.prepared},
        {"wait_volume_surface_s", model_times.volume.wait_prepared_ms * 1e-3},
        {"assemble_s", model_times.volume.assemble_ms * 1e-3},
        {"join_s", model_times.volume.join_ms * 1e-3},
        {"deform_s", model_times.deform_ms * 1e-3}}},
      {"render_s", render_s},
      {"frame_ms", {{"median", quantile(frame_ms, 0.5)}, {"p95", quantile(frame_ms, 0.95)}, {"max", quantile(frame_ms, 1.0)}}},
      // Every frame's time and stages, in frame order: where the slow frames' time goes.
      {"per_frame",
       {{"frame_ms", frame_ms},
        {"decode_ms", decode},
        {"track_ms", track},
        {"integrate_ms", integrate},
        {"move_ms", move},
        {"raycast_ms", raycast},
        {"deform_ms", deform},
        {"upload_wait_ms", upload_wait}}},
      {"stages",
       {{"decode", stage(decode)},
        {"track", stage(track)},
        {"integrate", stage(integrate)},
        {"move", stage(move)},
        {"raycast", stage(raycast)},
        {"deform", stage(deform)},
        {"upload_wait", stage(upload_wait)}}},
      {"loop_closure", loop},
      {"points", model.cloud.size()}};
  if (device.is_cuda()) {
    const GpuMemory memory = gpu_memory(device);
    result["gpu"] = {{"name", cuda_device_name(device.id)},
                     {"memory_used_bytes", memory.used_bytes},
                     {"memory_total_bytes", memory.total_bytes},
                     {"budget_bytes", options.max_gpu_memory},
                     {"allocated_before_scan_bytes", before_scan.in_use_bytes},
                     {"allocated_peak_bytes", scan_allocations.peak_bytes},
                     {"copy_bandwidth_gb_s", copy_bandwidth_gbps(device)}};
    // Each hot kernel's achieved (effective) bandwidth against the copy's (kernel_profile.h).
    const double copy_gb_s = result["gpu"]["copy_bandwidth_gb_s"].get<double>();
    nlohmann::json kernel_rows = nlohmann::json::array();
    for (const KernelFigures& k : kernels) {
      kernel_rows.push_back({{"name", k.name},
                             {"launches", k.launches},
                             {"gpu_s", k.gpu_ms * 1e-3},
                             {"mean_ms", k.gpu_ms / static_cast<double>(k.launches)},
                             {"model_bytes", k.bytes},
                             {"achieved_gb_s", k.achieved_gb_s()},
                             {"fraction_of_copy", copy_gb_s > 0.0 ? k.achieved_gb_s() / copy_gb_s : 0.0}});
    }
    result["gpu"]["kernels"] = kernel_rows;
  }
  // Not timed, not in end_to_end_s: on the host, after every GPU figure above.
  start = SteadyClock::now();
  result["accuracy"] = bench_accuracy(session, model.cloud, rig, scene, frames, geometry.voxel_size_m);
  result["evaluate_s"] = ms_since(start) * 1e-3;
  return result;
}

void print_bench(const nlohmann::json& r) {
  std::cout << fmt::format("{} revolution of the {} ({} frames of {}x{}{}), {} voxels of {:.1f} um, on {}\n",
                           r["preset"].get<std::string>(), r["object"].get<std::string>(), r["frames"].get<int>(),
                           r["camera"]["width"].get<int>(), r["camera"]["height"].get<int>(),
                           r["input"] == "patterns"
                               ? fmt::format(", {} images each", r["images_per_frame"].get<std::size_t>())
                               : std::string(", depth maps"),
                           fmt::format("{}x{}x{}", r["volume"]["voxels"][0].get<int>(), r["volume"]["voxels"][1].get<int>(),
                                       r["volume"]["voxels"][2].get<int>()),
                           r["volume"]["voxel_size_m"].get<double>() * 1e6, r["device"].get<std::string>());
  std::cout << fmt::format("end to end {:.2f} s: frames {:.2f} s, loop closure {:.2f} s, final model {:.2f} s "
                           "(rendering {:.2f} s, not timed)\n",
                           r["end_to_end_s"].get<double>(), r["frames_s"].get<double>(),
                           r["loop_closure_s"].get<double>(), r["extract_s"].get<double>(), r["render_s"].get<double>());
  const nlohmann::json& m = r["extract_stages"];
  std::cout << fmt::format("final model s: waiting for a ship {:.2f}, the volume's surface {:.2f} (host assembly "
                           "{:.2f}), joined to the shipped parts {:.2f}, deformed {:.2f}; stacks in {} memory\n",
                           m["wait_ship_s"].get<double>(), m["volume_surface_s"].get<double>(),
                           m["assemble_s"].get<double>(), m["join_s"].get<double>(), m["deform_s"].get<double>(),
                           r["stack_memory"].get<std::string>());
  std::cout << fmt::format("frame ms: median {:.1f}, p95 {:.1f}, max {:.1f}; fused {} of {} ({} at the turntable "
                           "prior, unverified), {} moves\n",
                           r["frame_ms"]["median"].get<double>(), r["frame_ms"]["p95"].get<double>(),
                           r["frame_ms"]["max"].get<double>(), r["frames_fused"].get<std::size_t>(),
                           r["frames"].get<int>(), r["frames_unverified"].get<int>(), r["volume"]["moves"].get<int>());
  const nlohmann::json& a = r["accuracy"];
  std::cout << fmt::format("accuracy against the exact scene ({} of {} points, {:.2f} s, not timed): C2C mean {}, "
                           "RMS {}, p95 {}, edge mean {}; ATE RMSE {}, max {}; loop error {}, {}\n",
                           a["evaluated_points"].get<std::size_t>(), a["points"].get<std::size_t>(),
                           r["evaluate_s"].get<double>(), bench_figure(a["c2c_mean_um"], 2, " um"),
                           bench_figure(a["c2c_rms_um"], 2, " um"), bench_figure(a["c2c_p95_um"], 2, " um"),
                           bench_figure(a["c2c_edge_mean_um"], 2, " um"), bench_figure(a["ate_rmse_um"], 2, " um"),
                           bench_figure(a["ate_max_um"], 2, " um"), bench_figure(a["loop_closure_error_um"], 2, " um"),
                           bench_figure(a["loop_closure_error_deg"], 4, " deg"));
  std::cout << "stage      median ms   total s\n";
  for (const auto& [name, figures] : r["stages"].items()) {
    std::cout << fmt::format("{:<10} {:9.2f} {:9.2f}\n", name, figures["median_ms"].get<double>(),
                             figures["total_s"].get<double>());
  }
  if (r.contains("gpu")) {
    std::cout << fmt::format("GPU {}: {:.2f} GiB in use of {:.2f}, device copy {:.0f} GB/s\n",
                             r["gpu"]["name"].get<std::string>(),
                             static_cast<double>(r["gpu"]["memory_used_bytes"].get<std::size_t>()) / 1073741824.0,
                             static_cast<double>(r["gpu"]["memory_total_bytes"].get<std::size_t>()) / 1073741824.0,
                             r["gpu"]["copy_bandwidth_gb_s"].get<double>());
    std::cout << fmt::format("slscan's GPU allocations: {:.2f} GB at most ({:.2f} GB before the first frame){}\n",
                             static_cast<double>(r["gpu"]["allocated_peak_bytes"].get<std::size_t>()) * 1e-9,
                             static_cast<double>(r["gpu"]["allocated_before_scan_bytes"].get<std::size_t>()) * 1e-9,
                             r["gpu"]["budget_bytes"].get<double>() > 0.0
                                 ? fmt::format(", budget {:.2f} GB", r["gpu"]["budget_bytes"].get<double>() * 1e-9)
                                 : std::string());
    std::cout << "kernel          launches   GPU s   mean ms   GB/s   of the copy's\n";
    for (const nlohmann::json& k : r["gpu"]["kernels"]) {
      std::cout << fmt::format("{:<15} {:8} {:7.2f} {:9.3f} {:6.0f} {:8.0f} %\n", k["name"].get<std::string>(),
                               k["launches"].get<std::size_t>(), k["gpu_s"].get<double>(), k["mean_ms"].get<double>(),
                               k["achieved_gb_s"].get<double>(), 100.0 * k["fraction_of_copy"].get<double>());
    }
  }
}

}  // namespace

void add_bench_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "bench", "Benchmark a simulated turntable revolution end to end: decode, track, fuse, moves, deformation, "
               "loop closure and the final model, per-stage medians beside the total");
  auto options = std::make_shared<BenchOptions>();
  command->add_option("--preset", options->preset, "ci (400x300, 36 frames), demo (800x600, 120) or paper (4000x3000, 440)")
      ->check(CLI::IsMember({"ci", "demo", "paper"}))
      ->capture_default_str();
  command->add_option("--object", options->object, "Simulated object")
      ->check(CLI::IsMember({"knurled-screw", "knurled-knob"}))
      ->capture_default_str();
  command->add_option("--frames", options->frames, "Frames per revolution (0: the preset's)")
      ->check(CLI::Range(0, 100000));
  command->add_option("--input", options->input,
                      "patterns: each frame's pattern stack, decoded by the session; depth: the simulator's depth maps "
                      "(no decoding)")
      ->check(CLI::IsMember({"patterns", "depth"}))
      ->capture_default_str();
  command->add_flag("--turntable-prior", options->turntable_prior,
                    "The turntable's angles as the pose guess, as sls scan --turntable-prior (default: depth alone)");
  command->add_option("--deformation", options->deformation,
                      "Online deformation and, after the revolution, the loop closure (off: neither)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  command->add_option("--upload-ahead", options->upload_ahead,
                      "On a GPU, upload the next frame's pattern stack while this one is fused, as a live scan does "
                      "(off: each frame uploads its own)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  command->add_option("--stack-memory", options->stack_memory,
                      "Where the pattern images lie before the upload: pinned (page-locked, as a camera captures "
                      "them for a GPU scan), pageable, or auto (pinned on a GPU)")
      ->check(CLI::IsMember({"auto", "pinned", "pageable"}))
      ->capture_default_str();
  command->add_option("--background-shipping", options->background_shipping,
                      "On a GPU, ship a volume move's surface beside the frame loop, as a scan does (off: each move "
                      "ships before the next frame)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  command->add_option("--max-gpu-memory", options->max_gpu_memory,
                      "GPU memory budget in bytes (e.g. 6e9), as sls scan --max-gpu-memory (0: none)")
      ->check(finite_range(0.0, 1e15));
  command->add_option("--device", options->device, "cpu, cuda or cuda:N (default: cuda when a GPU is present, else cpu)");
  command->callback([&context, exit_code, options] {
    run_command(context, "bench", [&context, options] {
      const Device device = options->device.empty() ? default_device() : parse_device(options->device);
      require_device(device);
      const nlohmann::json result = run_bench(context, *options, device);
      context.emit(result, [&] { print_bench(result); });
      return kExitOk;
    }, exit_code);
  });
}

}  // namespace sls::cli
