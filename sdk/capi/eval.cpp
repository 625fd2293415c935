// sls_evaluate and sls_report_write_html: sdk/eval (what `sls eval` measures) and sdk/report
// (the report `sls scan` writes) behind the C API. An evaluation is immutable once made; its
// JSON text is made with it, so the getters only copy out.
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>

#include "sdk/capi/capi_guard.h"
#include "sdk/capi/context_internal.h"
#include "sdk/capi/progress_callback.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/error.h"
#include "sdk/core/progress.h"
#include "sdk/eval/eval_json.h"
#include "sdk/report/result_report.h"
#include "sls/sls_eval.h"

struct sls_evaluation {
  sls::eval::ResultEvaluation result;
  std::string json;
};

namespace {

sls_eval_config eval_config_defaults() {
  sls_eval_config config = sls::capi::zeroed<sls_eval_config>();
  const sls::eval::EvalOptions options;
  config.voxel_size_m = options.voxel_size_m;
  config.edge_band_voxels = options.edge_band_voxels;
  config.coverage_radius_voxels = options.coverage_radius_voxels;
  config.visibility_stride = options.visibility_stride;
  config.align_first_pose = options.align_first_pose ? 1 : 0;
  config.register_to_surface = options.register_to_surface ? 1 : 0;
  return config;
}

sls_report_config report_config_defaults() {
  sls_report_config config = sls::capi::zeroed<sls_report_config>();
  config.image_size_px = sls::report::ResultReportOptions().image_size_px;
  return config;
}

constexpr std::size_t kEvalConfigFirstVersionSize = offsetof(sls_eval_config, register_to_surface) + sizeof(int);
constexpr std::size_t kSummaryFirstVersionSize = offsetof(sls_evaluation_summary, has_undeformed) + sizeof(int);
constexpr std::size_t kReportConfigFirstVersionSize = offsetof(sls_report_config, voxel_size_m) + sizeof(double);

sls::eval::EvalOptions eval_options(const sls_eval_config& config) {
  const auto positive = [](double value) { return std::isfinite(value) && value > 0.0; };
  if (!(config.voxel_size_m == 0.0 || positive(config.voxel_size_m))) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.voxel_size_m {} (metres, positive; 0: report.json's)",
                     config.voxel_size_m);
  }
  if (!positive(config.edge_band_voxels)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.edge_band_voxels {} (positive)", config.edge_band_voxels);
  }
  if (!positive(config.coverage_radius_voxels)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.coverage_radius_voxels {} (positive)",
                     config.coverage_radius_voxels);
  }
  if (config.visibility_stride < 1) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.visibility_stride {} (1 or more)",
                     config.visibility_stride);
  }
  sls::eval::EvalOptions options;
  options.voxel_size_m = config.voxel_size_m;
  options.edge_band_voxels = config.edge_band_voxels;
  options.coverage_radius_voxels = config.coverage_radius_voxels;
  options.visibility_stride = config.visibility_stride;
  options.align_first_pose = config.align_first_pose != 0;
  options.register_to_surface = config.register_to_surface != 0;
  options.keep_point_errors = true;  // sls_evaluation_get_point_errors: 4 bytes a point
  return options;
}

double or_nan(const sls::eval::DistanceStats& stats, double sls::eval::DistanceStats::*field) {
  return stats.count > 0 ? stats.*field : std::numeric_limits<double>::quiet_NaN();
}

sls_evaluation_summary summary_of(const sls::eval::EvalReport& report, bool has_undeformed) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  sls_evaluation_summary summary = sls::capi::zeroed<sls_evaluation_summary>();
  summary.voxel_size_m = report.voxel_size_m;
  summary.points = report.cloud_points;
  const sls::eval::SurfaceErrors& errors = report.cloud;
  summary.c2c_mean_m = or_nan(errors.all, &sls::eval::DistanceStats::mean_m);
  summary.c2c_rms_m = or_nan(errors.all, &sls::eval::DistanceStats::rms_m);
  summary.c2c_p95_m = or_nan(errors.all, &sls::eval::DistanceStats::p95_m);
  summary.c2c_max_m = or_nan(errors.all, &sls::eval::DistanceStats::max_m);
  summary.edge_points = errors.edge.count;
  summary.edge_c2c_mean_m = or_nan(errors.edge, &sls::eval::DistanceStats::mean_m);
  summary.edge_c2c_rms_m = or_nan(errors.edge, &sls::eval::DistanceStats::rms_m);
  summary.coverage = report.coverage.considered > 0 ? report.coverage.fraction() : nan;
  summary.has_trajectory = report.trajectory ? 1 : 0;
  summary.ate_rmse_m = summary.ate_max_m = summary.loop_closure_error_m = summary.loop_closure_error_deg = nan;
  if (report.trajectory) {
    summary.trajectory_frames = report.trajectory->matched_frames;
    summary.ate_rmse_m = report.trajectory->ate_rmse_m;
    summary.ate_max_m = report.trajectory->ate_max_m;
    summary.loop_closure_error_m = report.trajectory->loop_closure_error_m;
    summary.loop_closure_error_deg = report.trajectory->loop_closure_error_rad * 180.0 / M_PI;
  }
  summary.has_undeformed = has_undeformed ? 1 : 0;
  return summary;
}

