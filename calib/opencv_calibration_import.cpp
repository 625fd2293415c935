#include "calib/opencv_calibration_import.h"

#include <cmath>
#include <filesystem>
#include <initializer_list>
#include <vector>

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "calib/opencv_conversions.h"
#include "sdk/core/error.h"

namespace sls::calib {
namespace {

using Keys = std::initializer_list<const char*>;

const Keys kCameraMatrix = {"cam_int", "camera_matrix", "cam_K", "camera_K", "K1", "M1", "K", "KK", "cameraMatrix"};
const Keys kCameraDistortion = {"cam_dist", "camera_distortion", "dist_coeffs", "distortion_coefficients",
                                "cam_kc",   "D1",                "dist",        "distCoeffs"};
const Keys kProjectorMatrix = {"proj_int", "projector_matrix", "proj_K", "projector_K", "K2", "M2"};
const Keys kProjectorDistortion = {"proj_dist", "projector_distortion", "proj_kc", "D2"};
const Keys kRotation = {"R", "rotation", "roration", "R_cam_proj"};
const Keys kTranslation = {"T", "translation", "T_cam_proj"};

std::string list(Keys keys) {
  std::string out;
  for (const char* key : keys) out += std::string(out.empty() ? "" : ", ") + key;
  return out;
}

class File {
 public:
  File(const std::string& path) : path_(path) {
    try {
      storage_.open(path, cv::FileStorage::READ);
    } catch (const cv::Exception& error) {
      throw_error(ErrorCode::kFormat, "{}: not a readable OpenCV YAML/XML calibration: {}", path, error.what());
    }
    if (!storage_.isOpened()) {
      throw_error(ErrorCode::kFormat, "{}: not a readable OpenCV YAML/XML calibration", path);
    }
  }

  // The first key of `keys` present, as a double matrix; empty when none is.
  cv::Mat matrix(Keys keys, std::string* found) {
    for (const char* key : keys) {
      const cv::FileNode node = storage_[key];
      if (node.empty() || node.isNone()) continue;
      cv::Mat m;
      try {
        if (node.isSeq()) {
          std::vector<double> values;
          node >> values;
          m = cv::Mat(values, true);
        } else if (node.isReal() || node.isInt()) {
          m = cv::Mat(1, 1, CV_64F, cv::Scalar(static_cast<double>(node)));
        } else {
          node >> m;
        }
      } catch (const cv::Exception& error) {
        throw_error(ErrorCode::kFormat, "{}: \"{}\" is not a matrix: {}", path_, key, error.what());
      }
      if (m.empty()) throw_error(ErrorCode::kFormat, "{}: \"{}\" is empty or not a matrix", path_, key);
      m.convertTo(m, CV_64F);
      *found = key;
      return m;
    }
    return {};
  }

  cv::Mat required(Keys keys, const char* what, std::string* found) {
    cv::Mat m = matrix(keys, found);
    if (m.empty()) throw_error(ErrorCode::kFormat, "{}: no {} (looked for {})", path_, what, list(keys));
    return m;
  }

  double number(const char* key) {
    const cv::FileNode node = storage_[key];
    return node.isReal() || node.isInt() ? static_cast<double>(node) : 0.0;
  }

  const std::string& path() const { return path_; }

