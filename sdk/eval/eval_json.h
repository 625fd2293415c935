// The quality figures as JSON: the object `sls eval --json` prints, report.json's
// "evaluation" and "evaluation_undeformed", and the C API's sls_evaluation_json() (all in
// micrometres and degrees; a figure with nothing to average is null, JSON having no NaN).
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "sdk/core/progress.h"
#include "sdk/eval/evaluate.h"
#include "sdk/eval/evaluate_regions.h"

namespace sls::eval {

// C2C (mean, RMS, p95, max), edge C2C and its point count of one surface.
nlohmann::json errors_json(const SurfaceErrors& errors);

// One image region of the paper's Table I (`sls eval --raw-scan`).
nlohmann::json region_json(const RegionErrors& region);

// Everything evaluate_result() measured.
nlohmann::json evaluation_json(const EvalReport& report);

// A result and, when it holds the model as tracked (RESULT/undeformed/cloud.ply, written by a
// scan with online deformation), that model too, at the result's voxel size.
struct ResultEvaluation {
  EvalReport report;
  std::optional<EvalReport> undeformed;
};

// evaluate_result() of RESULT and of RESULT/undeformed when it exists (the undeformed model's
// point errors are not kept). Errors as evaluate_result().
ResultEvaluation evaluate_with_undeformed(const std::string& result_folder, const std::string& recording_folder,
                                          const EvalOptions& options, const ProgressCallback& progress = {});

// evaluation_json() of the result, with the undeformed model's under "undeformed".
nlohmann::json result_evaluation_json(const ResultEvaluation& evaluation);

}  // namespace sls::eval
