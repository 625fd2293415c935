// report.json's parts that describe the scan session (`sls scan`): stage times, a frame's
// capture counters, the loop closure, the deformation graph, and the warnings of a finished scan.
#include "samples/sls/scan_json.h"

#include <cmath>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace sls::cli {

nlohmann::json stage_json(const session::StageTimes& times) {
  return {{"read", times.read_ms},       {"decode", times.decode_ms}, {"track", times.track_ms},
          {"integrate", times.integrate_ms}, {"move", times.move_ms},   {"raycast", times.raycast_ms},
          {"deform", times.deform_ms}};
}

nlohmann::json pipeline_json(const session::PipelineOutcome& outcome, bool live) {
  return {{"source", live ? "capture" : "recording"},
          {"queue_frames", session::PipelineOptions{}.queue_frames},
          {"delivered", outcome.delivered},
          {"waits", outcome.waits},
          {"wait_s", outcome.wait_s},
          {"deepest_queue", outcome.deepest_queue},
          {"source_s", outcome.source_s}};
}

nlohmann::json writer_json(const RecordingWriteStatistics& writes, bool recorded) {
  return {{"recorded", recorded},
          {"queue_frames", writes.queue_frames},
          {"frames_written", writes.frames.size()},
          {"write_s_median", writes.write_s_median()},
          {"write_s_total", writes.write_s_total()},
          {"waits", writes.waits},
          {"wait_s", writes.wait_s},
          {"deepest_queue", writes.deepest_queue}};
}

nlohmann::json capture_json(const FrameCaptureCounters& counters) {
  nlohmann::json json = {{"attempts", counters.attempts},
                         {"incomplete_images", counters.incomplete_images},
                         {"lost_images", counters.lost_images},
                         {"stale_images", counters.stale_images}};
  if (counters.transport) {
    json["resent_packets"] = counters.transport->resent_packets;
    json["missing_packets"] = counters.transport->missing_packets;
    json["queue_depth"] = counters.transport->queue_depth;
  }
  return json;
}

nlohmann::json loop_closure_json(const session::LoopClosureReport& loop) {
  nlohmann::json unregistered = nlohmann::json::array();
  for (const auto& [frame, reason] : loop.unregistered) unregistered.push_back({{"frame", frame}, {"reason", reason}});
  // The turntable's motion as the registrations' prior (null without): the prior's σ about the
  // axis and across it (√2 times the table's), the surface's own σ of those rotations, and
  // where the registration ended beyond the prior's (about the axis, signed; the tilt's size).
  const auto finite_or_null = [](double value) {
    return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
  };
  const auto optional = [](const std::optional<double>& value) {
    return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
  };
  nlohmann::json prior = nullptr;
  if (loop.registration.prior) {
    const fusion::TrackingResult& r = loop.registration;
    prior = {{"sigma_deg", finite_or_null(r.prior_sigma_deg)},
             {"tilt_sigma_deg", finite_or_null(r.prior_tilt_sigma_deg)},
             {"surface_sigma_deg", finite_or_null(r.prior_surface_sigma_deg)},
             {"surface_tilt_sigma_deg", finite_or_null(r.prior_surface_tilt_sigma_deg)},
             {"offset_deg", r.prior_offset_deg},
             {"tilt_offset_deg", r.prior_tilt_offset_deg}};
  }
  return {{"closed", true},
          {"first_frame", loop.first_frame},
          {"last_frame", loop.last_frame},
          {"turntable_sigma_deg", optional(loop.turntable_sigma_deg)},
          {"turntable_tilt_sigma_deg", optional(loop.turntable_tilt_sigma_deg)},
          {"registration",
           {{"inlier_fraction", loop.registration.inlier_fraction},
            {"residual_rms_um", loop.registration.residual_rms_m * 1e6},
            {"degenerate_directions", loop.registration.degenerate_directions},
            {"iterations", loop.registration.iterations},
            {"moved_from_guess_um", loop.guess_moved_m * 1e6},
            {"moved_from_guess_deg", loop.guess_moved_deg},
            {"prior", prior}}},
          {"registered_frames", loop.registered_frames},
          {"unregistered_frames", unregistered},
          {"constraints", loop.constraints},
          {"iterations", loop.solve.iterations},
          {"energy_before", loop.solve.before.total()},
          {"energy_after", loop.solve.after.total()},
          {"solve_ms", loop.solve.ms},
          {"last_pose_moved_um", loop.moved_m * 1e6},
          {"last_pose_moved_deg", loop.moved_deg},
          {"last_pose_correction_um", loop.correction_m * 1e6},
          {"last_pose_correction_deg", loop.correction_deg},
          {"ms", loop.ms}};
}

