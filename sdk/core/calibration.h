// Scanner calibration: camera and projector intrinsics (the projector is modelled as an
// inverse camera), their relative pose and, when calibrated, the turntable axis.
// Stored as OpenCV FileStorage YAML ("%YAML:1.0", !!opencv-matrix), readable by
// cv::FileStorage and by this SDK on machines without OpenCV. Lengths in metres.
#pragma once

#include <optional>
#include <string>
#include <vector>

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

// A camera of a multi-camera head other than the primary one (camera 0, `camera` below):
// its intrinsics and where it is relative to the primary camera. Everything that scans
// (decode, fusion, the session) uses the primary camera and the projector only; these are
// carried for the OEM's own use (e.g. a second triangulation, or checking the head's build).
struct AdditionalCamera {
  CameraIntrinsics intrinsics;
  Pose T_camera0_camera;  // this camera's frame -> the primary camera's frame
  double rms_px = -1.0;   // its own calibrateCamera RMS; < 0 if unknown
};

struct ScannerCalibration {
  // Additional cameras are optional keys of version 1 (an SDK that predates them reads such a
  // file's primary camera and projector, which is all that scans).
  static constexpr int kFormatVersion = 1;
  // More cameras than this in one head is a corrupt file, not a head.
  static constexpr int kMaxCameras = 16;

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
  // Cameras 1 .. N−1 of a head with N cameras (empty: one camera). File keys camera_count,
  // and per camera K: cameraK_width, cameraK_height, cameraK_matrix, cameraK_distortion,
  // T_camera0_cameraK (cameraK frame -> camera 0 frame, 4x4) and optionally cameraK_rms_px.
  std::vector<AdditionalCamera> additional_cameras;

  int camera_count() const { return 1 + static_cast<int>(additional_cameras.size()); }

  // Throws sls::Error (invalid argument) naming the first problem: non-positive image size
  // or focal length, principal point far outside the image, non-finite values, a zero axis,
  // a turntable angle or tilt σ negative, not finite or above TurntableAxis::kMaxSigmaDeg,
  // more than kMaxCameras cameras, an additional camera's bad intrinsics or non-finite pose.
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
