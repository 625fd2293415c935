// The quality figures and the report through the C API (sls_eval.h): a scan made through the C
// API and written to a folder, measured by sls_evaluate() with the same figures, point errors and
// JSON as the SDK's own evaluation (what `sls eval` prints), the model as tracked when the folder
// holds one, report.html written from the folder with and without a recording, progress and its
// cancel, and the mistakes (NULL handles and outputs, bad configs and struct sizes, missing files)
// each a status, never a crash. Also run under ASan (build/asan).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "sdk/core/file_util.h"
#include "sdk/eval/eval_json.h"
#include "tests/api/c_results_fixture.h"

namespace sls::test {
namespace {

struct EvaluationDeleter {
  void operator()(sls_evaluation* evaluation) const { sls_evaluation_destroy(evaluation); }
};
using EvaluationPtr = std::unique_ptr<sls_evaluation, EvaluationDeleter>;

class CEval : public ::testing::Test {
 protected:
  // A 6-frame knob recording scanned through the C API; cloud.ply and trajectory.txt written to
  // a result folder, as an integrator would.
  static void SetUpTestSuite() {
    directory_ = new TemporaryDirectory();
    recording_ = new std::string(sim_recording(*directory_, "knob", true, 6));
    result_ = new std::string(directory_->file("result"));
    std::filesystem::create_directories(*result_);
    const ContextPtr context = cpu_context();
    sls_scan_config config;
    sls_scan_config_init(&config);
    config.use_turntable_prior = 1;
    sls_scan* scan = nullptr;
    ASSERT_EQ(sls_scan_create(context.get(), &config, &scan, nullptr), SLS_OK);
    const ScanPtr owned(scan);
    SLS_OK_CALL(sls_scan_run_recording(scan, recording_->c_str(), &error_));
    SLS_OK_CALL(sls_scan_write_cloud(scan, (*result_ + "/cloud.ply").c_str(), &error_));
    SLS_OK_CALL(sls_scan_write_trajectory(scan, (*result_ + "/trajectory.txt").c_str(), &error_));
    sls_scan_summary summary;
    sls_scan_summary_init(&summary);
    SLS_OK_CALL(sls_scan_get_summary(scan, &summary, &error_));
    voxel_size_m_ = summary.voxel_size_m;
    ASSERT_GT(voxel_size_m_, 0.0);
  }
  static void TearDownTestSuite() {
    delete result_;
    delete recording_;
    delete directory_;
  }
  static const std::string& recording() { return *recording_; }
  static const std::string& result() { return *result_; }
  std::string scratch(const std::string& name) const { return directory_->file(name); }

  static sls_eval_config config_with_voxel() {
    sls_eval_config config;
    sls_eval_config_init(&config);
    config.voxel_size_m = voxel_size_m_;
    return config;
  }

  EvaluationPtr evaluate(const std::string& folder, const sls_eval_config* config) {
    sls_evaluation* evaluation = nullptr;
    SLS_OK_CALL(sls_evaluate(context_.get(), folder.c_str(), recording().c_str(), config, nullptr, nullptr,
                             &evaluation, &error_));
    return EvaluationPtr(evaluation);
  }