nlohmann::json deformation_json(const session::ScanSession& session) {
  if (!session.deformation_enabled()) return {{"enabled", false}};
  const session::DeformationStatus status = session.deformation_status(true);
  const session::ScanSession::GraphSummary graph = session.graph_summary();
  nlohmann::json keyframes = nlohmann::json::array();
  for (const session::KeyframeSolve& k : session.keyframe_solves()) {
    keyframes.push_back({{"frame", k.frame},
                         {"node", k.node},
                         {"matches", k.matches},
                         {"constraints", k.constraints},
                         {"iterations", k.solve.iterations},
                         {"energy_after", k.solve.after.total()},
                         {"solve_ms", k.solve.ms},
                         {"ms", k.ms}});
  }
  nlohmann::json out = {{"enabled", true},
                        {"nodes", graph.nodes},
                        {"links", graph.links},
                        {"constraints", graph.constraints},
                        {"rotation_priors", graph.rotation_priors},
                        {"analyses", graph.analyses},
                        {"factorizations", graph.factorizations},
                        {"node_spacing_mm", graph.node_spacing_m * 1e3},
                        {"region_radius_mm", graph.region_radius_m * 1e3},
                        {"worker_ms", status.worker_ms},
                        {"keyframes", keyframes}};
  if (!status.error.empty()) out["error"] = status.error;
  return out;
}

nlohmann::json scan_warnings(const std::vector<session::FrameReport>& frames, bool turntable_known) {
  std::vector<int> unverified, degenerate;
  std::size_t tracked = 0;
  const session::FrameReport* first_lost = nullptr;
  std::size_t lost = 0;
  for (const session::FrameReport& frame : frames) {
    if (frame.status == session::FrameStatus::kLost && lost++ == 0) first_lost = &frame;
    if (frame.status != session::FrameStatus::kFused || !frame.tracking) continue;
    ++tracked;
    if (frame.unverified) unverified.push_back(frame.index);
    if (frame.tracking->degenerate_directions > 0) degenerate.push_back(frame.index);
  }
  nlohmann::json warnings = nlohmann::json::array();
  if (first_lost != nullptr) {
    // A scan that lost frames is not the model of the whole object: said at the end, not only
    // in the per-frame lines that scrolled by.
    warnings.push_back(fmt::format("{} of {} frames lost by tracking (not in the model); the first, frame {}: {}", lost,
                                   frames.size(), first_lost->index, first_lost->reason));
  }
  if (!unverified.empty()) {
    warnings.push_back(fmt::format("{} frame(s) fused at the turntable prior without verification (too little overlap "
                                   "with the model), first frame {}: their poses are the turntable's",
                                   unverified.size(), unverified.front()));
  }
  if (!degenerate.empty() && !turntable_known) {
    warnings.push_back(fmt::format("{} of {} tracked frames registered with direction(s) the geometry does not "
                                   "constrain (first frame {}), where they keep the guess{}",
                                   degenerate.size(), tracked, degenerate.front(),
                                   degenerate.size() == tracked ? ": the motion along them is the guess's alone" : ""));
  }
  return warnings;
}

}  // namespace sls::cli
