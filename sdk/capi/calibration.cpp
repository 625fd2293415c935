// sls_calibration: calib::calibrate_capture (calib/calibrate_capture.h, what `sls calibrate`
// runs) behind the C API, or calib::calibrate_multi_camera_capture for a head's folder. A run makes an immutable result; the getters copy out of it, its
// strings stay in it until sls_calibration_destroy(). Built with SLS_HAVE_CALIB where the
// sls_calib target exists (OpenCV found); elsewhere every function is a stub returning
// SLS_ERROR_UNSUPPORTED, so the header and the exported symbols are the same in every build.
#include <cstddef>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "sdk/capi/capi_guard.h"
#include "sdk/capi/context_internal.h"
#include "sdk/capi/progress_callback.h"
#include "sdk/capi/versioned_struct.h"
#include "sdk/core/error.h"
#include "sls/sls_calibration.h"

#if defined(SLS_HAVE_CALIB)
#include <cmath>
#include <optional>
#include <utility>

#include <fmt/format.h>

#include "calib/board.h"
#include "calib/calibrate_capture.h"
#include "calib/multi_camera_calibration.h"
#include "sdk/core/calibration.h"
#include "sdk/core/progress.h"
#endif

namespace {

sls_calibration_config calibration_config_defaults() {
  sls_calibration_config config = sls::capi::zeroed<sls_calibration_config>();
  config.max_obliquity_deg = 65.0;
  config.min_projector_corner_fraction = 0.5;
  config.max_rms_px = 1.0;
  return config;
}

}  // namespace

extern "C" {

// The _init() functions work in every build: a program fills its structs the same way.

SLS_CAPI_DEFINE_INIT(sls_calibration_config, max_rms_px, calibration_config_defaults())

SLS_CAPI_DEFINE_INIT(sls_calibration_summary, axis_point_err_um,
                     sls::capi::zeroed<sls_calibration_summary>())

SLS_CAPI_DEFINE_INIT(sls_intrinsics, p2, sls::capi::zeroed<sls_intrinsics>())

SLS_CAPI_DEFINE_INIT(sls_calibration_view, decoded_fraction,
                     sls::capi::zeroed<sls_calibration_view>())

SLS_CAPI_DEFINE_INIT(sls_calibration_camera, camera_camera_rotation_err_deg,
                     sls::capi::zeroed<sls_calibration_camera>())

}  // extern "C"

#if defined(SLS_HAVE_CALIB)

struct sls_calibration {
  sls::calib::CalibrateCaptureResult result;  // of a head: camera 0's (every getter's but the cameras')
  std::optional<sls::calib::MultiCameraCalibrateResult> head;
  double max_rms_px = 1.0;
  std::vector<std::string> rejected_reasons;  // per view: the solve's reason, else the observation's
};

