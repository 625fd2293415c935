// `sls calibrate --report DIR`: DIR/calibration.json (what --json prints) and a self-contained
// DIR/calibration_report.html for people: the RMS figures, every view with its corners and
// residual vectors drawn (camera and projector, magnified), the rejected views and why, and
// the board poses, the projector and the turntable axis in 3D (top and side projections).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "calib/calibrate_capture.h"

namespace sls::cli {

nlohmann::json intrinsics_json(const CameraIntrinsics& c);
nlohmann::json vector_json(const Eigen::Vector3d& v);

// The result as JSON: the figures, the views used and rejected, the calibration, the axis
// and, for a simulated capture, "truth" (errors against the exact calibration).
nlohmann::json calibration_json(const calib::CalibrateCaptureResult& result);

void write_calibration_report(const std::string& folder, const calib::CalibrateCaptureResult& result,
                              const nlohmann::json& json);

}  // namespace sls::cli
