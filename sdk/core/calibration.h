// Scanner calibration: camera and projector intrinsics (the projector is modelled as an
// inverse camera), their relative pose and, when calibrated, the turntable axis.
// Stored as OpenCV FileStorage YAML ("%YAML:1.0", !!opencv-matrix), readable by
// cv::FileStorage and by this SDK on machines without OpenCV. Lengths in metres.
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/pose.h"

namespace sls {

// The turntable's rotation axis in the camera frame, and how well the table keeps to it.
struct TurntableAxis {
  // Largest σ accepted (degrees): worse is no measuring turntable, or a value not in degrees
  // (arcseconds, say).
  static constexpr double kMaxSigmaDeg = 1.0;

  Eigen::Vector3d point_camera = Eigen::Vector3d::Zero();       // a point on the axis (m)
  Eigen::Vector3d direction_camera = Eigen::Vector3d::UnitY();  // unit direction, right-handed turn
  // How well the table repeats, when known (degrees, per position: the difference of two
  // positions has √2 σ): angle_sigma_deg, the σ of its true angle about the recorded one;
  // tilt_sigma_deg, the σ of its turn about each axis perpendicular to its own (wobble: the
  // table turns about nothing but its axis to this). `sls calibrate` measures both from the
  // board's poses at the recorded angles (upper bounds: the board poses' own noise is in them;
  // calib/turntable_axis.h); the simulator's exact calibration carries its jitter and its zero
  // wobble. The turntable prior weighs the table's motion by them (fusion/pose_prior.h). File
  // keys turntable_angle_sigma_deg and turntable_tilt_sigma_deg, optional; finite,
  // 0 .. kMaxSigmaDeg.
  std::optional<double> angle_sigma_deg = std::nullopt;
  std::optional<double> tilt_sigma_deg = std::nullopt;
};

struct ScannerCalibration {
  static constexpr int kFormatVersion = 1;

  CameraIntrinsics camera;
  CameraIntrinsics projector;
  Pose T_camera_projector;  // projector frame -> camera frame
  std::optional<TurntableAxis> turntable;
  double reprojection_rms_px = -1.0;  // from the calibration that produced it (the joint,
                                      // stereo RMS of `sls calibrate`); < 0 if unknown
  double camera_rms_px = -1.0;        // the camera's and the projector's own RMS; < 0 if unknown
  double projector_rms_px = -1.0;
  std::string calibrated_utc;         // ISO 8601 time of the calibration; empty if unknown
  std::string description;            // free text: rig name, date, tool

  // Throws sls::Error (invalid argument) naming the first problem: non-positive image size
  // or focal length, principal point far outside the image, non-finite values, a zero axis,
  // a turntable angle or tilt σ negative, not finite or above TurntableAxis::kMaxSigmaDeg.
  void validate() const;
};

// Writes the calibration; throws sls::Error (I/O) naming the path on failure. The file is
// written to a temporary name and renamed, so a crash never leaves half a calibration.
void write_calibration(const std::string& path, const ScannerCalibration& calibration);

// Reads and validates a calibration; throws sls::Error naming the file and the problem
// (missing key, wrong matrix size, unparsable YAML with its line, invalid values).
ScannerCalibration read_calibration(const std::string& path);
// The same from a file's text; `path` only names it in errors.
ScannerCalibration parse_calibration(const std::string& text, const std::string& path);

}  // namespace sls
