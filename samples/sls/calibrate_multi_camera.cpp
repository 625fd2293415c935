#include "samples/sls/calibrate_multi_camera.h"

#include <filesystem>
#include <iostream>

#include <fmt/format.h>

#include "samples/sls/calibration_report.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"

namespace sls::cli {
namespace {

nlohmann::json pose_errors_json(const calib::PoseErrors& errors) {
  return {{"baseline_rel_err", errors.baseline_rel_err}, {"rotation_err_deg", errors.rotation_err_deg}};
}

nlohmann::json pose_json(const Pose& pose) {
  return {{"translation_m", vector_json(pose.translation())},
          {"baseline_m", pose.translation().norm()},
          {"rotation_deg", pose.angle_rad() * 180.0 / M_PI}};
}

// Every RMS the head's calibration is judged by, with its name: each camera's stereo (joint
// with the projector) and each camera–camera pose's.
std::vector<std::pair<std::string, double>> judged_rms(const calib::MultiCameraCalibrateResult& result) {
  std::vector<std::pair<std::string, double>> values;
  for (std::size_t k = 0; k < result.cameras.size(); ++k) {
    values.emplace_back(fmt::format("camera{} stereo RMS", k), result.cameras[k].procam.stereo_rms_px);
  }
  for (std::size_t k = 1; k < result.cameras.size(); ++k) {
    values.emplace_back(fmt::format("camera{}-camera0 RMS", k), result.pairs[k - 1].rms_px);
  }
  return values;
}

}  // namespace

nlohmann::json multi_camera_calibration_json(const calib::MultiCameraCalibrateResult& result) {
  nlohmann::json json = calibration_json(result.cameras.front());
  nlohmann::json cameras = nlohmann::json::array();
  for (std::size_t k = 0; k < result.cameras.size(); ++k) {
    const calib::CalibrateCaptureResult& camera = result.cameras[k];
    const calib::ProcamCalibration& procam = camera.procam;
    nlohmann::json used = nlohmann::json::array(), rejected = nlohmann::json::array();
    for (std::size_t v = 0; v < camera.views.size(); ++v) {
      if (procam.views[v].used) {
        used.push_back(camera.views[v].name);
      } else {
        rejected.push_back({{"name", camera.views[v].name}, {"reason", procam.views[v].rejected_reason}});
      }
    }
    nlohmann::json entry = {{"camera", k},
                            {"folder", result.camera_folders[k]},
                            {"camera_rms_px", procam.camera_rms_px},
                            {"projector_rms_px", procam.projector_rms_px},
                            {"stereo_rms_px", procam.stereo_rms_px},
                            {"views_used", used},
                            {"views_rejected", rejected},
                            {"intrinsics", intrinsics_json(procam.calibration.camera)},
                            {"T_camera_projector", pose_json(procam.calibration.T_camera_projector)},
                            {"seconds", camera.seconds}};
    if (k > 0) {
      const calib::CameraPairSolution& pair = result.pairs[k - 1];
      entry["T_camera0_camera"] = pose_json(pair.T_camera0_camera);
      entry["T_camera0_camera_via_projector"] = pose_json(pair.via_projector);
      entry["camera_camera_rms_px"] = pair.rms_px;
      entry["camera_camera_views"] = pair.views;
      entry["camera_camera_corners"] = pair.corners;
    }
    if (camera.errors) {
      const calib::CalibrationErrors& e = *camera.errors;
      entry["truth"] = {{"focal_rel_err", e.camera_focal_rel_err},
                        {"principal_point_err_px", e.camera_principal_point_err_px},
                        {"projector_focal_rel_err", e.projector_focal_rel_err},
                        {"projector_principal_point_err_px", e.projector_principal_point_err_px},
                        {"projector_baseline_rel_err", e.baseline_rel_err},
                        {"projector_rotation_err_deg", e.rotation_err_deg}};
    }
    // The head's exact calibration (groundtruth/calibration.yml) gives the camera–camera truth
    // also where the cameras' recordings have none of their own (a head captured through
    // devices, its truth put beside it).
    if (k > 0 && k - 1 < result.pair_errors.size()) {
      entry["truth"]["camera_camera"] = pose_errors_json(result.pair_errors[k - 1]);
      entry["truth"]["camera_camera"]["via_projector"] = pose_errors_json(result.pair_errors_via_projector[k - 1]);
    }
    cameras.push_back(entry);
  }
  json["camera_count"] = result.cameras.size();
  json["cameras"] = cameras;
  json["camera_camera_rms_px"] = result.camera_camera_rms_px;
  json["seconds"] = result.seconds;
  return json;
}

int run_multi_camera_calibrate(const Context& context, const calib::CalibrateCaptureOptions& options,
                               const MultiCameraOutput& output) {
  const calib::MultiCameraCalibrateResult result = calib::calibrate_multi_camera_capture(
      options, output.progress ? output.progress : context.progress_callback("calibrate"));
  nlohmann::json json = multi_camera_calibration_json(result);
  if (!output.capture.is_null()) json["capture"] = output.capture;
  std::string too_high;
  for (const auto& [what, rms] : judged_rms(result)) {
    if (!(rms <= output.max_rms_px)) too_high += fmt::format("{}{} {:.3f} px", too_high.empty() ? "" : ", ", what, rms);
  }
  const bool write = too_high.empty() || output.force;
  json["out"] = output.out;
  json["written"] = write;
  json["max_rms_px"] = output.max_rms_px;
  if (!too_high.empty()) {
    json["warning"] = fmt::format("{} above the limit {:.3f} px{}", too_high, output.max_rms_px,
                                  output.force ? ": written anyway (--force)" : ": not written (--force writes it)");
  }
  // The reports first: if the calibration cannot be written, the work is still on disk.
  if (!output.report.empty()) {
    json["report"] = output.report + "/calibration_report.html";
    write_calibration_report(output.report, result.cameras.front(), json);
    for (std::size_t k = 1; k < result.cameras.size(); ++k) {
      write_calibration_report(fmt::format("{}/camera{}", output.report, k), result.cameras[k],
                               calibration_json(result.cameras[k]));
    }
  }
  if (write) {
    const std::filesystem::path parent = std::filesystem::path(output.out).parent_path();
    if (!parent.empty()) create_directories(parent.string());
    write_calibration(output.out, result.calibration);
  }
  if (!write) throw_error(ErrorCode::kInvalidArgument, "{}", json["warning"].get<std::string>());
  json["ok"] = true;
  context.emit(json, [&] {
    std::cout << fmt::format("calibrated a head of {} cameras in {:.1f} s:\n", result.cameras.size(), result.seconds);
    for (std::size_t k = 0; k < result.cameras.size(); ++k) {
      const calib::CalibrateCaptureResult& camera = result.cameras[k];
      std::cout << fmt::format("  camera{}: {} of {} views, camera {:.3f} px, projector {:.3f} px, stereo {:.3f} px RMS",
                               k, camera.procam.views_used, camera.views.size(), camera.procam.camera_rms_px,
                               camera.procam.projector_rms_px, camera.procam.stereo_rms_px);
      if (k > 0) {
        const calib::CameraPairSolution& pair = result.pairs[k - 1];
        std::cout << fmt::format("; against camera0 from {} views: baseline {:.4f} mm, {:.3f} px RMS",
                                 pair.views, 1e3 * pair.T_camera0_camera.translation().norm(), pair.rms_px);
      }
      std::cout << "\n";
      const bool pair_truth = k > 0 && k - 1 < result.pair_errors.size();
      if (camera.errors || pair_truth) {
        std::cout << "    against the exact calibration:";
        if (camera.errors) {
          std::cout << fmt::format(" focal {:.4f} %, principal point {:.3f} px",
                                   100.0 * camera.errors->camera_focal_rel_err,
                                   camera.errors->camera_principal_point_err_px);
        }
        if (pair_truth) {
          std::cout << fmt::format("{} camera-camera baseline {:.4f} %, rotation {:.4f}°", camera.errors ? "," : "",
                                   100.0 * result.pair_errors[k - 1].baseline_rel_err,
                                   result.pair_errors[k - 1].rotation_err_deg);
        }
        std::cout << "\n";
      }
    }
    if (json.contains("warning")) std::cout << "warning: " << json["warning"].get<std::string>() << "\n";
    std::cout << "wrote " << output.out;
    if (!output.report.empty()) std::cout << " and " << output.report << "/calibration_report.html";
    std::cout << "\n";
  });
  return kExitOk;
}

}  // namespace sls::cli
