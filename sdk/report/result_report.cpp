// report.html of a result folder (result_report.h).
#include "sdk/report/result_report.h"

#include <cmath>
#include <filesystem>
#include <optional>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/ply.h"
#include "sdk/core/trajectory.h"
#include "sdk/eval/eval_json.h"

namespace sls::report {
namespace {

bool exists_as_file(const std::string& path) {
  std::error_code ignored;
  return std::filesystem::exists(path, ignored);
}

nlohmann::json read_report_json(const std::string& path) {
  if (!exists_as_file(path)) return nlohmann::json::object();
  const std::string text = read_file_text(path);
  nlohmann::json report = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (report.is_discarded() || !report.is_object()) {
    throw_error(ErrorCode::kFormat, "{}: not a JSON object (a scan's report.json)", path);
  }
  return report;
}

}  // namespace

ScanReportFiles write_result_report_html(const std::string& result_folder, const ResultReportOptions& options,
                                         const ProgressCallback& progress) {
  if (!(options.voxel_size_m == 0.0 || (std::isfinite(options.voxel_size_m) && options.voxel_size_m > 0.0))) {
    throw_error(ErrorCode::kInvalidArgument, "voxel size {} m (positive; 0: report.json's)", options.voxel_size_m);
  }
  if (options.image_size_px < 64 || options.image_size_px > 4096) {
    throw_error(ErrorCode::kInvalidArgument, "image size {} px (64 to 4096)", options.image_size_px);
  }
  const std::string cloud_path = result_folder + "/cloud.ply";
  if (!exists_as_file(cloud_path)) {
    throw_error(ErrorCode::kNotFound, "{}: no such file (a result folder holds the model as cloud.ply)", cloud_path);
  }
  ScanReportInputs inputs;
  inputs.report = read_report_json(result_folder + "/report.json");
  const PointCloud cloud = read_ply_cloud(cloud_path);
  inputs.cloud = &cloud;
  if (exists_as_file(result_folder + "/trajectory.txt")) {
    inputs.trajectory = read_tum_trajectory(result_folder + "/trajectory.txt");
  }
  const std::string undeformed_trajectory = result_folder + "/undeformed/trajectory.txt";
  if (exists_as_file(undeformed_trajectory)) {
    inputs.trajectory_undeformed = read_tum_trajectory(undeformed_trajectory);
    // A folder the caller filled has no report.json saying so; its undeformed/ does.
    if (!inputs.report.contains("deformation")) inputs.report["deformation"] = {{"enabled", true}};
  }

  std::optional<eval::ResultEvaluation> evaluation;
  if (!options.recording_folder.empty()) {
    eval::EvalOptions eval_options;
    eval_options.keep_point_errors = true;
    eval_options.voxel_size_m = options.voxel_size_m;
    evaluation = eval::evaluate_with_undeformed(result_folder, options.recording_folder, eval_options, progress);
    // The figures shown are those measured now, whatever an older report.json holds.
    inputs.report["evaluation"] = eval::evaluation_json(evaluation->report);
    if (evaluation->undeformed) inputs.report["evaluation_undeformed"] = eval::evaluation_json(*evaluation->undeformed);
    inputs.evaluation = &evaluation->report;
    inputs.point_errors_m = evaluation->report.cloud_point_errors_m;
    if (evaluation->report.trajectory) {
      const std::string truth_path = options.recording_folder + "/groundtruth/trajectory.txt";
      inputs.truth = eval::truth_in_estimate_frame(read_tum_trajectory(truth_path), *evaluation->report.trajectory);
    }
  }
  inputs.title = options.title.empty() ? "Scan of " + result_folder : options.title;
  inputs.image_size_px = options.image_size_px;
  report_progress(progress, {"report", 0, 1, result_folder + "/report.html"});
  ScanReportFiles files = write_scan_report_html(result_folder, inputs);
  report_progress(progress, {"report", 1, 1, files.html});
  return files;
}

}  // namespace sls::report
