// sls calibrate: camera, projector and turntable axis from board views (calib/), written as
// the calibration.yml that decode and fusion read. Input: a recording (e.g. `sls sim
// --calibration`) or a folder of captures, one subfolder per board pose.
#include <cstdio>
#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "samples/sls/commands.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"

#if defined(SLS_HAVE_CALIB)
#include "calib/calibrate_capture.h"
#include "samples/sls/calibration_report.h"
#endif

namespace sls::cli {
namespace {

struct CalibrateOptions {
  std::string input;
  std::string out;
  std::string patterns;
  std::string board;  // COLSxROWS
  double square_m = 0.0;
  std::string report;
  std::string device;
  double max_rms_px = 1.0;
  bool force = false;
  bool estimate_k3 = false;
};

#if defined(SLS_HAVE_CALIB)
int run_calibrate(const Context& context, const CalibrateOptions& options) {
  calib::CalibrateCaptureOptions calibrate;
  calibrate.input = options.input;
  calibrate.patterns = options.patterns;
  calibrate.estimate_k3 = options.estimate_k3;
  calibrate.device = options.device.empty() ? Device::cpu() : parse_device(options.device);
  if (!options.board.empty()) {
    char trailing = 0;
    if (std::sscanf(options.board.c_str(), "%dx%d%c", &calibrate.board.inner_cols, &calibrate.board.inner_rows,
                    &trailing) != 2) {
      throw_error(ErrorCode::kInvalidArgument, "--board {}: expected COLSxROWS inner corners, e.g. 9x7", options.board);
    }
    if (!(options.square_m > 0.0)) {
      throw_error(ErrorCode::kInvalidArgument, "--board needs --square (the square's side in metres)");
    }
    calibrate.board.square_m = options.square_m;
  } else if (options.square_m > 0.0) {
    throw_error(ErrorCode::kInvalidArgument, "--square needs --board COLSxROWS");
  }
  const calib::CalibrateCaptureResult result =
      calib::calibrate_capture(calibrate, context.progress_callback("calibrate"));
  nlohmann::json json = calibration_json(result);
  const double rms = result.procam.stereo_rms_px;
  const bool too_high = !(rms <= options.max_rms_px);
  const bool write = !too_high || options.force;
  json["out"] = options.out;
  json["written"] = write;
  json["max_rms_px"] = options.max_rms_px;
  if (too_high) {
    json["warning"] = fmt::format("stereo RMS {:.3f} px is above the limit {:.3f} px{}", rms, options.max_rms_px,
                                  options.force ? ": written anyway (--force)" : ": not written (--force writes it)");
  }
  // The report first: if the calibration cannot be written, the work is still on disk.
  if (!options.report.empty()) {
    json["report"] = options.report + "/calibration_report.html";
    write_calibration_report(options.report, result, json);
  }
  if (write) {
    const std::filesystem::path parent = std::filesystem::path(options.out).parent_path();
    if (!parent.empty()) create_directories(parent.string());
    write_calibration(options.out, result.procam.calibration);
  }
  if (!write) throw_error(ErrorCode::kInvalidArgument, "{}", json["warning"].get<std::string>());
  json["ok"] = true;
  context.emit(json, [&] {
    std::cout << fmt::format("calibrated from {} of {} views in {:.1f} s: camera {:.3f} px, projector {:.3f} px, "
                             "stereo {:.3f} px RMS (corners dropped as mislocated: {} camera, {} projector)\n",
                             result.procam.views_used, result.views.size(), result.seconds,
                             result.procam.camera_rms_px, result.procam.projector_rms_px, rms,
                             result.procam.camera_outliers, result.procam.projector_outliers);
    for (std::size_t v = 0; v < result.views.size(); ++v) {
      if (!result.procam.views[v].used) {
        std::cout << "  rejected " << result.views[v].name << ": " << result.procam.views[v].rejected_reason << "\n";
      }
    }
    std::cout << (result.axis.fitted
                      ? fmt::format("turntable axis from {} views ({:.0f}° span)\n", result.axis.views,
                                    result.axis.angle_span_deg)
                      : "no turntable axis: " + result.axis.reason + "\n");
    if (json.contains("truth")) {
      const nlohmann::json& t = json["truth"];
      std::cout << fmt::format("against the exact calibration: focal {:.4f} %, principal point {:.3f} px, baseline "
                               "{:.4f} %, rotation {:.4f}°",
                               100.0 * t["focal_rel_err"].get<double>(), t["principal_point_err_px"].get<double>(),
                               100.0 * t["baseline_rel_err"].get<double>(), t["rotation_err_deg"].get<double>());
      if (!t["axis_direction_err_deg"].is_null()) {
        std::cout << fmt::format(", axis {:.4f}° and {:.1f} um", t["axis_direction_err_deg"].get<double>(),
                                 t["axis_point_err_um"].get<double>());
      }
      std::cout << "\n";
    }
    if (too_high) std::cout << "warning: " << json["warning"].get<std::string>() << "\n";
    std::cout << "wrote " << options.out;
    if (!options.report.empty()) std::cout << " and " << options.report << "/calibration_report.html";
    std::cout << "\n";
  });
  return kExitOk;
}
#endif

}  // namespace

void add_calibrate_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "calibrate", "Calibrate camera, projector and turntable axis from board views (a recording, e.g. `sls sim "
                   "--calibration`, or a folder with one subfolder of pattern images per board pose)");
  auto options = std::make_shared<CalibrateOptions>();
  command->add_option("--input", options->input, "Recording, or folder of captures (one subfolder per board pose)")
      ->required();
  command->add_option("--out", options->out, "calibration.yml to write")->required();
  command->add_option("--patterns", options->patterns,
                      "Pattern set by name: opencv-graycode:WxH (OpenCV structured_light's Gray code for a WxH "
                      "projector, white and black last) or gray-phase:WxH (default: the recording's own)");
  command->add_option("--board", options->board, "Chessboard inner corners COLSxROWS, e.g. 9x7 (default: a simulated "
                                                 "capture's own board)");
  command->add_option("--square", options->square_m, "Chessboard square side in metres (with --board)")
      ->check(CLI::PositiveNumber);
  command->add_option("--report", options->report, "Folder for calibration_report.html and calibration.json");
  command->add_option("--max-rms-px", options->max_rms_px,
                      "Stereo RMS above which the calibration is not written (unless --force)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_flag("--force", options->force, "Write the calibration even when its RMS is above --max-rms-px");
  command->add_flag("--estimate-k3", options->estimate_k3,
                    "Also estimate the r^6 distortion term (default: fixed at 0, poorly determined by a narrow field)");
  command->add_option("--device", options->device, "Decode on cpu, cuda or cuda:N (default: cpu)");
  command->callback([&context, exit_code, options] {
    run_command(context, "calibrate",
                [&context, options] {
#if defined(SLS_HAVE_CALIB)
                  return run_calibrate(context, *options);
#else
                  throw_error(ErrorCode::kUnsupported, "sls was built without OpenCV: calibration is not available");
                  return kExitUnavailable;
#endif
                },
                exit_code);
  });
}

}  // namespace sls::cli