const char* const kNoEvaluation = "evaluation is NULL";

}  // namespace

extern "C" {

SLS_CAPI_DEFINE_INIT(sls_eval_config, register_to_surface, eval_config_defaults())

SLS_CAPI_DEFINE_INIT(sls_evaluation_summary, has_undeformed, sls::capi::zeroed<sls_evaluation_summary>())

SLS_CAPI_DEFINE_INIT(sls_report_config, voxel_size_m, report_config_defaults())

SLS_API sls_status sls_evaluate(sls_context* context, const char* result_path, const char* recording_path,
                                const sls_eval_config* config, sls_eval_progress_callback progress, void* user,
                                sls_evaluation** evaluation, sls_error** error) {
  SLS_CAPI_REQUIRE(evaluation != nullptr, error, "evaluation (the output pointer) is NULL");
  *evaluation = nullptr;
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  SLS_CAPI_REQUIRE(result_path != nullptr, error, "result_path is NULL");
  SLS_CAPI_REQUIRE(recording_path != nullptr, error, "recording_path is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    sls_eval_config defaults;
    sls_eval_config_init(&defaults);
    const sls_eval_config resolved =
        config == nullptr ? defaults
                          : sls::capi::read_versioned(config, defaults, kEvalConfigFirstVersionSize, "sls_eval_config");
    auto made = std::make_unique<sls_evaluation>();
    made->result = sls::eval::evaluate_with_undeformed(result_path, recording_path, eval_options(resolved),
                                                       sls::capi::progress_callback(progress, user));
    made->json = sls::eval::result_evaluation_json(made->result).dump(2);
    *evaluation = made.release();
  });
}

SLS_API void sls_evaluation_destroy(sls_evaluation* evaluation) { delete evaluation; }

SLS_API sls_status sls_evaluation_get_summary(const sls_evaluation* evaluation, int undeformed,
                                              sls_evaluation_summary* summary, sls_error** error) {
  SLS_CAPI_REQUIRE(evaluation != nullptr, error, kNoEvaluation);
  SLS_CAPI_REQUIRE(summary != nullptr, error, "summary (the output pointer) is NULL");
  SLS_CAPI_REQUIRE(undeformed == 0 || undeformed == 1, error, "undeformed is neither 0 nor 1");
  return sls::capi::guarded(__func__, error, [&] {
    sls::capi::require_versioned(summary, kSummaryFirstVersionSize, "sls_evaluation_summary");
    const bool has_undeformed = evaluation->result.undeformed.has_value();
    if (undeformed == 1 && !has_undeformed) {
      sls::throw_error(sls::ErrorCode::kNotFound, "{} holds no model as tracked (undeformed/cloud.ply)",
                       evaluation->result.report.result_folder);
    }
    const sls::eval::EvalReport& report = undeformed == 1 ? *evaluation->result.undeformed : evaluation->result.report;
    sls::capi::write_versioned(summary_of(report, has_undeformed), summary, kSummaryFirstVersionSize,
                               "sls_evaluation_summary");
  });
}

SLS_API sls_status sls_evaluation_json(const sls_evaluation* evaluation, const char** json, sls_error** error) {
  SLS_CAPI_REQUIRE(evaluation != nullptr, error, kNoEvaluation);
  SLS_CAPI_REQUIRE(json != nullptr, error, "json (the output pointer) is NULL");
  *json = evaluation->json.c_str();
  return SLS_OK;
}

SLS_API sls_status sls_evaluation_get_point_errors(const sls_evaluation* evaluation, float* errors_m,
                                                   size_t capacity, size_t* count, sls_error** error) {
  SLS_CAPI_REQUIRE(evaluation != nullptr, error, kNoEvaluation);
  SLS_CAPI_REQUIRE(count != nullptr, error, "count (the output pointer) is NULL");
  SLS_CAPI_REQUIRE(errors_m != nullptr || capacity == 0, error, "errors_m is NULL with a capacity above 0");
  const std::vector<float>& errors = evaluation->result.report.cloud_point_errors_m;
  const std::size_t copied = std::min(capacity, errors.size());
  if (copied > 0) std::memcpy(errors_m, errors.data(), copied * sizeof(float));
  *count = errors.size();
  return SLS_OK;
}

SLS_API sls_status sls_report_write_html(sls_context* context, const char* result_path,
                                         const sls_report_config* config, sls_eval_progress_callback progress,
                                         void* user, sls_error** error) {
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  SLS_CAPI_REQUIRE(result_path != nullptr, error, "result_path is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    sls_report_config defaults;
    sls_report_config_init(&defaults);
    const sls_report_config resolved =
        config == nullptr
            ? defaults
            : sls::capi::read_versioned(config, defaults, kReportConfigFirstVersionSize, "sls_report_config");
    sls::report::ResultReportOptions options;
    if (resolved.recording_path != nullptr) options.recording_folder = resolved.recording_path;
    if (resolved.title != nullptr) options.title = resolved.title;
    options.image_size_px = resolved.image_size_px;
    options.voxel_size_m = resolved.voxel_size_m;
    sls::report::write_result_report_html(result_path, options, sls::capi::progress_callback(progress, user));
  });
}

}  // extern "C"
