// sls scan: the scan pipeline, from a recording, the built-in simulator or devices by URI, to
// a model. Devices given by URI (--camera/--projector/--turntable, hardware or sim://) are
// scanned through the capture sequencer into OUT/recording; the simulator writes its capture
// there too; each frame is fused as it is recorded (sdk/session/frame_pipeline.h) when it can be
// (can_fuse_while_capturing), else after the capture. Every frame goes through the scan session (sdk/session): decode,
// track (--poses track: ICP against the model, a moving volume) or take the true pose
// (--poses groundtruth: simulated recordings, one fixed volume around the object), integrate,
// move, raycast; the model, trajectory and report are written to OUT.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <new>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/interfaces/device_uri.h"
#include "drivers/sim/sim_recording.h"
#include "fusion/extract.h"
#include "fusion/integrator.h"
#include "fusion/raycaster.h"
#include "fusion/tracker.h"
#include "samples/sls/capture.h"
#include "samples/sls/commands.h"
#include "sdk/eval/eval_json.h"
#include "sdk/eval/evaluate.h"
#include "samples/sls/output_files.h"
#include "samples/sls/scan_capture.h"
#include "samples/sls/scan_json.h"
#include "sdk/report/scan_report.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/stopwatch.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/decode/hdr_fusion.h"
#include "sdk/core/trajectory.h"
#include "sdk/session/capture_sequencer.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_session.h"
#include "sdk/session/scan_setup.h"