namespace {

constexpr std::size_t kConfigFirstVersionSize = offsetof(sls_calibration_config, max_rms_px) + sizeof(double);
constexpr std::size_t kSummaryFirstVersionSize =
    offsetof(sls_calibration_summary, axis_point_err_um) + sizeof(double);
constexpr std::size_t kIntrinsicsFirstVersionSize = offsetof(sls_intrinsics, p2) + sizeof(double);
constexpr std::size_t kViewFirstVersionSize = offsetof(sls_calibration_view, decoded_fraction) + sizeof(double);
constexpr std::size_t kCameraFirstVersionSize =
    offsetof(sls_calibration_camera, camera_camera_rotation_err_deg) + sizeof(double);

// The fields appended in 0.10 start past the first version's structs, padding included
// (versioned_struct.h): an older caller's struct never reaches them and means a chessboard.
static_assert(offsetof(sls_calibration_config, board_kind) >=
                  sls::capi::size_ending_at<sls_calibration_config>(kConfigFirstVersionSize),
              "board_kind lies in the padding of the first config");
static_assert(offsetof(sls_calibration_summary, board_kind) >=
                  sls::capi::size_ending_at<sls_calibration_summary>(kSummaryFirstVersionSize),
              "board_kind lies in the padding of the first summary");

void copy_matrix(const sls::Pose& pose, double out[16]) {
  const Eigen::Matrix4d T = pose.matrix();
  for (int row = 0; row < 4; ++row) {
    for (int column = 0; column < 4; ++column) out[4 * row + column] = T(row, column);
  }
}

// The board the config describes, each fault naming its field; or, all three of its sizes 0,
// none (inner corners and square 0): the whole board, kind included, from a simulated capture's
// ground truth (groundtruth/board.json).
sls::calib::BoardSpec config_board(const sls_calibration_config& config) {
  const long long kind = sls::capi::c_enum_value(config.board_kind);
  if (kind != SLS_CALIBRATION_BOARD_CHESSBOARD && kind != SLS_CALIBRATION_BOARD_CHARUCO) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.board_kind {} is not an sls_calibration_board_kind (SLS_CALIBRATION_BOARD_CHESSBOARD or "
                     "SLS_CALIBRATION_BOARD_CHARUCO)",
                     kind);
  }
  const bool charuco = kind == SLS_CALIBRATION_BOARD_CHARUCO;
  const bool dictionary_given = config.board_dictionary != nullptr && config.board_dictionary[0] != '\0';
  const std::string dictionary = dictionary_given ? config.board_dictionary : "";
  const bool board_automatic =
      config.board_inner_cols == 0 && config.board_inner_rows == 0 && config.board_square_m == 0.0;
  const bool board_given = config.board_inner_cols > 0 && config.board_inner_rows > 0 &&
                           config.board_square_m > 0.0 && std::isfinite(config.board_square_m);
  if (!board_automatic && !board_given) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.board_inner_cols {}, board_inner_rows {}, board_square_m {} (all three 0: from a "
                     "simulated capture's ground truth, or all three positive)",
                     config.board_inner_cols, config.board_inner_rows, config.board_square_m);
  }
  if (board_automatic) {
    if (charuco || config.board_marker_m != 0.0 || dictionary_given) {
      sls::throw_error(sls::ErrorCode::kInvalidArgument,
                       "config.board_kind {}, board_marker_m {}, board_dictionary '{}' with board_inner_cols, "
                       "board_inner_rows and board_square_m all 0: the whole board, its kind included, comes from a "
                       "simulated capture's ground truth (describe the board to give its kind)",
                       kind, config.board_marker_m, dictionary);
    }
    return {0, 0, 0.0};
  }
  sls::calib::BoardSpec board{config.board_inner_cols, config.board_inner_rows, config.board_square_m};
  if (!charuco) {
    if (config.board_marker_m != 0.0 || dictionary_given) {
      sls::throw_error(sls::ErrorCode::kInvalidArgument,
                       "config.board_marker_m {} and board_dictionary '{}' describe a ChArUco board, but "
                       "config.board_kind is SLS_CALIBRATION_BOARD_CHESSBOARD",
                       config.board_marker_m, dictionary);
    }
    return board;
  }
  board.kind = sls::calib::BoardKind::kCharuco;
  if (board.inner_cols < 3 || board.inner_rows < 3 || board.inner_cols > 100 || board.inner_rows > 100) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.board_inner_cols {}, board_inner_rows {}: a ChArUco board of {}x{} squares (its inner "
                     "corners are its squares less one each way; it needs 4..101 squares each way)",
                     board.inner_cols, board.inner_rows, board.inner_cols + 1, board.inner_rows + 1);
  }
  if (!(config.board_marker_m > 0.0) || !std::isfinite(config.board_marker_m)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.board_marker_m {} (a ChArUco board's marker side in metres, positive)",
                     config.board_marker_m);
  }
  if (config.board_marker_m >= config.board_square_m) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument,
                     "config.board_marker_m {} m must be smaller than config.board_square_m {} m (a marker sits "
                     "inside its square)",
                     config.board_marker_m, config.board_square_m);
  }
  board.marker_m = config.board_marker_m;
  // What is left to refuse is the dictionary's: unknown, or with fewer markers than the board
  // has light squares.
  try {
    if (dictionary_given) board.dictionary = sls::calib::charuco_dictionary_name(dictionary);
    board.validate();
  } catch (const sls::Error& error) {
    throw sls::Error(error.code(), fmt::format("config.board_dictionary '{}': {}",
                                              dictionary_given ? dictionary : board.dictionary, error.what()));
  }
  return board;
}