  static TemporaryDirectory* directory_;
  static std::string* recording_;
  static std::string* result_;
  static double voxel_size_m_;  // the scan's (the C API writes no report.json)
  ContextPtr context_ = cpu_context();
};
TemporaryDirectory* CEval::directory_ = nullptr;
std::string* CEval::recording_ = nullptr;
std::string* CEval::result_ = nullptr;
double CEval::voxel_size_m_ = 0.0;

TEST_F(CEval, DefaultsAreTheSdks) {
  sls_eval_config config;
  sls_eval_config_init(&config);
  const eval::EvalOptions options;
  EXPECT_EQ(config.struct_size, sizeof(config));
  EXPECT_EQ(config.voxel_size_m, options.voxel_size_m);
  EXPECT_EQ(config.edge_band_voxels, options.edge_band_voxels);
  EXPECT_EQ(config.coverage_radius_voxels, options.coverage_radius_voxels);
  EXPECT_EQ(config.visibility_stride, options.visibility_stride);
  EXPECT_EQ(config.align_first_pose, 1);
  EXPECT_EQ(config.register_to_surface, 0);
  sls_report_config report;
  sls_report_config_init(&report);
  EXPECT_EQ(report.recording_path, nullptr);
  EXPECT_EQ(report.title, nullptr);
  EXPECT_EQ(report.image_size_px, 800);
  EXPECT_EQ(report.voxel_size_m, 0.0);
}

TEST_F(CEval, FiguresEqualTheSdksEvaluationOfTheSameFolder) {
  const sls_eval_config config = config_with_voxel();
  const EvaluationPtr evaluation = evaluate(result(), &config);
  ASSERT_NE(evaluation, nullptr);

  eval::EvalOptions options;
  options.voxel_size_m = voxel_size_m_;
  options.keep_point_errors = true;
  const eval::ResultEvaluation expected = eval::evaluate_with_undeformed(result(), recording(), options);
  ASSERT_FALSE(expected.undeformed.has_value());

  sls_evaluation_summary summary;
  sls_evaluation_summary_init(&summary);
  SLS_OK_CALL(sls_evaluation_get_summary(evaluation.get(), 0, &summary, &error_));
  const eval::EvalReport& report = expected.report;
  EXPECT_EQ(summary.voxel_size_m, voxel_size_m_);
  EXPECT_EQ(summary.points, report.cloud_points);
  EXPECT_GT(summary.points, 1000u);
  EXPECT_EQ(summary.c2c_mean_m, report.cloud.all.mean_m);
  EXPECT_EQ(summary.c2c_rms_m, report.cloud.all.rms_m);
  EXPECT_EQ(summary.c2c_p95_m, report.cloud.all.p95_m);
  EXPECT_EQ(summary.c2c_max_m, report.cloud.all.max_m);
  EXPECT_EQ(summary.edge_points, report.cloud.edge.count);
  EXPECT_GT(summary.edge_points, 0u);  // the knob's knurls are creases
  EXPECT_EQ(summary.edge_c2c_mean_m, report.cloud.edge.mean_m);
  EXPECT_EQ(summary.coverage, report.coverage.fraction());
  EXPECT_GT(summary.coverage, 0.0);
  EXPECT_LE(summary.coverage, 1.0);
  ASSERT_EQ(summary.has_trajectory, 1);
  ASSERT_TRUE(report.trajectory.has_value());
  EXPECT_EQ(summary.trajectory_frames, 6u);
  EXPECT_EQ(summary.ate_rmse_m, report.trajectory->ate_rmse_m);
  EXPECT_EQ(summary.ate_max_m, report.trajectory->ate_max_m);
  EXPECT_EQ(summary.loop_closure_error_m, report.trajectory->loop_closure_error_m);
  EXPECT_EQ(summary.has_undeformed, 0);
  // The model lies within a fraction of a voxel of the exact surface.
  EXPECT_LT(summary.c2c_mean_m, 2 * voxel_size_m_);

  const char* json = nullptr;
  SLS_OK_CALL(sls_evaluation_json(evaluation.get(), &json, &error_));
  ASSERT_NE(json, nullptr);
  EXPECT_EQ(nlohmann::json::parse(json), eval::result_evaluation_json(expected));

  size_t count = 0;
  SLS_OK_CALL(sls_evaluation_get_point_errors(evaluation.get(), nullptr, 0, &count, &error_));
  ASSERT_EQ(count, report.cloud_points);
  std::vector<float> errors(count + 2, -1.0f);
  SLS_OK_CALL(sls_evaluation_get_point_errors(evaluation.get(), errors.data(), errors.size(), &count, &error_));
  EXPECT_EQ(std::vector<float>(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(count)),
            report.cloud_point_errors_m);
  EXPECT_EQ(errors[count], -1.0f);  // nothing past the points
  std::vector<float> few(3, -1.0f);
  SLS_OK_CALL(sls_evaluation_get_point_errors(evaluation.get(), few.data(), few.size(), &count, &error_));
  EXPECT_EQ(count, report.cloud_points);
  EXPECT_EQ(few[2], report.cloud_point_errors_m[2]);
}

TEST_F(CEval, TheModelAsTrackedBesideItWhenTheFolderHoldsOne) {
  const std::string folder = scratch("with-undeformed");
  std::filesystem::create_directories(folder + "/undeformed");
  for (const char* name : {"cloud.ply", "trajectory.txt"}) {
    std::filesystem::copy_file(result() + "/" + name, folder + "/" + name);
    std::filesystem::copy_file(result() + "/" + name, folder + "/undeformed/" + name);
  }
  const sls_eval_config config = config_with_voxel();
  const EvaluationPtr evaluation = evaluate(folder, &config);
  ASSERT_NE(evaluation, nullptr);
  sls_evaluation_summary deformed, tracked;
  sls_evaluation_summary_init(&deformed);
  sls_evaluation_summary_init(&tracked);
  SLS_OK_CALL(sls_evaluation_get_summary(evaluation.get(), 0, &deformed, &error_));
  SLS_OK_CALL(sls_evaluation_get_summary(evaluation.get(), 1, &tracked, &error_));
  EXPECT_EQ(deformed.has_undeformed, 1);
  EXPECT_EQ(tracked.c2c_mean_m, deformed.c2c_mean_m);  // the same model in both places
  EXPECT_EQ(tracked.ate_rmse_m, deformed.ate_rmse_m);
  const char* json = nullptr;
  SLS_OK_CALL(sls_evaluation_json(evaluation.get(), &json, &error_));
  EXPECT_TRUE(nlohmann::json::parse(json).contains("undeformed"));

  const EvaluationPtr without = evaluate(result(), &config);
  SLS_FAILS(sls_evaluation_get_summary(without.get(), 1, &tracked, &error_), SLS_ERROR_NOT_FOUND, "undeformed");
}

TEST_F(CEval, ProgressIsReportedAndACancelMakesNothing) {
  struct Seen {
    std::vector<std::string> stages;
    int answer = 1;
  } seen;
  const auto on_progress = [](const sls_eval_progress* progress, void* user) {
    auto* state = static_cast<Seen*>(user);
    EXPECT_EQ(progress->struct_size, sizeof(sls_eval_progress));
    EXPECT_NE(progress->detail, nullptr);
    state->stages.emplace_back(progress->stage);
    return state->answer;
  };
  const sls_eval_config config = config_with_voxel();
  sls_evaluation* evaluation = nullptr;
  SLS_OK_CALL(sls_evaluate(context_.get(), result().c_str(), recording().c_str(), &config, on_progress, &seen,
                           &evaluation, &error_));
  sls_evaluation_destroy(evaluation);
  EXPECT_NE(std::find(seen.stages.begin(), seen.stages.end(), "c2c"), seen.stages.end());
  EXPECT_NE(std::find(seen.stages.begin(), seen.stages.end(), "visibility"), seen.stages.end());

  seen.answer = 0;
  evaluation = reinterpret_cast<sls_evaluation*>(&seen);  // must be reset to NULL
  SLS_FAILS(sls_evaluate(context_.get(), result().c_str(), recording().c_str(), &config, on_progress, &seen,
                         &evaluation, &error_),
            SLS_ERROR_CANCELLED, nullptr);
  EXPECT_EQ(evaluation, nullptr);

  const std::string folder = scratch("report-cancelled");
  std::filesystem::create_directories(folder);
  std::filesystem::copy_file(result() + "/cloud.ply", folder + "/cloud.ply");
  sls_report_config report;
  sls_report_config_init(&report);
  report.recording_path = recording().c_str();
  report.image_size_px = 160;
  report.voxel_size_m = voxel_size_m_;
  SLS_FAILS(sls_report_write_html(context_.get(), folder.c_str(), &report, on_progress, &seen, &error_),
            SLS_ERROR_CANCELLED, nullptr);
  EXPECT_FALSE(std::filesystem::exists(folder + "/report.html"));
}

TEST_F(CEval, ReportFromTheFolderWithAndWithoutARecording) {
  const std::string folder = scratch("report");
  std::filesystem::create_directories(folder);
  for (const char* name : {"cloud.ply", "trajectory.txt"}) {
    std::filesystem::copy_file(result() + "/" + name, folder + "/" + name);
  }
  // report.json gives the voxel size and the summary, as `sls scan` writes it.
  write_file_atomic(folder + "/report.json",
                    nlohmann::json({{"voxel_size_m", voxel_size_m_}, {"frames", 6}, {"frames_fused", 6}}).dump());
  sls_report_config config;
  sls_report_config_init(&config);
  config.image_size_px = 160;
  config.title = "Knob through the C API";
  SLS_OK_CALL(sls_report_write_html(context_.get(), folder.c_str(), &config, nullptr, nullptr, &error_));
  const std::string plain = read_file_text(folder + "/report.html");
  EXPECT_NE(plain.find("Knob through the C API"), std::string::npos);
  EXPECT_EQ(plain.find("C2C"), std::string::npos);  // no ground truth asked for: no quality table
  EXPECT_TRUE(std::filesystem::exists(folder + "/report_view_0.png"));
  EXPECT_NE(plain.find("report_view_0.png"), std::string::npos);

  config.recording_path = recording().c_str();
  SLS_OK_CALL(sls_report_write_html(context_.get(), folder.c_str(), &config, nullptr, nullptr, &error_));
  const std::string measured = read_file_text(folder + "/report.html");
  EXPECT_NE(measured.find("C2C"), std::string::npos);
  EXPECT_NE(measured.find("report_error_"), std::string::npos);  // the heat map
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("report_", 0) == 0 && entry.path().extension() == ".png") {
      EXPECT_NE(measured.find(name), std::string::npos) << name << " written but not shown";
    }
  }
}

