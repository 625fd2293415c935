// The whole calibration from a capture on disk (what `sls calibrate` and the C API run):
//   - a recording (sdk/core/recording.h) whose frames are board poses, frames with a
//     turntable angle also serving the axis (a simulated capture: `sls sim --calibration`);
//   - or a folder of captures, one subfolder per board pose (sorted by name), each holding
//     the pattern set's images in its order (PNG, files sorted by name), as
//     ../shared/data/procam-calibration. The set comes by name (`opencv-graycode:WxH`...).
// Views are loaded, decoded and observed one at a time (a 4000 x 3000 stack is ~1 GB), then
// camera, projector and extrinsics are solved, then the turntable axis when the views allow.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "calib/calibration_truth.h"
#include "calib/procam_calibration.h"
#include "calib/turntable_axis.h"
#include "calib/view_observation.h"
#include "sdk/core/device.h"
#include "sdk/core/progress.h"

namespace sls::calib {

struct CalibrateCaptureOptions {
  std::string input;     // recording or folder of captures
  std::string patterns;  // built-in name (pattern_set_from_name); empty: the recording's set
  // The board. inner_cols/rows 0 and square_m 0: from a simulated capture's
  // groundtruth/board.json; otherwise required.
  BoardSpec board{0, 0, 0.0};
  bool estimate_k3 = false;
  double max_obliquity_deg = 65.0;
  double min_projector_corner_fraction = 0.5;
  Device device = Device::cpu();  // decoding
};

struct CalibrateCaptureResult {
  std::string input_kind;        // "recording" or "folder"
  std::string pattern_set_name;
  BoardSpec board;
  int camera_bit_depth = 0;
  std::vector<ViewObservation> views;
  ProcamCalibration procam;      // procam.calibration carries the axis when fitted
  AxisFit axis;
  std::optional<ScannerCalibration> truth;     // a simulated capture's exact calibration
  std::optional<CalibrationErrors> errors;     // against it
  double seconds = 0.0;          // the whole run
  // Its parts (seconds, summed over views): reading the images, finding the boards, decoding,
  // the local homographies, the solve (camera, projector, joint, axis).
  double load_s = 0.0, detect_s = 0.0, decode_s = 0.0, homography_s = 0.0, solve_s = 0.0;
};

// Throws sls::Error: kNotFound / kFormat for unreadable input (naming the file), kInvalidArgument
// for a bad board, pattern set or too few usable views (naming each rejected view and why),
// kCancelled when progress asks to stop. Progress: stage "calibrate", one unit per view, the
// view's name as detail; then stage "solve", before each of its steps ("camera", "projector",
// "camera and projector", "turntable axis": done 0..3 of 4) and once done ("solved", 4 of 4).
CalibrateCaptureResult calibrate_capture(const CalibrateCaptureOptions& options, const ProgressCallback& progress);

}  // namespace sls::calib
