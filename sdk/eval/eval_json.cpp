// sls eval's figures as JSON (eval_json.h).
#include "sdk/eval/eval_json.h"

#include <cmath>
#include <filesystem>

namespace sls::eval {
namespace {

constexpr double kUm = 1e6;

// null where there is nothing to average (JSON has no NaN).
nlohmann::json um_or_null(const DistanceStats& stats, double DistanceStats::*field) {
  return stats.count > 0 ? nlohmann::json(stats.*field * kUm) : nlohmann::json(nullptr);
}

}  // namespace

nlohmann::json errors_json(const SurfaceErrors& errors) {
  return {{"c2c_mean_um", um_or_null(errors.all, &DistanceStats::mean_m)},
          {"c2c_rms_um", um_or_null(errors.all, &DistanceStats::rms_m)},
          {"c2c_p95_um", um_or_null(errors.all, &DistanceStats::p95_m)},
          {"c2c_max_um", um_or_null(errors.all, &DistanceStats::max_m)},
          {"c2c_edge_mean_um", um_or_null(errors.edge, &DistanceStats::mean_m)},
          {"c2c_edge_rms_um", um_or_null(errors.edge, &DistanceStats::rms_m)},
          {"edge_points", errors.edge.count}};
}

nlohmann::json region_json(const RegionErrors& region) {
  return {{"points", region.to_raw_scan.count},
          {"to_raw_scan_mean_um", um_or_null(region.to_raw_scan, &DistanceStats::mean_m)},
          {"to_raw_scan_rms_um", um_or_null(region.to_raw_scan, &DistanceStats::rms_m)},
          {"to_surface_mean_um", um_or_null(region.to_surface, &DistanceStats::mean_m)},
          {"to_surface_rms_um", um_or_null(region.to_surface, &DistanceStats::rms_m)}};
}

nlohmann::json evaluation_json(const EvalReport& report) {
  nlohmann::json out = {{"result", report.result_folder},
                         {"truth", report.recording_folder},
                         {"scene", report.scene_name},
                         {"voxel_size_m", report.voxel_size_m},
                         {"voxel_size_source", report.voxel_size_source},
                         {"points", report.cloud_points},
                         {"edge_band_um", report.edge_band_m * kUm},
                         {"coverage", report.coverage.considered > 0 ? nlohmann::json(report.coverage.fraction())
                                                                     : nlohmann::json(nullptr)},
                         {"coverage_radius_um", report.coverage_radius_m * kUm},
                         {"coverage_basis", report.coverage_basis},
                         {"reference_points", report.reference_points},
                         {"reference_points_counted", report.coverage.considered},
                         {"reference_points_covered", report.coverage.covered},
                         {"frames_checked", report.frames_checked},
                         {"alignment", report.alignment},
                         {"alignment_translation_um", report.T_object_world.translation().norm() * kUm},
                         {"alignment_angle_deg", report.T_object_world.angle_rad() * 180.0 / M_PI}};
  if (report.trajectory) {
    const TrajectoryErrors& t = *report.trajectory;
    out["ate_rmse_um"] = t.ate_rmse_m * kUm;
    out["ate_max_um"] = t.ate_max_m * kUm;
    out["ate_frames"] = t.matched_frames;
    out["trajectory_frames_unmatched"] = t.unmatched_frames;
    out["loop_closure_error_um"] = t.loop_closure_error_m * kUm;
    out["loop_closure_error_deg"] = t.loop_closure_error_rad * 180.0 / M_PI;
  } else {
    // The keys are left out rather than null: there is no trajectory to measure, which is
    // not a failed measurement.
    out["trajectory_note"] = report.trajectory_note;
  }
  out.update(errors_json(report.cloud));
  if (report.mesh) out["mesh"] = errors_json(*report.mesh);
  return out;
}

ResultEvaluation evaluate_with_undeformed(const std::string& result_folder, const std::string& recording_folder,
                                          const EvalOptions& options, const ProgressCallback& progress) {
  ResultEvaluation evaluation;
  evaluation.report = evaluate_result(result_folder, recording_folder, options, progress);
  const std::string undeformed_folder = result_folder + "/undeformed";
  if (std::filesystem::is_regular_file(undeformed_folder + "/cloud.ply")) {
    EvalOptions undeformed_options = options;
    undeformed_options.voxel_size_m = evaluation.report.voxel_size_m;  // undeformed/ has no report.json
    undeformed_options.keep_point_errors = false;
    evaluation.undeformed = evaluate_result(undeformed_folder, recording_folder, undeformed_options, progress);
  }
  return evaluation;
}

nlohmann::json result_evaluation_json(const ResultEvaluation& evaluation) {
  nlohmann::json out = evaluation_json(evaluation.report);
  if (evaluation.undeformed) out["undeformed"] = evaluation_json(*evaluation.undeformed);
  return out;
}

}  // namespace sls::eval