sls::calib::CalibrateCaptureOptions capture_options(const sls_calibration_config& config, const std::string& input,
                                                    const sls::Device& device) {
  sls::calib::CalibrateCaptureOptions options;
  options.input = input;
  if (config.pattern_set != nullptr) options.patterns = config.pattern_set;
  options.board = config_board(config);
  options.estimate_k3 = config.estimate_k3 != 0;
  if (!(config.max_obliquity_deg > 0.0 && config.max_obliquity_deg <= 90.0)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.max_obliquity_deg {} (degrees, in (0, 90])",
                     config.max_obliquity_deg);
  }
  options.max_obliquity_deg = config.max_obliquity_deg;
  if (!(config.min_projector_corner_fraction >= 0.0 && config.min_projector_corner_fraction <= 1.0)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.min_projector_corner_fraction {} (in [0, 1])",
                     config.min_projector_corner_fraction);
  }
  options.min_projector_corner_fraction = config.min_projector_corner_fraction;
  if (!(config.max_rms_px > 0.0)) {
    sls::throw_error(sls::ErrorCode::kInvalidArgument, "config.max_rms_px {} (pixels, positive)", config.max_rms_px);
  }
  options.device = device;
  return options;
}

std::vector<std::string> rejected_reasons(const sls::calib::CalibrateCaptureResult& result) {
  std::vector<std::string> reasons;
  for (std::size_t i = 0; i < result.views.size(); ++i) {
    const bool used = i < result.procam.views.size() && result.procam.views[i].used;
    std::string reason;
    if (!used) {
      if (i < result.procam.views.size()) reason = result.procam.views[i].rejected_reason;
      if (reason.empty()) reason = result.views[i].rejected_reason;
      if (reason.empty()) reason = "not used by the solve";
    }
    reasons.push_back(std::move(reason));
  }
  return reasons;
}

sls_intrinsics to_c(const sls::CameraIntrinsics& lens) {
  sls_intrinsics out;
  sls_intrinsics_init(&out);
  out.width = lens.width;
  out.height = lens.height;
  out.fx = lens.fx;
  out.fy = lens.fy;
  out.cx = lens.cx;
  out.cy = lens.cy;
  out.k1 = lens.k1;
  out.k2 = lens.k2;
  out.k3 = lens.k3;
  out.p1 = lens.p1;
  out.p2 = lens.p2;
  return out;
}

const char* const kNoResult = "calibration is NULL";

}  // namespace

extern "C" {

SLS_API sls_status sls_calibration_run(sls_context* context, const char* input_path,
                                       const sls_calibration_config* config,
                                       sls_calibration_progress_callback progress, void* user,
                                       sls_calibration** calibration, sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, "calibration (the output pointer) is NULL");
  *calibration = nullptr;
  SLS_CAPI_REQUIRE(context != nullptr, error, "context is NULL");
  SLS_CAPI_REQUIRE(input_path != nullptr, error, "input_path is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    sls_calibration_config defaults;
    sls_calibration_config_init(&defaults);
    const sls_calibration_config resolved =
        config == nullptr
            ? defaults
            : sls::capi::read_versioned(config, defaults, kConfigFirstVersionSize, "sls_calibration_config");
    const sls::calib::CalibrateCaptureOptions options = capture_options(resolved, input_path, context->device);
    auto made = std::make_unique<sls_calibration>();
    // The header promises stage "calibrate" only (one report per view, then "solve"): the
    // solve's own steps and the camera pairs, which `sls calibrate` shows, are not passed on.
    const sls::ProgressCallback caller = sls::capi::progress_callback(progress, user);
    const sls::ProgressCallback views_only = [&caller](const sls::ProgressUpdate& update) {
      return !caller || update.stage != "calibrate" || caller(update);
    };
    if (sls::calib::is_multi_camera_capture(options.input)) {
      made->head = sls::calib::calibrate_multi_camera_capture(options, views_only);
      made->result = made->head->cameras.front();
    } else {
      made->result = sls::calib::calibrate_capture(options, views_only);
    }
    made->max_rms_px = resolved.max_rms_px;
    made->rejected_reasons = rejected_reasons(made->result);
    *calibration = made.release();
  });
}

SLS_API void sls_calibration_destroy(sls_calibration* calibration) { delete calibration; }

