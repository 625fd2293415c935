// Calibrations made by other tools, read from OpenCV FileStorage (YAML or XML) into
// slscan's ScannerCalibration (`sls import --calibration`). OpenCV stays inside calib/.
//
// Field mapping (the first key found of each list; docs/import.md repeats it):
//   camera matrix K      cam_int, camera_matrix, cam_K, camera_K, K1, M1, K, KK, cameraMatrix
//   camera distortion    cam_dist, camera_distortion, dist_coeffs, distortion_coefficients,
//                        cam_kc, D1, dist, distCoeffs           (k1 k2 p1 p2 [k3]; rows or columns)
//   projector matrix     proj_int, projector_matrix, proj_K, projector_K, K2, M2
//   projector distortion proj_dist, projector_distortion, proj_kc, D2
//   rotation R           R, rotation, roration (sic, procam-calibration), R_cam_proj  (3x3, or a
//                        3-vector Rodrigues rotation)
//   translation T        T, translation, T_cam_proj
//   camera size          img_shape / cam_shape (rows, cols), image_size / imageSize /
//                        camera_size (width, height), image_width + image_height
//   projector size       proj_shape (rows, cols), projector_size (width, height),
//                        projector_width + projector_height; else the pattern description's
// R and T follow OpenCV's stereoCalibrate with the camera first: a point X in the camera
// frame is R X + T in the projector frame; T in `unit_m` metres per file unit. Distortion
// models beyond k1 k2 p1 p2 k3 (rational, thin prism, tilt) are refused unless their extra
// coefficients are zero. A file that is slscan's own calibration.yml is read as such.
#pragma once

#include <string>

#include "sdk/core/calibration.h"

namespace sls::calib {

struct CalibrationImportOptions {
  // Used when the file gives no size: the camera's from the images, the projector's from the
  // pattern description.
  int camera_width = 0;
  int camera_height = 0;
  int projector_width = 0;
  int projector_height = 0;
  double unit_m = 1e-3;  // metres per length unit of T in the file (1e-3: millimetres)
};

struct ImportedCalibration {
  ScannerCalibration calibration;
  std::string layout;  // "slscan" or the keys used, e.g. "cam_int/cam_dist/proj_int/proj_dist/roration/translation"
};

// Throws sls::Error: kNotFound (no file), kFormat naming the file and what is missing or
// malformed (the keys looked for), kInvalidArgument (sizes that contradict the options).
ImportedCalibration import_calibration(const std::string& path, const CalibrationImportOptions& options);

}  // namespace sls::calib