 private:
  std::string path_;
  cv::FileStorage storage_;
};

// A size from (rows, cols) or (width, height) keys, or a width + height pair.
bool read_size(File& file, Keys rows_cols, Keys width_height, const char* width_key, const char* height_key,
               int* width, int* height) {
  std::string key;
  cv::Mat m = file.matrix(rows_cols, &key);
  bool swap = true;
  if (m.empty()) {
    m = file.matrix(width_height, &key);
    swap = false;
  }
  if (!m.empty()) {
    if (m.total() < 2) throw_error(ErrorCode::kFormat, "{}: \"{}\" does not hold two sizes", file.path(), key);
    const double a = m.at<double>(0), b = m.at<double>(1);
    *width = static_cast<int>(std::lround(swap ? b : a));
    *height = static_cast<int>(std::lround(swap ? a : b));
    return true;
  }
  const double w = file.number(width_key), h = file.number(height_key);
  if (w > 0.0 && h > 0.0) {
    *width = static_cast<int>(std::lround(w));
    *height = static_cast<int>(std::lround(h));
    return true;
  }
  return false;
}

CameraIntrinsics intrinsics(const std::string& path, const cv::Mat& k, const cv::Mat& d, const std::string& k_key,
                            const std::string& d_key, int width, int height) {
  if (k.rows != 3 || k.cols != 3) {
    throw_error(ErrorCode::kFormat, "{}: \"{}\" is {}x{}, a camera matrix is 3x3", path, k_key, k.rows, k.cols);
  }
  if (std::fabs(k.at<double>(0, 1)) > 1e-9 * std::fabs(k.at<double>(0, 0))) {
    throw_error(ErrorCode::kFormat, "{}: \"{}\" has a skew of {}: not supported by slscan's camera model", path,
                k_key, k.at<double>(0, 1));
  }
  if (d.empty()) return intrinsics_from(k, cv::Mat::zeros(1, 5, CV_64F), width, height);
  const cv::Mat flat = d.reshape(1, 1);
  if (flat.cols < 4) {
    throw_error(ErrorCode::kFormat, "{}: \"{}\" holds {} coefficients (OpenCV's order k1 k2 p1 p2 [k3 ...])", path,
                d_key, flat.cols);
  }
  for (int i = 5; i < flat.cols; ++i) {
    if (flat.at<double>(i) != 0.0) {
      throw_error(ErrorCode::kFormat,
                  "{}: \"{}\" coefficient {} is {}: the rational / thin-prism / tilted models are not supported "
                  "(slscan's model is k1 k2 p1 p2 k3)",
                  path, d_key, i, flat.at<double>(i));
    }
  }
  return intrinsics_from(k, flat, width, height);
}

}  // namespace

ImportedCalibration import_calibration(const std::string& path, const CalibrationImportOptions& options) {
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error)) {
    throw_error(ErrorCode::kNotFound, "calibration {}: no such file", path);
  }
  if (!(options.unit_m > 0.0) || !std::isfinite(options.unit_m)) {
    throw_error(ErrorCode::kInvalidArgument, "calibration unit {} m must be positive", options.unit_m);
  }
  ImportedCalibration out;
  File file(path);
  if (file.number("slscan_calibration_version") > 0.0) {
    out.calibration = read_calibration(path);
    out.layout = "slscan";
    return out;
  }
  std::string ck, cd, pk, pd, rk, tk;
  const cv::Mat camera_k = file.required(kCameraMatrix, "camera matrix", &ck);
  const cv::Mat camera_d = file.matrix(kCameraDistortion, &cd);
  const cv::Mat projector_k = file.required(kProjectorMatrix, "projector matrix", &pk);
  const cv::Mat projector_d = file.matrix(kProjectorDistortion, &pd);
  cv::Mat rotation = file.required(kRotation, "camera-to-projector rotation", &rk);
  const cv::Mat translation = file.required(kTranslation, "camera-to-projector translation", &tk);

  int camera_width = options.camera_width, camera_height = options.camera_height;
  int file_width = 0, file_height = 0;
  if (read_size(file, {"img_shape", "cam_shape"}, {"image_size", "imageSize", "camera_size"}, "image_width",
                "image_height", &file_width, &file_height)) {
    if (camera_width > 0 && (file_width != camera_width || file_height != camera_height)) {
      throw_error(ErrorCode::kInvalidArgument, "{}: calibrated for a {}x{} camera, the images are {}x{}", path,
                  file_width, file_height, camera_width, camera_height);
    }
    camera_width = file_width;
    camera_height = file_height;
  }
  int projector_width = options.projector_width, projector_height = options.projector_height;
  if (read_size(file, {"proj_shape"}, {"projector_size"}, "projector_width", "projector_height", &file_width,
                &file_height)) {
    if (projector_width > 0 && (file_width != projector_width || file_height != projector_height)) {
      throw_error(ErrorCode::kInvalidArgument,
                  "{}: calibrated for a {}x{} projector, the pattern description's is {}x{}", path, file_width,
                  file_height, projector_width, projector_height);
    }
    projector_width = file_width;
    projector_height = file_height;
  }
  if (camera_width <= 0 || projector_width <= 0) {
    throw_error(ErrorCode::kFormat, "{}: no {} size in the file and none given", path,
                camera_width <= 0 ? "camera" : "projector");
  }
  ScannerCalibration& c = out.calibration;
  c.camera = intrinsics(path, camera_k, camera_d, ck, cd, camera_width, camera_height);
  c.projector = intrinsics(path, projector_k, projector_d, pk, pd, projector_width, projector_height);
  if (rotation.total() == 3) {
    cv::Mat matrix;
    cv::Rodrigues(rotation.reshape(1, 3), matrix);
    rotation = matrix;
  }
  if (rotation.rows != 3 || rotation.cols != 3 || translation.total() != 3) {
    throw_error(ErrorCode::kFormat, "{}: \"{}\" is {}x{} and \"{}\" holds {} values (need 3x3 or 3, and 3)", path, rk,
                rotation.rows, rotation.cols, tk, translation.total());
  }
  Eigen::Matrix3d r;
  for (int i = 0; i < 9; ++i) r(i / 3, i % 3) = rotation.at<double>(i / 3, i % 3);
  if (!((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() < 1e-4) || !(r.determinant() > 0.0)) {
    throw_error(ErrorCode::kFormat, "{}: \"{}\" is not a rotation (R^T R != I or det < 0)", path, rk);
  }
  const Eigen::Vector3d t(translation.at<double>(0), translation.at<double>(1), translation.at<double>(2));
  // X_projector = R X_camera + T: that is T_projector_camera; slscan stores its inverse.
  c.T_camera_projector = Pose(Eigen::Quaterniond(r).normalized(), options.unit_m * t).inverse();
  const double rms = file.number("rms");
  if (rms > 0.0) c.reprojection_rms_px = rms;
  c.description = fmt::format("imported from {} ({}/{}/{}/{}/{}/{}; T in {} m)", path, ck, cd.empty() ? "-" : cd,
                              pk, pd.empty() ? "-" : pd, rk, tk, options.unit_m);
  out.layout = fmt::format("{}/{}/{}/{}/{}/{}", ck, cd.empty() ? "-" : cd, pk, pd.empty() ? "-" : pd, rk, tk);
  try {
    c.validate();
  } catch (const Error& e) {
    throw_error(ErrorCode::kFormat, "{}: {}", path, e.what());
  }
  return out;
}

}  // namespace sls::calib