SLS_API sls_status sls_calibration_get_summary(const sls_calibration* calibration, sls_calibration_summary* summary,
                                               sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(summary != nullptr, error, "summary (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::calib::CalibrateCaptureResult& result = calibration->result;
    const sls::calib::ProcamCalibration& procam = result.procam;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    sls_calibration_summary filled;
    sls_calibration_summary_init(&filled);
    filled.camera_rms_px = procam.camera_rms_px;
    filled.projector_rms_px = procam.projector_rms_px;
    filled.stereo_rms_px = procam.stereo_rms_px;
    filled.joint_camera_rms_px = procam.joint_camera_rms_px;
    filled.joint_projector_rms_px = procam.joint_projector_rms_px;
    filled.views_total = result.views.size();
    filled.views_used = static_cast<std::size_t>(procam.views_used);
    filled.views_rejected = filled.views_total - filled.views_used;
    filled.camera_outliers = static_cast<std::size_t>(procam.camera_outliers);
    filled.projector_outliers = static_cast<std::size_t>(procam.projector_outliers);
    filled.turntable_axis_fitted = result.axis.fitted ? 1 : 0;
    filled.turntable_axis_rms_px = result.axis.fitted ? result.axis.rms_px : 0.0;
    filled.seconds = result.seconds;
    filled.board_inner_cols = result.board.inner_cols;
    filled.board_inner_rows = result.board.inner_rows;
    filled.board_square_m = result.board.square_m;
    filled.pattern_set = result.pattern_set_name.c_str();
    const bool charuco = result.board.is_charuco();
    filled.board_kind = charuco ? SLS_CALIBRATION_BOARD_CHARUCO : SLS_CALIBRATION_BOARD_CHESSBOARD;
    filled.board_marker_m = charuco ? result.board.marker_m : 0.0;
    filled.board_dictionary = charuco ? result.board.dictionary.c_str() : "";
    filled.has_truth = result.errors.has_value() ? 1 : 0;
    filled.focal_rel_err = result.errors ? result.errors->focal_rel_err() : nan;
    filled.principal_point_err_px = result.errors ? result.errors->principal_point_err_px() : nan;
    filled.baseline_rel_err = result.errors ? result.errors->baseline_rel_err : nan;
    filled.rotation_err_deg = result.errors ? result.errors->rotation_err_deg : nan;
    filled.axis_direction_err_deg = result.errors ? result.errors->axis_direction_err_deg.value_or(nan) : nan;
    filled.axis_point_err_um = result.errors ? result.errors->axis_point_err_um.value_or(nan) : nan;
    sls::capi::write_versioned(filled, summary, kSummaryFirstVersionSize, "sls_calibration_summary");
  });
}

SLS_API sls_status sls_calibration_get_intrinsics(const sls_calibration* calibration, sls_calibration_device device,
                                                  sls_intrinsics* intrinsics, sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(intrinsics != nullptr, error, "intrinsics (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::ScannerCalibration& scanner = calibration->result.procam.calibration;
    const long long which = sls::capi::c_enum_value(device);
    if (which != SLS_CALIBRATION_CAMERA && which != SLS_CALIBRATION_PROJECTOR) {
      sls::throw_error(sls::ErrorCode::kInvalidArgument,
                       "device {} is not an sls_calibration_device (SLS_CALIBRATION_CAMERA or "
                       "SLS_CALIBRATION_PROJECTOR)",
                       which);
    }
    const sls_intrinsics lens = to_c(which == SLS_CALIBRATION_CAMERA ? scanner.camera : scanner.projector);
    sls::capi::write_versioned(lens, intrinsics, kIntrinsicsFirstVersionSize, "sls_intrinsics");
  });
}

SLS_API sls_status sls_calibration_get_extrinsics(const sls_calibration* calibration, double T_camera_projector[16],
                                                  sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(T_camera_projector != nullptr, error, "T_camera_projector (the output array) is NULL");
  return sls::capi::guarded(__func__, error,
                            [&] { copy_matrix(calibration->result.procam.calibration.T_camera_projector, T_camera_projector); });
}

SLS_API sls_status sls_calibration_get_turntable_axis(const sls_calibration* calibration, double point[3],
                                                      double direction[3], sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(point != nullptr, error, "point (the output array) is NULL");
  SLS_CAPI_REQUIRE(direction != nullptr, error, "direction (the output array) is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::calib::AxisFit& fit = calibration->result.axis;
    if (!fit.fitted) {
      sls::throw_error(sls::ErrorCode::kNotFound, "no turntable axis was fitted: {}",
                       fit.reason.empty() ? std::string("the capture has no turntable views") : fit.reason);
    }
    for (int i = 0; i < 3; ++i) {
      point[i] = fit.axis.point_camera[i];
      direction[i] = fit.axis.direction_camera[i];
    }
  });
}

