// Calibration files are OpenCV FileStorage YAML: what we write, cv::FileStorage reads; what
// cv::FileStorage writes (with its own layout, quoting and number format), we read.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "calib/opencv_conversions.h"
#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

std::uint64_t bits(double value) {
  std::uint64_t out;
  std::memcpy(&out, &value, sizeof out);
  return out;
}

// The real rig of shared/data/procam-calibration: its camera, projector and their pose (the
// file's "roration"/"translation", in millimetres), plus a made-up turntable axis.
ScannerCalibration real_procam_calibration() {
  const std::string path = test::shared_data_path("procam-calibration/calibration_result.xml");
  cv::FileStorage storage(path, cv::FileStorage::READ);
  if (!storage.isOpened()) throw std::runtime_error("cannot open " + path);
  auto intrinsics = [&](const char* matrix_key, const char* distortion_key, int width, int height) {
    cv::Mat k, d;
    storage[matrix_key] >> k;
    storage[distortion_key] >> d;
    return calib::intrinsics_from(k, d, width, height);
  };
  ScannerCalibration c;
  c.camera = intrinsics("cam_int", "cam_dist", 1280, 1024);
  c.projector = intrinsics("proj_int", "proj_dist", 1024, 768);
  cv::Mat r, t;
  storage["roration"] >> r;
  storage["translation"] >> t;
  Eigen::Matrix3d rotation;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) rotation(i, j) = r.at<double>(i, j);
  }
  c.T_camera_projector =
      Pose(rotation, Eigen::Vector3d(t.at<double>(0), t.at<double>(1), t.at<double>(2)) / 1000.0);
  c.turntable = TurntableAxis{Eigen::Vector3d(0.01, -0.02, 0.45), Eigen::Vector3d(0.02, 1.0, -0.03).normalized()};
  storage["rms"] >> c.reprojection_rms_px;
  c.description = "procam-calibration \"real\" rig: 9x7 board, C:\\data\\capture_0";
  return c;
}

cv::Mat camera_matrix(const CameraIntrinsics& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
}
cv::Mat distortion(const CameraIntrinsics& c) { return (cv::Mat_<double>(1, 5) << c.k1, c.k2, c.p1, c.p2, c.k3); }

cv::Mat to_mat(const Eigen::Matrix4d& m) {
  cv::Mat out(4, 4, CV_64F);
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) out.at<double>(i, j) = m(i, j);
  }
  return out;
}
cv::Mat to_mat(const Eigen::Vector3d& v) { return (cv::Mat_<double>(3, 1) << v.x(), v.y(), v.z()); }

void expect_mat_bit_exact(const cv::Mat& actual, const cv::Mat& expected, const std::string& key) {
  ASSERT_EQ(actual.type(), CV_64F) << key;
  ASSERT_EQ(actual.rows, expected.rows) << key;
  ASSERT_EQ(actual.cols, expected.cols) << key;
  for (int i = 0; i < expected.rows; ++i) {
    for (int j = 0; j < expected.cols; ++j) {
      EXPECT_EQ(bits(actual.at<double>(i, j)), bits(expected.at<double>(i, j)))
          << key << "(" << i << "," << j << "): " << actual.at<double>(i, j) << " vs " << expected.at<double>(i, j);
    }
  }
}

TEST(CalibrationOpenCv, OpenCvReadsWhatWeWrite) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("calibration.yml");
  const ScannerCalibration calibration = real_procam_calibration();
  write_calibration(path, calibration);

  cv::FileStorage storage(path, cv::FileStorage::READ);
  ASSERT_TRUE(storage.isOpened());
  EXPECT_EQ(static_cast<int>(storage["slscan_calibration_version"]), ScannerCalibration::kFormatVersion);
  EXPECT_EQ(static_cast<std::string>(storage["description"]), calibration.description);
  EXPECT_EQ(static_cast<int>(storage["camera_width"]), 1280);
  EXPECT_EQ(static_cast<int>(storage["camera_height"]), 1024);
  EXPECT_EQ(static_cast<int>(storage["projector_width"]), 1024);
  EXPECT_EQ(static_cast<int>(storage["projector_height"]), 768);
  cv::Mat m;
  storage["camera_matrix"] >> m;
  expect_mat_bit_exact(m, camera_matrix(calibration.camera), "camera_matrix");
  storage["camera_distortion"] >> m;
  expect_mat_bit_exact(m, distortion(calibration.camera), "camera_distortion");
  storage["projector_matrix"] >> m;
  expect_mat_bit_exact(m, camera_matrix(calibration.projector), "projector_matrix");
  storage["projector_distortion"] >> m;
  expect_mat_bit_exact(m, distortion(calibration.projector), "projector_distortion");
  storage["T_camera_projector"] >> m;
  expect_mat_bit_exact(m, to_mat(calibration.T_camera_projector.matrix()), "T_camera_projector");
  storage["turntable_axis_point"] >> m;
  expect_mat_bit_exact(m, to_mat(calibration.turntable->point_camera), "turntable_axis_point");
  storage["turntable_axis_direction"] >> m;
  expect_mat_bit_exact(m, to_mat(calibration.turntable->direction_camera), "turntable_axis_direction");
  EXPECT_EQ(bits(static_cast<double>(storage["reprojection_rms_px"])), bits(calibration.reprojection_rms_px));
}