namespace sls::cli {
namespace {


using Clock = SteadyClock;

// Set by SIGINT / SIGTERM: the scan stops after the current frame and writes what it fused.
std::atomic<bool> g_stop_requested{false};
extern "C" void request_stop(int) { g_stop_requested.store(true); }

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

struct LoopClosureChoice {
  bool requested = false;
  std::string why;
};

// --loop-closure on|off, or by default on for a full turntable revolution.
LoopClosureChoice loop_closure_choice(const std::vector<std::optional<double>>& turntable_angles,
                                      const ScanOptions& options, bool deformation) {
  if (!deformation) return {false, options.poses == "groundtruth" ? "known poses" : "--deformation off"};
  if (options.loop_closure == "on") return {true, "--loop-closure on"};
  if (options.loop_closure == "off") return {false, "--loop-closure off"};
  std::string why;
  const bool full = session::is_full_revolution(turntable_angles, &why);
  return {full, why};
}

// Decodes, tracks (or takes the true poses) and fuses every frame of the recording at `folder`
// through a scan session, then writes the model, the trajectory and the report; returns the
// report. A replay (`live` null) reads the recording's frames a little ahead of fusing them; a
// live capture (--sim/--camera, capture.h's LiveCapture) is fused as it records, the session made
// once its first frame is in the recording. A frame that cannot be read, decoded or registered is
// reported and skipped; a SIGINT stops after the current frame (a live capture: stops the capture
// after the frame it is taking, and fuses what it recorded), and what was fused is written as a
// valid partial model.
nlohmann::json scan_recording(const Context& context, const std::string& folder, const ScanOptions& options,
                              const Device& device, LiveCapture* live) {
  const bool groundtruth = options.poses == "groundtruth";
  session::ScanSessionOptions session_options;
  session_options.device = device;
  session_options.integration = fusion::parse_fusion_method(options.fusion);
  fusion::IntegrationOptions& integration = session_options.integration;
  if (options.gtsdf_lambda) integration.lambda = *options.gtsdf_lambda;
  if (options.gtsdf_kappa) integration.kappa = *options.gtsdf_kappa;
  if (!options.gtsdf_penalty.empty()) integration.penalty = fusion::parse_penalty(options.gtsdf_penalty);
  if (options.gtsdf_iterations) integration.iterations = *options.gtsdf_iterations;
  if (!groundtruth) {
    session_options.voxel_size_m = options.voxel_um * 1e-6;
    session_options.max_voxels =
        options.max_voxels_million > 0.0 ? options.max_voxels_million * 1e6 : session::automatic_max_voxels(device);
    session_options.max_gpu_bytes = options.max_gpu_memory;
    session_options.turntable_prior = options.turntable_prior;
    session_options.tracking.photometric_weight = options.photometric_weight;
    session_options.tracking.weight_by_confidence = options.icp_weights == "confidence";
    session_options.tracking.crease_angle_deg = options.icp_crease_deg;
  }
  session_options.deformation.enabled = !groundtruth && options.deformation == "on";
  session_options.deformation.loop_frames = options.loop_frames;
  session_options.revisits = session::parse_revisit_policy(options.revisits);
  // --calibration with --input: decode with that calibration instead of the recording's.
  std::optional<ScannerCalibration> calibration;
  if (!options.calibration.empty() && options.camera_uri.empty()) calibration = read_calibration(options.calibration);
  // The recording and the session made for it: at once for a replay, at the first frame for a
  // live capture (its recording exists by then).
  std::optional<RecordingReader> opened;
  std::optional<session::ScanSession> made;
  std::vector<StampedPose> truth;
  const auto make_session = [&]() -> session::ScanSession& {
    if (live != nullptr && !live->record) {
      // --no-record: no recording to open; what the capture described before its first frame.
      if (!live->info || !live->calibration) {
        throw_error(ErrorCode::kInvalidArgument, "--no-record: the capture has no calibration to decode with");
      }
      made.emplace(session::make_capture_session(*live->info, *live->calibration, session_options));
      return *made;
    }
    opened.emplace(session::open_recording_for_scan(folder, calibration.has_value()));
    if (groundtruth) {
      try {
        truth = session::groundtruth_poses(*opened);
      } catch (const Error& error) {
        if (error.code() != ErrorCode::kInvalidArgument) throw;
        throw Error(error.code(), fmt::format("--poses groundtruth: {}", error.what()));
      }
      const double budget = options.max_voxels_million > 0.0 ? options.max_voxels_million * 1e6
                                                              : session::automatic_max_voxels(device);
      session_options.fixed_volume =
          session::groundtruth_volume(*opened, options.voxel_um * 1e-6, budget, session_options.integration);
    }
    made.emplace(session::make_recording_session(*opened, session_options, calibration ? &*calibration : nullptr));
    return *made;
  };
  if (live == nullptr) make_session();

  // A replay stops on SIGINT/SIGTERM here; a live capture's signals stop the capture (its
  // StopOnSignal), and what it recorded is still fused.
  g_stop_requested.store(false);
  using Handler = void (*)(int);
  const Handler previous_int = live == nullptr ? std::signal(SIGINT, request_stop) : SIG_ERR;
  const Handler previous_term = live == nullptr ? std::signal(SIGTERM, request_stop) : SIG_ERR;
  const auto restore_signals = [&] {
    if (previous_int != SIG_ERR) std::signal(SIGINT, previous_int);
    if (previous_term != SIG_ERR) std::signal(SIGTERM, previous_term);
  };
  const ProgressCallback display = context.progress_callback("scan");
  const ProgressCallback progress = [&display, live](const ProgressUpdate& update) {
    if (g_stop_requested.load()) return false;
    if (!display) return true;
    if (live == nullptr) return display(update);
    ProgressUpdate shown = update;  // a live capture's total is what it plans to record
    shown.total = live->planned_frames.load();
    return display(shown);
  };
  bool printed_volume = false;
  const auto on_frame = [&](const session::FrameReport& frame) {
    if (context.after_frame) context.after_frame(frame.index);
    if (context.options.json) return;
    if (!printed_volume && frame.status == session::FrameStatus::kFused) {
      const fusion::VolumeGeometry& geometry = made->volume_geometry();
      std::cerr << fmt::format("\nvolume {} x {} x {} voxels of {:.1f} um ({:.0f} MiB, {}), {} fusion on {}, poses: {}{}\n",
                               geometry.nx, geometry.ny, geometry.nz, geometry.voxel_size_m * 1e6,
                               static_cast<double>(made->volume_bytes()) / 1048576.0,
                               groundtruth ? "fixed" : "moving", options.fusion, device.to_string(), options.poses,
                               live != nullptr ? ", fused while capturing" : "");
      printed_volume = true;
    }
    if (frame.status != session::FrameStatus::kFused || frame.unverified) {
      std::cerr << fmt::format("\nframe {} {}: {}\n", frame.index, session::frame_status_name(frame.status),
                               frame.reason);
    }
  };
  session::PipelineOutcome outcome;
  // A fault of the machine part-way (memory, the GPU, a disk) after frames were fused — or a
  // live capture's device that stopped answering —: what was fused is written as a partial
  // model, and the scan then fails naming the fault and where the model is.
  std::optional<Error> failure;
  const auto fused_count = [&made] { return made ? made->fused_count() : std::size_t{0}; };
  try {
    try {
      if (live != nullptr) {
        outcome = session::run_pipeline(make_session, live->frames, session::PipelineOptions{}, on_frame, progress);
      } else {
        outcome = session::run_recording(*made, *opened, groundtruth ? &truth : nullptr, on_frame, progress);
      }
    } catch (const std::bad_alloc&) {
      // An allocation the admission could not foresee failed: a fault of the machine as any other.
      if (live == nullptr) {
        throw_error(ErrorCode::kOutOfMemory, "out of host memory after {} of {} frame(s)", made->frames().size(),
                    opened->frame_count());
      }
      throw_error(ErrorCode::kOutOfMemory, "out of host memory after {} frame(s) of the capture",
                  made ? made->frames().size() : std::size_t{0});
    }
  } catch (const Error& error) {
    restore_signals();
    if (error.code() == ErrorCode::kOutOfMemory && fused_count() == 0) {
      throw Error(error.code(), fmt::format("{}; sls scan: a larger --voxel-um, or a smaller --max-voxels for the "
                                            "automatic voxel size",
                                            error.what()));
    }
    if (fused_count() == 0) throw;
    failure = error;
    outcome.interrupted = true;
    outcome.interruption = fmt::format("stopped by an error: {}", error.what());
  } catch (...) {
    restore_signals();
    throw;
  }
  restore_signals();
  if (live != nullptr) {
    // The recording as the capture left it (the session was made from it at its first frame).
    if (made && live->record) opened.emplace(RecordingReader::open(folder));
    if (live->outcome.interrupted && !failure) {
      outcome.interrupted = true;
      outcome.interruption =
          live->record
              ? fmt::format("interrupted by {} during the capture: {} of {} frame(s) captured into {} and fused (a "
                            "valid recording; continue the capture and fuse it all with: {})",
                            live->stop.signal_name(), live->outcome.frames, live->outcome.planned, folder,
                            live->resume_command)
              : fmt::format("interrupted by {} during the capture: {} of {} frame(s) captured and fused (--no-record: "
                            "nothing was recorded, the capture cannot be resumed)",
                            live->stop.signal_name(), live->outcome.frames, live->outcome.planned);
    }
  }
  if (fused_count() == 0) {
    throw_error(ErrorCode::kInvalidArgument, "{}: no frame could be fused ({} frames{})", folder,
                made ? made->frames().size() : std::size_t{0}, outcome.interrupted ? ", interrupted" : "");
  }
  // What was fused, as the recording holds it — or with --no-record, as the capture said.
  const bool recorded = opened.has_value();
  std::vector<std::optional<double>> turntable_angles = recorded ? std::vector<std::optional<double>>{}
                                                                 : live->turntable_angles;
  for (std::size_t i = 0; recorded && i < opened->frame_count(); ++i) {
    turntable_angles.push_back(opened->frame(i).turntable_angle_deg);
  }
  session::ScanSession& session = *made;
  // After a fault part-way, what stops the outputs too (the same full disk) is said with it.
  bool failure_said = false;
  try {

  // The loop closure, after the revolution: asked for, or by default when the recording is a
  // full turntable revolution (its angles span 360° less at most two steps).
  const LoopClosureChoice loop = loop_closure_choice(turntable_angles, options, session.deformation_enabled());
  nlohmann::json loop_json = {{"requested", loop.requested}, {"why", loop.why}};
  std::string loop_failure;
  auto start = Clock::now();
  if (loop.requested && !outcome.interrupted) {
    try {
      const session::LoopClosureReport closed = session.close_loop();
      loop_json.update(loop_closure_json(closed));
    } catch (const Error& error) {
      if (error.code() != ErrorCode::kInvalidArgument) throw;
      loop_failure = error.what();
      loop_json["closed"] = false;
      loop_json["reason"] = loop_failure;
      if (!context.options.json) std::cerr << "\nwarning: " << loop_failure << "\n";
    }
  }
  const double loop_ms = ms_since(start);

  start = Clock::now();
  const fusion::ExtractedSurface surface = session.final_surface();
  const double extract_ms = ms_since(start);
  // When the final model was in host memory, on the frames' clock: a live scan's wait after
  // its last capture is this less the last frame's captured_s.
  const double model_s = std::chrono::duration<double>(Clock::now() - outcome.started).count();
  const std::vector<StampedPose> trajectory = session.trajectory();
  // Each output written whole or not at all, the reports after the model they describe, an
  // earlier run's reports removed first (output_files.h): a kill, a full disk or a fault while
  // writing never leaves a partial file, nor a report beside another run's model.
  std::vector<std::string> planned;
  if (session.deformation_enabled()) planned = {"undeformed/cloud.ply", "undeformed/trajectory.txt"};
  for (const char* name : {"render.png", "cloud.ply", "mesh.ply", "trajectory.txt", "report.json", "report.html"}) {
    planned.emplace_back(name);
  }
  OutputFiles outputs(options.out, planned, {"report.json", "report.html"});
  // With deformation, the model and trajectory as tracked too (OUT/undeformed), so `sls eval`
  // can put the two side by side.
  if (session.deformation_enabled()) {
    const PointCloud undeformed = session.final_surface_undeformed().cloud;
    outputs.write("undeformed/cloud.ply", [&](const std::string& path) {
      create_directories(options.out + "/undeformed");
      write_ply(path, undeformed);
    });
    outputs.write("undeformed/trajectory.txt",
                  [&](const std::string& path) { write_tum_trajectory(path, session.trajectory_undeformed()); });
  }
  // A shaded picture of the current volume from the last fused view, with the camera's own
  // model (render.png): the fused surface at the scanner's resolution.
  const Image8u render = session.render(trajectory.back().T_world_camera);
  outputs.write("render.png", [&](const std::string& path) { write_png(path, render); });
  outputs.write("cloud.ply", [&](const std::string& path) { write_ply(path, surface.cloud); });
  outputs.write("mesh.ply", [&](const std::string& path) { write_ply(path, surface.mesh); });
  outputs.write("trajectory.txt", [&](const std::string& path) { write_tum_trajectory(path, trajectory); });

  const fusion::IntegrationOptions& fusion_options = session_options.integration;
  const fusion::VolumeGeometry& geometry = session.volume_geometry();
  nlohmann::json report;
  report["format"] = "slscan-scan-report";
  report["format_version"] = 2;
  report["input"] = recorded ? nlohmann::json(opened->folder()) : nlohmann::json(nullptr);
  report["device"] = device.to_string();
  report["calibration"] = calibration     ? options.calibration
                          : recorded      ? opened->folder() + "/calibration.yml"
                          : options.calibration.empty() ? "the simulator's" : options.calibration;
  report["poses"] = options.poses;
  report["turntable_prior"] = !groundtruth && options.turntable_prior;
  report["photometric_weight"] = groundtruth ? 0.0 : options.photometric_weight;
  if (!groundtruth) {
    report["icp_weights"] = options.icp_weights;
    report["icp_crease_angle_deg"] = options.icp_crease_deg;
  }
  report["fusion"] = {{"method", options.fusion},
                      {"truncation_voxels", fusion_options.truncation_voxels},
                      {"eta_voxels", fusion_options.eta_voxels},
                      {"weight_max", fusion_options.weight_max},
                      {"lambda", fusion_options.lambda},
                      {"beta", fusion_options.beta},
                      {"kappa", fusion_options.kappa},
                      {"penalty", fusion::penalty_name(fusion_options.penalty)},
                      {"iterations", fusion_options.iterations}};
  report["voxel_size_m"] = geometry.voxel_size_m;
  report["volume"] = {{"voxels", {geometry.nx, geometry.ny, geometry.nz}},
                      {"kind", groundtruth ? "fixed" : "moving"},
                      {"format", fusion::voxel_format_name(session_options.voxel_format)},
                      {"bytes", session.volume_bytes()},
                      {"moves", session.moves()}};
  report["frames"] = turntable_angles.size();
  report["frames_processed"] = session.frames().size();
  report["frames_fused"] = session.fused_count();
  report["interrupted"] = outcome.interrupted;
  if (outcome.interrupted) report["interruption"] = outcome.interruption;
  report["pipeline"] = pipeline_json(outcome, live != nullptr);
  report["pipeline"]["model_s"] = model_s;
  // The recording's writer thread beside the capture (none with --no-record: nothing written).
  std::map<int, double> written_s;
  if (live != nullptr) {
    const RecordingWriteStatistics& writes = live->outcome.writes;
    report["writer"] = writer_json(writes, live->record);
    for (const RecordingWriteStatistics::Frame& frame : writes.frames) {
      written_s[frame.frame] = std::chrono::duration<double>(frame.written - outcome.started).count();
    }
  }
  if (live != nullptr) {
    // The capture this scan fused while it recorded: how far it got, and how to continue it.
    report["live_capture"] = {{"frames_captured", live->outcome.frames},
                              {"frames_planned", live->outcome.planned},
                              {"resumed_from", live->outcome.resumed_from},
                              {"interrupted", live->outcome.interrupted},
                              {"signal", live->stop.signal_name()},
                              {"recorded", live->record},
                              {"resume", live->record ? nlohmann::json(live->resume_command) : nlohmann::json(nullptr)}};
  }
  // When each frame reached the session and left it (seconds since the frames began): a live
  // capture's frames as recorded, a replay's as read.
  std::map<int, const session::FrameTiming*> timings;
  for (const session::FrameTiming& timing : outcome.timings) timings[timing.index] = &timing;
  nlohmann::json lost = nlohmann::json::array();
  nlohmann::json per_frame = nlohmann::json::array();
  std::vector<double> pipeline_ms;  // track + integrate + move + raycast of each fused frame
  std::size_t active = 0;
  // What each frame's capture took, as the recording keeps it (device captures), by frame index.
  std::map<int, FrameCaptureCounters> capture_counters;
  for (std::size_t i = 0; recorded && i < opened->frame_count(); ++i) {
    if (opened->frame(i).capture) capture_counters[opened->frame(i).index] = *opened->frame(i).capture;
  }
  for (const session::FrameReport& frame : session.frames()) {
    nlohmann::json entry = {{"frame", frame.index}, {"status", session::frame_status_name(frame.status)},
                            {"ms", stage_json(frame.times)}};
    if (!frame.reason.empty()) entry["reason"] = frame.reason;
    if (frame.unverified) entry["unverified"] = true;
    if (const auto timing = timings.find(frame.index); timing != timings.end()) {
      entry["captured_s"] = timing->second->delivered_s;
      entry["fused_s"] = timing->second->fused_s;
      if (timing->second->waited_s > 0.0) entry["waited_s"] = timing->second->waited_s;
    }
    if (const auto written = written_s.find(frame.index); written != written_s.end()) {
      entry["written_s"] = written->second;
    }
    if (const auto counters = capture_counters.find(frame.index); counters != capture_counters.end()) {
      entry["capture"] = capture_json(counters->second);
    }
    if (frame.tracking) {
      entry["tracking"] = {{"inlier_fraction", frame.tracking->inlier_fraction},
                           {"crease_pixels", frame.tracking->crease_pixels},
                           {"pixels_outside_volume", frame.tracking->live_pixels_outside_model},
                           {"residual_rms_um", frame.tracking->residual_rms_m * 1e6},
                           {"degenerate_directions", frame.tracking->degenerate_directions},
                           {"iterations", frame.tracking->iterations}};
      // The turntable's motion as the registration's prior (its σ known): where the registration
      // ended beyond it, about the axis (signed) and across it.
      if (frame.tracking->prior) {
        entry["tracking"]["prior"] = {{"offset_deg", frame.tracking->prior_offset_deg},
                                      {"tilt_offset_deg", frame.tracking->prior_tilt_offset_deg}};
      }
    }
    if (frame.move.moved) {
      entry["move"] = {{"translation_mm", frame.move.translation_m * 1e3}, {"rotation_deg", frame.move.rotation_deg}};
      // On a GPU the surface ships beside the frame loop: its figures come with a later frame.
      if (!frame.move.shipping) entry["move"]["shipped_points"] = frame.move.shipped_points;
    }
    if (frame.shipped) entry["shipped"] = {{"points", frame.shipped->shipped_points}};
    if (frame.deformation.keyframe) {
      entry["deformation"] = {{"keyframe", true},
                              {"nodes", frame.deformation.nodes},
                              {"constraints", frame.deformation.constraints},
                              {"pending", frame.deformation.pending},
                              {"last_solve_ms", frame.deformation.solve_ms}};
    }
    per_frame.push_back(entry);
    if (frame.status != session::FrameStatus::kFused) {
      lost.push_back({{"frame", frame.index}, {"status", session::frame_status_name(frame.status)},
                      {"reason", frame.reason}});
      continue;
    }
    active += frame.integration.active_voxels;
    pipeline_ms.push_back(frame.times.track_ms + frame.times.integrate_ms + frame.times.move_ms +
                          frame.times.raycast_ms);
  }
  report["lost_frames"] = lost;
  const ScannerCalibration& used_calibration = calibration ? *calibration
                                              : recorded  ? opened->calibration()
                                                          : *live->calibration;
  const bool turntable_known = used_calibration.turntable.has_value() && !turntable_angles.empty() &&
                               turntable_angles.front().has_value();
  report["warnings"] = scan_warnings(session.frames(), turntable_known);
  report["active_voxels_per_frame"] =
      static_cast<double>(active) / static_cast<double>(std::max<std::size_t>(session.fused_count(), 1));
  session::StageTimes totals = session.totals();
  report["ms_per_stage"] = stage_json(totals);
  report["ms_per_stage"]["extract"] = extract_ms;
  report["ms_per_stage"]["loop_closure"] = loop_ms;
  report["ms_total"] = totals.total_ms() + extract_ms + loop_ms;
  report["deformation"] = deformation_json(session);
  report["loop_closure"] = loop_json;
  const std::optional<int> merged_from = session.revisits_merged_from();
  report["revisits"] = {{"policy", session::revisit_policy_name(session_options.revisits)},
                        {"turned_deg", session.turned_deg()},
                        {"merged_from_frame", merged_from ? nlohmann::json(*merged_from) : nlohmann::json(nullptr)}};
  report["ms_track_integrate_move_raycast_median"] = median(pipeline_ms);
  report["points"] = surface.cloud.size();
  report["triangles"] = surface.mesh.faces.size();
  report["per_frame"] = per_frame;
  report["outputs"] = {{"cloud", options.out + "/cloud.ply"}, {"mesh", options.out + "/mesh.ply"},
                       {"render", options.out + "/render.png"}, {"trajectory", options.out + "/trajectory.txt"},
                       {"report", options.out + "/report.json"}, {"report_html", options.out + "/report.html"}};
  const auto write_report = [&] {
    outputs.write("report.json", [&](const std::string& path) { write_file_atomic(path, report.dump(2) + "\n"); });
  };
  write_report();

  // With ground truth (simulated recordings): sls eval's figures and per-point errors for the
  // report's heat map; the report.json written above is complete without them.
  sls::report::ScanReportInputs html;
  std::optional<eval::EvalReport> evaluation;
  if (recorded && opened->info().has_groundtruth && !failure) {
    const RecordingReader& recording = *opened;
    try {
      start = Clock::now();
      eval::EvalOptions eval_options;
      eval_options.keep_point_errors = true;
      evaluation = eval::evaluate_result(options.out, recording.folder(), eval_options,
                                         context.progress_callback("eval"));
      report["evaluation"] = eval::evaluation_json(*evaluation);
      if (session.deformation_enabled()) {
        // The same figures for the model as tracked: what deformation changed.
        eval::EvalOptions undeformed_options;
        undeformed_options.voxel_size_m = geometry.voxel_size_m;
        report["evaluation_undeformed"] = eval::evaluation_json(eval::evaluate_result(
            options.out + "/undeformed", recording.folder(), undeformed_options, context.progress_callback("eval")));
      }
      report["ms_per_stage"]["evaluate"] = ms_since(start);
      html.evaluation = &*evaluation;
      html.point_errors_m = evaluation->cloud_point_errors_m;
      if (evaluation->trajectory) {
        html.truth = eval::truth_in_estimate_frame(
            read_tum_trajectory(recording.groundtruth_folder() + "/trajectory.txt"), *evaluation->trajectory);
      }
    } catch (const Error& error) {
      // A broken ground truth spoils the evaluation, not the scan: the model, trajectory and
      // reports stand, and the report says what could not be measured.
      if (!is_frame_problem(error)) throw;
      const std::string warning = fmt::format("the scan is written, but it could not be evaluated against the "
                                              "recording's ground truth: {}", error.what());
      report["evaluation_error"] = error.what();
      report["warnings"].push_back(warning);
      html.evaluation = nullptr;
      html.point_errors_m.clear();
    }
    write_report();
  }
  html.report = report;
  html.cloud = &surface.cloud;
  html.trajectory = trajectory;
  if (session.deformation_enabled()) html.trajectory_undeformed = session.trajectory_undeformed();
  html.title = recorded ? fmt::format("Scan of {}", opened->folder()) : std::string("Scan (not recorded)");
  outputs.write("report.html", [&](const std::string&) { sls::report::write_scan_report_html(options.out, html); });
  if (failure) {
    failure_said = true;
    throw Error(failure->code(), fmt::format("{}; the {} frame(s) fused before it are written as a valid partial "
                                             "model: {}", failure->what(), session.fused_count(),
                                             outputs.describe_written()));
  }
  return report;
  } catch (const Error& error) {
    if (!failure || failure_said) throw;
    throw Error(failure->code(), fmt::format("{}; the {} frame(s) fused before it could not be written either: {}",
                                             failure->what(), session.fused_count(), error.what()));
  }
}

int run_scan(const Context& context, const ScanOptions& options) {
  // An explicit --device cuda without a GPU is an error, not a silent fallback.
  const Device device = options.device_given ? parse_device(options.device) : default_device();
  require_device(device);

  // The output is checked before any work: a scan that cannot be written, or that would
  // overwrite the recording it reads, is refused before it decodes a frame.
  if (!options.input.empty() && path_is_within(options.out, options.input)) {
    throw_error(ErrorCode::kInvalidArgument,
                "--out {} is inside the recording {}: the scan would overwrite it; choose a folder outside it",
                options.out, options.input);
  }
  ensure_writable_directory(options.out, kFirstOutputsBytes);

  // A capture (--sim, --camera, --resume) is fused while it records when it can be, else
  // captured first; a recording is read and checked (manifest, calibration), then every frame
  // decoded.
  std::string input = options.input;
  std::optional<LiveCapture> live;
  if (!options.camera_uri.empty() || !options.sim_preset.empty() || options.resume) {
    input = options.out + "/recording";
    if (can_fuse_while_capturing(options)) {
      live.emplace();
      start_live_capture(context, options, device, input, &*live);
    } else if (!capture_for_scan(context, options, device, input)) {
      return kExitInterrupted;
    }
  }
  const nlohmann::json report = scan_recording(context, input, options, device, live ? &*live : nullptr);
  if (live) {
    print_capture(context, options, live->outcome, input);
    if (live->outcome.interrupted) std::cerr << report["interruption"].get<std::string>() << "\n";
  }
  if (context.options.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    std::cout << fmt::format("\n{} {} of {} frames ({} lost or skipped{}): {} points, {} triangles\n  {}\n  {}\n  {}\n  {}\n",
                             report["interrupted"].get<bool>() ? "interrupted: fused" : "fused",
                             report["frames_fused"].get<std::size_t>(), report["frames"].get<std::size_t>(),
                             report["lost_frames"].size(),
                             report["interrupted"].get<bool>() ? ", the partial model is valid" : "",
                             report["points"].get<std::size_t>(), report["triangles"].get<std::size_t>(),
                             report["outputs"]["cloud"].get<std::string>(), report["outputs"]["mesh"].get<std::string>(),
                             report["outputs"]["trajectory"].get<std::string>(),
                             report["outputs"]["report"].get<std::string>());
    for (const auto& warning : report["warnings"]) std::cerr << "warning: " << warning.get<std::string>() << "\n";
  }
  return report["interrupted"].get<bool>() ? kExitInterrupted : kExitOk;
}

}  // namespace

void add_scan_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand("scan", "Scan an object: recording or simulator -> decode -> track -> fuse -> model");
  command->footer(
      "A capture (--sim, --camera) is fused while it records (with --poses track and a calibration known before "
      "its first frame: the simulator's, --calibration, a replay:// camera's or a resumed recording's; otherwise it "
      "is captured first). SIGINT/SIGTERM during the capture stops it after the current frame: OUT/recording is kept "
      "(valid, every frame flushed), what it recorded is fused and written as a valid partial model, exit status 4, "
      "and --resume continues the capture and fuses it all (a capture not fused while recording: nothing is fused). "
      "A second signal ends at once; the recording stays valid. During the fusion of a recording: the frames fused so "
      "far are written as a valid partial model, exit status 4.");
  auto options = std::make_shared<ScanOptions>();
  auto* input = command->add_option("--input", options->input, "Recording folder to scan");
  auto* sim = command->add_option("--sim", options->sim_preset, "Scan the simulated scanner with this preset")
                  ->check(CLI::IsMember({"ci", "demo", "paper"}));
  auto* camera = command->add_option("--camera", options->camera_uri,
                                     "Scan with devices by URI (see `sls devices`): the camera, e.g. gige://192.168.1.20");
  command->add_option("--projector", options->projector_uri, "With --camera: the projector, e.g. dlpc350://");
  command->add_option("--turntable", options->turntable_uri, "With --camera: the turntable, e.g. headctl://");
  command->add_option("--exposures", options->exposures,
                      "With --camera: HDR, the whole stack at each of these exposure times relative to the camera's, "
                      "comma separated (1 to 4, e.g. 4,1,0.25), fused per pixel for decoding (sdk/decode/hdr_fusion.h)");
  command->add_option("--calibration", options->calibration,
                      "With --camera: calibration.yml of these devices (stored in the recording; a replay:// camera's "
                      "default: the replayed recording's); with --input: decode with this calibration instead of the "
                      "recording's (e.g. a new calibration of the head)");
  input->excludes(sim);
  sim->excludes(input);
  camera->excludes(input);
  camera->excludes(sim);
  command->add_flag("--resume", options->resume,
                    "Continue a scan that was cut off (a signal, kill -9, a device error) in --out: the capture goes "
                    "on from the first frame OUT/recording lacks (the simulator: the options its manifest names, "
                    "unless given; devices: give the same --camera/--projector/--turntable/--frames), then the whole "
                    "recording is fused. Fusion keeps no checkpoint: a fusion cut off is run again from the complete "
                    "recording. Refused when OUT holds no recording or the options contradict it")
      ->excludes(input);
  command->add_flag("--no-record", options->no_record,
                    "With --sim/--camera: fuse the capture while it runs and write none of it (no OUT/recording: "
                    "the model, trajectory and reports are still written to OUT). Lost with it: --resume after a "
                    "cut-off capture, scanning the capture again, the evaluation against the simulator's ground "
                    "truth. Refused with --resume, --input, --poses groundtruth, and a --camera without "
                    "--calibration (unless a replay:// camera)")
      ->excludes(input);
  command->add_option("--object", options->object, "Simulated object (with --sim)")
      ->check(CLI::IsMember({"knurled-screw", "knurled-knob", "chessboard", "plane", "sphere"}))
      ->capture_default_str();
  command->add_option("--frames", options->frames,
                      "Frames per revolution (--sim: 0 is the preset's; --camera: 0 is 36 with a turntable, else 1, "
                      "with a replay:// camera the replayed recording's)")
      ->check(CLI::NonNegativeNumber);
  command->add_option("--out", options->out,
                      "Output folder for cloud.ply, mesh.ply, trajectory.txt, report.json, report.html")
      ->required();
  command->add_option("--device", options->device, "cpu, cuda or cuda:N (default: cuda when a GPU is present, else cpu)");
  command->add_option("--fusion", options->fusion, "Fusion: tsdf or gtsdf")
      ->check(CLI::IsMember({"tsdf", "gtsdf"}))
      ->capture_default_str();
  const fusion::IntegrationOptions gtsdf_defaults = fusion::IntegrationOptions::gtsdf();
  command->add_option("--gtsdf-lambda", options->gtsdf_lambda,
                      fmt::format("With --fusion gtsdf: lambda, the anisotropic term's weight (alpha = lambda * beta, "
                                  "beta = 1/6; default {:g})", gtsdf_defaults.lambda))
      ->check(finite_range(1e-3, 1e3));
  command->add_option("--gtsdf-kappa", options->gtsdf_kappa,
                      fmt::format("With --fusion gtsdf: kappa, the edge-stopping scale of the penalty in units of the "
                                  "truncated SDF (default {:g})", gtsdf_defaults.kappa))
      ->check(finite_range(1e-4, 10.0));
  command->add_option("--gtsdf-penalty", options->gtsdf_penalty,
                      fmt::format("With --fusion gtsdf: the penalty phi (default {})",
                                  fusion::penalty_name(gtsdf_defaults.penalty)))
      ->check(CLI::IsMember({"perona-malik", "charbonnier", "geman-mcclure"}));
  command->add_option("--gtsdf-iterations", options->gtsdf_iterations,
                      fmt::format("With --fusion gtsdf: Gauss-Seidel sweeps per frame (default {})",
                                  gtsdf_defaults.iterations))
      ->check(CLI::Range(1, 100));
  command->add_option("--poses", options->poses, "Camera poses: track (ICP) or groundtruth (simulated recordings)")
      ->check(CLI::IsMember({"track", "groundtruth"}))
      ->capture_default_str();
  command->add_flag("--turntable-prior", options->turntable_prior,
                    "With --poses track: use the recording's turntable angles about the calibrated axis as the pose guess, "
                    "and, when the calibration records the table's repeatability (turntable_angle_sigma_deg, "
                    "turntable_tilt_sigma_deg), as a prior on each registration's rotation weighed against the surface "
                    "(default: depth alone, constant-velocity guess)");
  command->add_option("--photometric-weight", options->photometric_weight,
                      "With --poses track: weight of the tracker's photometric term on each pattern stack's white - "
                      "black texture, relative to ICP's (0: off; frames given as depth maps have no texture)")
      ->check(finite_range(0.0, 1e6))
      ->capture_default_str();
  command->add_option("--icp-weights", options->icp_weights,
                      "With --poses track: ICP's per-pixel weights: confidence (the decoder's confidence, an inverse "
                      "predicted variance; frames given as depth maps have none and count equally) or equal")
      ->check(CLI::IsMember({"confidence", "equal"}))
      ->capture_default_str();
  command->add_option("--icp-crease-deg", options->icp_crease_deg,
                      "With --poses track: ICP sets aside matches within 60 um of a model crease, where the "
                      "surface turns by more than this angle (0: off)")
      ->check(finite_range(0.0, 179.0))
      ->capture_default_str();
  command->add_option("--deformation", options->deformation,
                      "With --poses track: online deformation, the graph that corrects drift beside the frame loop "
                      "(off: the model as tracked)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  command->add_option("--loop-closure", options->loop_closure,
                      "With --poses track: close the loop after the scan, registering the last frame to the first "
                      "(default: on for a full turntable revolution, else off)")
      ->check(CLI::IsMember({"on", "off"}));
  command->add_option("--loop-frames", options->loop_frames,
                      "With --loop-closure: how many of the last frames register to the first (each kept until "
                      "then; 1 .. 64)")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  command->add_option("--revisits", options->revisits,
                      "Surface the moving volume ships again on a later pass: auto (every pass until the scan has "
                      "turned a revolution and one move's 15 degrees, then only what no earlier move shipped: a long "
                      "session's model stays bounded), keep (every pass), merge (only new surface from the start)")
      ->check(CLI::IsMember({"auto", "keep", "merge"}))
      ->capture_default_str();
  command->add_option("--voxel-um", options->voxel_um,
                      "Voxel size in um (0: twice the pixel footprint, grown to fit --max-voxels; else 0.1 .. 100000)")
      ->check(finite_range(0.1, 1e5, true))
      ->capture_default_str();
  command->add_option("--max-voxels", options->max_voxels_million,
                      "Largest volume (one buffer of a moving volume) in millions of voxels for the automatic voxel "
                      "size (0: 256 on a GPU, 48 on the CPU)")
      ->check(finite_range(0.0, 1e6));
  command->add_option("--max-gpu-memory", options->max_gpu_memory,
                      "GPU memory budget in bytes (e.g. 6e9 on an 8 GB Jetson): the moving volume is sized to fit "
                      "beside the frames' buffers (an automatic voxel size grows, a given one keeps its size and the "
                      "volume shrinks); 0: none")
      ->check(finite_range(0.0, 1e15));
  command->callback([&context, exit_code, options, command] {
    if (!options->input.empty() && options->frames > 0) {
      throw CLI::ValidationError("--frames", "not with --input: a recording's frames are all scanned");
    }
    if (options->no_record && options->resume) {
      throw CLI::ValidationError("--no-record", "not with --resume: a capture that records nothing cannot be resumed");
    }
    if (options->no_record && !can_fuse_while_capturing(*options)) {
      throw CLI::ValidationError(
          "--no-record", options->poses != "track"
                             ? "needs a scan fused while it captures: --poses groundtruth reads the simulator's poses "
                               "from the whole recording"
                             : "needs a scan fused while it captures: --camera without --calibration has no "
                               "calibration before the capture");
    }
    if (!options->exposures.empty() && options->camera_uri.empty()) {
      throw CLI::ValidationError("--exposures", "needs --camera (an HDR recording says its own exposures)");
    }
    const bool gtsdf_parameters = options->gtsdf_lambda || options->gtsdf_kappa || !options->gtsdf_penalty.empty() ||
                                  options->gtsdf_iterations;
    if (gtsdf_parameters && options->fusion != "gtsdf") {
      throw CLI::ValidationError("--gtsdf-lambda/-kappa/-penalty/-iterations", "they need --fusion gtsdf");
    }
    run_command(context, "scan", [&context, options, command] {
      if (options->input.empty() && options->sim_preset.empty() && options->camera_uri.empty() && !options->resume) {
        throw_error(ErrorCode::kInvalidArgument,
                    "give --input REC, --sim PRESET, --camera URI --projector URI, or --resume (a scan cut off in --out)");
      }
      options->device_given = command->count("--device") > 0;
      options->object_given = command->count("--object") > 0;
      return run_scan(context, *options);
    }, exit_code);
  });
}

}  // namespace sls::cli