TEST_F(CEval, MistakesAreStatusesNeverCrashes) {
  sls_context* context = context_.get();
  const sls_eval_config good = config_with_voxel();
  sls_evaluation* evaluation = nullptr;
  const char* rec = recording().c_str();
  const char* res = result().c_str();
  SLS_FAILS(sls_evaluate(nullptr, res, rec, &good, nullptr, nullptr, &evaluation, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "context");
  SLS_FAILS(sls_evaluate(context, nullptr, rec, &good, nullptr, nullptr, &evaluation, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "result_path");
  SLS_FAILS(sls_evaluate(context, res, nullptr, &good, nullptr, nullptr, &evaluation, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "recording_path");
  SLS_FAILS(sls_evaluate(context, res, rec, &good, nullptr, nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "evaluation");
  // No voxel size: the folder has no report.json and the config gives none.
  SLS_FAILS(sls_evaluate(context, res, rec, nullptr, nullptr, nullptr, &evaluation, &error_),
            SLS_ERROR_INVALID_ARGUMENT, "voxel");
  EXPECT_EQ(evaluation, nullptr);
  SLS_FAILS(sls_evaluate(context, scratch("nowhere").c_str(), rec, &good, nullptr, nullptr, &evaluation, &error_),
            SLS_ERROR_NOT_FOUND, "nowhere");
  const std::string empty = scratch("empty-result");
  std::filesystem::create_directories(empty);
  SLS_FAILS(sls_evaluate(context, empty.c_str(), rec, &good, nullptr, nullptr, &evaluation, &error_),
            SLS_ERROR_NOT_FOUND, "cloud.ply");
  SLS_FAILS(sls_evaluate(context, res, scratch("no-recording").c_str(), &good, nullptr, nullptr, &evaluation, &error_),
            SLS_ERROR_NOT_FOUND, nullptr);
  for (const auto& [field, value] : std::vector<std::pair<double sls_eval_config::*, double>>{
           {&sls_eval_config::voxel_size_m, -1.0},
           {&sls_eval_config::voxel_size_m, std::nan("")},
           {&sls_eval_config::edge_band_voxels, 0.0},
           {&sls_eval_config::coverage_radius_voxels, INFINITY}}) {
    sls_eval_config bad = good;
    bad.*field = value;
    SLS_FAILS(sls_evaluate(context, res, rec, &bad, nullptr, nullptr, &evaluation, &error_),
              SLS_ERROR_INVALID_ARGUMENT, "config.");
  }
  sls_eval_config bad = good;
  bad.visibility_stride = 0;
  SLS_FAILS(sls_evaluate(context, res, rec, &bad, nullptr, nullptr, &evaluation, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "visibility_stride");
  bad = good;
  bad.struct_size = 0;
  SLS_FAILS(sls_evaluate(context, res, rec, &bad, nullptr, nullptr, &evaluation, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "struct_size");

  const EvaluationPtr made = evaluate(result(), &good);
  sls_evaluation_summary summary;
  sls_evaluation_summary_init(&summary);
  SLS_FAILS(sls_evaluation_get_summary(nullptr, 0, &summary, &error_), SLS_ERROR_INVALID_ARGUMENT, "evaluation");
  SLS_FAILS(sls_evaluation_get_summary(made.get(), 0, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "summary");
  SLS_FAILS(sls_evaluation_get_summary(made.get(), 2, &summary, &error_), SLS_ERROR_INVALID_ARGUMENT, "undeformed");
  summary.struct_size = 3;
  SLS_FAILS(sls_evaluation_get_summary(made.get(), 0, &summary, &error_), SLS_ERROR_INVALID_ARGUMENT, "struct_size");
  const char* json = nullptr;
  SLS_FAILS(sls_evaluation_json(nullptr, &json, &error_), SLS_ERROR_INVALID_ARGUMENT, "evaluation");
  SLS_FAILS(sls_evaluation_json(made.get(), nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT, "json");
  size_t count = 0;
  SLS_FAILS(sls_evaluation_get_point_errors(made.get(), nullptr, 4, &count, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "errors_m");
  SLS_FAILS(sls_evaluation_get_point_errors(made.get(), nullptr, 0, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "count");
  SLS_FAILS(sls_evaluation_get_point_errors(nullptr, nullptr, 0, &count, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "evaluation");
  sls_evaluation_destroy(nullptr);

  sls_report_config report;
  sls_report_config_init(&report);
  SLS_FAILS(sls_report_write_html(nullptr, res, &report, nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "context");
  SLS_FAILS(sls_report_write_html(context, nullptr, &report, nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "result_path");
  SLS_FAILS(sls_report_write_html(context, scratch("nowhere").c_str(), &report, nullptr, nullptr, &error_),
            SLS_ERROR_NOT_FOUND, "cloud.ply");
  report.image_size_px = 10;
  SLS_FAILS(sls_report_write_html(context, res, &report, nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "image size");
  sls_report_config_init(&report);
  report.voxel_size_m = -1.0;
  SLS_FAILS(sls_report_write_html(context, res, &report, nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "voxel size");
  sls_report_config_init(&report);
  report.struct_size = 1;
  SLS_FAILS(sls_report_write_html(context, res, &report, nullptr, nullptr, &error_), SLS_ERROR_INVALID_ARGUMENT,
            "struct_size");
  // A corrupt report.json is named, and nothing is written.
  const std::string corrupt = scratch("corrupt-report");
  std::filesystem::create_directories(corrupt);
  std::filesystem::copy_file(result() + "/cloud.ply", corrupt + "/cloud.ply");
  write_file_atomic(corrupt + "/report.json", "{\"frames\": ");
  sls_report_config_init(&report);
  SLS_FAILS(sls_report_write_html(context, corrupt.c_str(), &report, nullptr, nullptr, &error_), SLS_ERROR_FORMAT,
            "report.json");
  EXPECT_FALSE(std::filesystem::exists(corrupt + "/report.html"));
}

}  // namespace
}  // namespace sls::test