TEST(CalibrationOpenCv, WeReadWhatOpenCvWrites) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("from_opencv.yml");
  const ScannerCalibration calibration = real_procam_calibration();
  {
    cv::FileStorage storage(path, cv::FileStorage::WRITE);
    ASSERT_TRUE(storage.isOpened());
    storage << "slscan_calibration_version" << 1;
    storage << "description" << calibration.description;
    storage << "camera_width" << calibration.camera.width << "camera_height" << calibration.camera.height;
    storage << "camera_matrix" << camera_matrix(calibration.camera);
    storage << "camera_distortion" << distortion(calibration.camera);
    storage << "projector_width" << calibration.projector.width;
    storage << "projector_height" << calibration.projector.height;
    storage << "projector_matrix" << camera_matrix(calibration.projector);
    // A column vector, as some tools store distortion.
    storage << "projector_distortion" << distortion(calibration.projector).t();
    storage << "T_camera_projector" << to_mat(calibration.T_camera_projector.matrix());
    storage << "turntable_axis_point" << to_mat(calibration.turntable->point_camera);
    storage << "turntable_axis_direction" << to_mat(calibration.turntable->direction_camera).t();
    storage << "reprojection_rms_px" << calibration.reprojection_rms_px;
    storage << "unknown_extra_key" << "ignored";
  }
  const std::string text = read_file_text(path);
  ASSERT_EQ(text.rfind("%YAML:1.0", 0), 0u) << text;

  const ScannerCalibration read = read_calibration(path);
  const double written[] = {calibration.camera.fx, calibration.camera.fy, calibration.camera.cx,
                            calibration.camera.cy, calibration.camera.k1, calibration.camera.k2,
                            calibration.camera.k3, calibration.camera.p1, calibration.camera.p2,
                            calibration.projector.fx, calibration.projector.fy, calibration.projector.cx,
                            calibration.projector.cy, calibration.projector.k1, calibration.projector.k2,
                            calibration.projector.k3, calibration.projector.p1, calibration.projector.p2,
                            calibration.reprojection_rms_px};
  const double parsed[] = {read.camera.fx, read.camera.fy, read.camera.cx, read.camera.cy, read.camera.k1,
                           read.camera.k2, read.camera.k3, read.camera.p1, read.camera.p2, read.projector.fx,
                           read.projector.fy, read.projector.cx, read.projector.cy, read.projector.k1,
                           read.projector.k2, read.projector.k3, read.projector.p1, read.projector.p2,
                           read.reprojection_rms_px};
  // OpenCV prints "%.16e": 17 significant digits, so every double comes back exactly.
  for (std::size_t i = 0; i < std::size(written); ++i) EXPECT_EQ(bits(parsed[i]), bits(written[i])) << i;
  EXPECT_EQ(read.camera.width, 1280);
  EXPECT_EQ(read.projector.height, 768);
  EXPECT_EQ(read.description, calibration.description);
  EXPECT_LE((read.T_camera_projector.matrix() - calibration.T_camera_projector.matrix()).cwiseAbs().maxCoeff(),
            1e-15);
  ASSERT_TRUE(read.turntable.has_value());
  EXPECT_EQ(read.turntable->point_camera, calibration.turntable->point_camera);
  EXPECT_EQ(read.turntable->direction_camera, calibration.turntable->direction_camera);
}

TEST(CalibrationOpenCv, OpenCvReadsOurEscapedStrings) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("calibration.yml");
  ScannerCalibration calibration = real_procam_calibration();
  for (const std::string& description :
       {std::string(""), std::string("plain"), std::string("tab\there, new\nline, quote \" and backslash \\"),
        std::string("UTF-8: 10×8×6 mm, 5.7 µm # not a comment: [not, a, list]")}) {
    calibration.description = description;
    write_calibration(path, calibration);
    cv::FileStorage storage(path, cv::FileStorage::READ);
    ASSERT_TRUE(storage.isOpened());
    EXPECT_EQ(static_cast<std::string>(storage["description"]), description);
    EXPECT_EQ(read_calibration(path).description, description);
  }
}

// cv::FileStorage reading errors are not our business, but ours must name the key when a
// file from OpenCV lacks one.
TEST(CalibrationOpenCv, OpenCvFileWithMissingKeyNamesIt) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("partial.yml");
  {
    cv::FileStorage storage(path, cv::FileStorage::WRITE);
    storage << "slscan_calibration_version" << 1 << "camera_width" << 1280 << "camera_height" << 1024;
  }
  try {
    read_calibration(path);
    FAIL() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kFormat);
    EXPECT_NE(std::string(error.what()).find("key 'camera_matrix'"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace sls