SLS_API sls_status sls_calibration_view_count(const sls_calibration* calibration, size_t* count, sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(count != nullptr, error, "count (the output pointer) is NULL");
  *count = calibration->result.views.size();
  return SLS_OK;
}

SLS_API sls_status sls_calibration_get_view(const sls_calibration* calibration, size_t index,
                                            sls_calibration_view* view, sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(view != nullptr, error, "view (the output pointer) is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const sls::calib::CalibrateCaptureResult& result = calibration->result;
    if (index >= result.views.size()) {
      sls::throw_error(sls::ErrorCode::kInvalidArgument, "view index {} out of range (the calibration has {} views)",
                       index, result.views.size());
    }
    const sls::calib::ViewObservation& observation = result.views[index];
    sls_calibration_view filled;
    sls_calibration_view_init(&filled);
    filled.name = observation.name.c_str();
    filled.rejected_reason = calibration->rejected_reasons[index].c_str();
    filled.board_found = observation.board_found ? 1 : 0;
    filled.has_turntable_angle = observation.turntable_angle_deg.has_value() ? 1 : 0;
    filled.turntable_angle_deg = observation.turntable_angle_deg.value_or(0.0);
    if (index < result.procam.views.size()) {
      const sls::calib::ViewSolution& solution = result.procam.views[index];
      filled.used = solution.used ? 1 : 0;
      filled.camera_rms_px = solution.camera_rms_px;
      filled.projector_rms_px = solution.projector_rms_px;
      filled.obliquity_deg = solution.obliquity_deg;
    }
    filled.corners = static_cast<std::size_t>(result.board.corner_count());
    filled.projector_corners_valid = static_cast<std::size_t>(observation.projector.valid_count());
    filled.decoded_fraction = observation.decoded_fraction;
    sls::capi::write_versioned(filled, view, kViewFirstVersionSize, "sls_calibration_view");
  });
}

SLS_API sls_status sls_calibration_camera_count(const sls_calibration* calibration, size_t* count, sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(count != nullptr, error, "count (the output pointer) is NULL");
  *count = calibration->head ? calibration->head->cameras.size() : 1;
  return SLS_OK;
}

SLS_API sls_status sls_calibration_get_camera(const sls_calibration* calibration, size_t index,
                                              sls_calibration_camera* camera, sls_intrinsics* intrinsics,
                                              sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(camera != nullptr || intrinsics != nullptr, error,
                   "camera and intrinsics (the output pointers) are both NULL");
  return sls::capi::guarded(__func__, error, [&] {
    const std::size_t count = calibration->head ? calibration->head->cameras.size() : 1;
    if (index >= count) {
      sls::throw_error(sls::ErrorCode::kInvalidArgument, "camera index {} out of range (the head has {} camera{})",
                       index, count, count == 1 ? "" : "s");
    }
    const sls::calib::CalibrateCaptureResult& result =
        calibration->head ? calibration->head->cameras[index] : calibration->result;
    if (intrinsics != nullptr) {
      const sls_intrinsics lens = to_c(result.procam.calibration.camera);
      sls::capi::write_versioned(lens, intrinsics, kIntrinsicsFirstVersionSize, "sls_intrinsics");
    }
    if (camera == nullptr) return;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    sls_calibration_camera filled;
    sls_calibration_camera_init(&filled);
    filled.camera_rms_px = result.procam.camera_rms_px;
    filled.projector_rms_px = result.procam.projector_rms_px;
    filled.stereo_rms_px = result.procam.stereo_rms_px;
    filled.views_used = static_cast<std::size_t>(result.procam.views_used);
    copy_matrix(sls::Pose(), filled.T_camera0_camera);
    filled.camera_camera_baseline_rel_err = nan;
    filled.camera_camera_rotation_err_deg = nan;
    if (index > 0) {
      const sls::calib::CameraPairSolution& pair = calibration->head->pairs[index - 1];
      copy_matrix(pair.T_camera0_camera, filled.T_camera0_camera);
      filled.camera_camera_rms_px = pair.rms_px;
      filled.camera_camera_views = static_cast<std::size_t>(pair.views);
      if (index - 1 < calibration->head->pair_errors.size()) {
        filled.camera_camera_baseline_rel_err = calibration->head->pair_errors[index - 1].baseline_rel_err;
        filled.camera_camera_rotation_err_deg = calibration->head->pair_errors[index - 1].rotation_err_deg;
      }
    }
    filled.has_truth = result.errors.has_value() ? 1 : 0;
    filled.focal_rel_err = result.errors ? result.errors->camera_focal_rel_err : nan;
    filled.principal_point_err_px = result.errors ? result.errors->camera_principal_point_err_px : nan;
    sls::capi::write_versioned(filled, camera, kCameraFirstVersionSize, "sls_calibration_camera");
  });
}

SLS_API sls_status sls_calibration_write(const sls_calibration* calibration, const char* path, int force,
                                         sls_error** error) {
  SLS_CAPI_REQUIRE(calibration != nullptr, error, kNoResult);
  SLS_CAPI_REQUIRE(path != nullptr, error, "path is NULL");
  return sls::capi::guarded(__func__, error, [&] {
    // Every RMS the calibration is judged by: the stereo one, and a head's per camera and per pair.
    std::vector<std::pair<std::string, double>> judged = {{"the stereo RMS", calibration->result.procam.stereo_rms_px}};
    if (calibration->head) {
      const sls::calib::MultiCameraCalibrateResult& head = *calibration->head;
      for (std::size_t k = 1; k < head.cameras.size(); ++k) {
        judged.emplace_back(fmt::format("camera{}'s stereo RMS", k), head.cameras[k].procam.stereo_rms_px);
        judged.emplace_back(fmt::format("the camera{}-camera0 RMS", k), head.pairs[k - 1].rms_px);
      }
    }
    for (const auto& [what, rms] : judged) {
      if (force == 0 && !(rms <= calibration->max_rms_px)) {
        sls::throw_error(sls::ErrorCode::kInvalidArgument,
                         "{} not written: {} {:.3f} px is above max_rms_px {:.3f} px (pass force to write it anyway)",
                         path, what, rms, calibration->max_rms_px);
      }
    }
    sls::write_calibration(path, calibration->head ? calibration->head->calibration
                                                   : calibration->result.procam.calibration);
  });
}

}  // extern "C"

#else  // !SLS_HAVE_CALIB: calibration needs OpenCV; the same functions, each unsupported.

struct sls_calibration {
  int never_made;
};

namespace {

sls_status unsupported(const char* function, sls_error** error) {
  return sls::capi::report(SLS_ERROR_UNSUPPORTED, function, "built without OpenCV: calibration is not available",
                           error);
}

}  // namespace

extern "C" {

SLS_API sls_status sls_calibration_run(sls_context*, const char*, const sls_calibration_config*,
                                       sls_calibration_progress_callback, void*, sls_calibration** calibration,
                                       sls_error** error) {
  if (calibration != nullptr) *calibration = nullptr;
  return unsupported(__func__, error);
}

SLS_API void sls_calibration_destroy(sls_calibration* calibration) { delete calibration; }

SLS_API sls_status sls_calibration_get_summary(const sls_calibration*, sls_calibration_summary*, sls_error** error) {
  return unsupported(__func__, error);
}

SLS_API sls_status sls_calibration_get_intrinsics(const sls_calibration*, sls_calibration_device, sls_intrinsics*,
                                                  sls_error** error) {
  return unsupported(__func__, error);
}

SLS_API sls_status sls_calibration_get_extrinsics(const sls_calibration*, double*, sls_error** error) {
  return unsupported(__func__, error);
}

SLS_API sls_status sls_calibration_get_turntable_axis(const sls_calibration*, double*, double*, sls_error** error) {
  return unsupported(__func__, error);
}

SLS_API sls_status sls_calibration_view_count(const sls_calibration*, size_t* count, sls_error** error) {
  if (count != nullptr) *count = 0;
  return unsupported(__func__, error);
}

SLS_API sls_status sls_calibration_get_view(const sls_calibration*, size_t, sls_calibration_view*,
                                            sls_error** error) {
  return unsupported(__func__, error);
}

SLS_API sls_status sls_calibration_write(const sls_calibration*, const char*, int, sls_error** error) {
  return unsupported(__func__, error);
}

SLS_API sls_status sls_calibration_camera_count(const sls_calibration*, size_t* count, sls_error** error) {
  if (count != nullptr) *count = 0;
  return unsupported(__func__, error);
}

SLS_API sls_status sls_calibration_get_camera(const sls_calibration*, size_t, sls_calibration_camera*, sls_intrinsics*,
                                              sls_error** error) {
  return unsupported(__func__, error);
}

}  // extern "C"

#endif  // SLS_HAVE_CALIB
