// Calibration files (OpenCV FileStorage YAML): exact round trips, and every kind of broken
// file gives an error naming the file, the key and the problem. Reading files written by
// cv::FileStorage itself is in tests/interop/test_calibration_opencv.cpp.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <utility>

#include <fmt/format.h>
#include <gtest/gtest.h>

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

// Values with simple decimal forms, so tests can edit the file text.
ScannerCalibration simple_calibration() {
  ScannerCalibration c;
  c.camera.width = 1280;
  c.camera.height = 1024;
  c.camera.fx = 3452.5;
  c.camera.fy = 3449.75;
  c.camera.cx = 587.25;
  c.camera.cy = 521.5;
  c.camera.k1 = -0.25;
  c.camera.k2 = -0.875;
  c.camera.p1 = -0.0625;
  c.camera.p2 = 0.03125;
  c.camera.k3 = 3.125;
  c.projector.width = 1024;
  c.projector.height = 768;
  c.projector.fx = 3953.5;
  c.projector.fy = 3893.25;
  c.projector.cx = 737.125;
  c.projector.cy = 1357.75;
  c.projector.k1 = -0.015625;
  c.T_camera_projector = Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d(0.2, 1.0, 0.1).normalized())),
                              Eigen::Vector3d(0.085, -0.63, -0.1));
  c.reprojection_rms_px = 0.5;
  c.description = "test rig";
  return c;
}

// Awkward doubles (full 17 digits, tiny, negative zero) and an awkward description.
ScannerCalibration awkward_calibration() {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  ScannerCalibration c;
  c.camera.width = 4000;
  c.camera.height = 3000;
  c.camera.fx = 13000.0 + 100.0 * u(rng);
  c.camera.fy = 13000.0 + 100.0 * u(rng);
  c.camera.cx = 2000.0 + 30.0 * u(rng);
  c.camera.cy = 1500.0 + 30.0 * u(rng);
  c.camera.k1 = 0.3 * u(rng);
  c.camera.k2 = u(rng);
  c.camera.k3 = 5.0 * u(rng);
  c.camera.p1 = 1e-3 * u(rng);
  c.camera.p2 = -0.0;
  c.projector.width = 1920;
  c.projector.height = 1080;
  c.projector.fx = 2200.0 + u(rng);
  c.projector.fy = 2200.0 + u(rng);
  c.projector.cx = 960.0 + u(rng);
  c.projector.cy = 1080.0 + u(rng);
  c.projector.k1 = 1e-300 * u(rng);
  c.projector.k2 = 4.9406564584124654e-324;  // the smallest subnormal
  c.projector.p1 = 1e-17;
  c.T_camera_projector = Pose(Eigen::Quaterniond(0.9, 0.1 * u(rng), 0.2 * u(rng), 0.05).normalized(),
                              Eigen::Vector3d(0.1 * u(rng), 1e-9 * u(rng), -0.3));
  c.turntable = TurntableAxis{Eigen::Vector3d(0.01 * u(rng), -0.02, 0.35 + 0.01 * u(rng)),
                              Eigen::Vector3d(0.01 * u(rng), 1.0, 0.02 * u(rng)).normalized()};
  c.turntable->angle_sigma_deg = 0.0021 + 1e-4 * u(rng);
  c.turntable->tilt_sigma_deg = 3e-4 + 1e-5 * u(rng);
  c.reprojection_rms_px = 0.123456789012345678;
  c.description = "rig \"B\" \\ 2024-05-01: 10×8×6 mm µ-volume\n\tline two # not a comment";
  return c;
}

void expect_intrinsics_bit_exact(const CameraIntrinsics& a, const CameraIntrinsics& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  const double av[] = {a.fx, a.fy, a.cx, a.cy, a.k1, a.k2, a.k3, a.p1, a.p2};
  const double bv[] = {b.fx, b.fy, b.cx, b.cy, b.k1, b.k2, b.k3, b.p1, b.p2};
  for (int i = 0; i < 9; ++i) EXPECT_EQ(bits(av[i]), bits(bv[i])) << "field " << i << ": " << av[i] << " vs " << bv[i];
}

void expect_calibrations_equal(const ScannerCalibration& written, const ScannerCalibration& read) {
  expect_intrinsics_bit_exact(written.camera, read.camera);
  expect_intrinsics_bit_exact(written.projector, read.projector);
  // The file holds the 4x4 matrix; rebuilding the quaternion from it is exact to rounding.
  EXPECT_LE((written.T_camera_projector.matrix() - read.T_camera_projector.matrix()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(written.T_camera_projector.translation(), read.T_camera_projector.translation());
  ASSERT_EQ(written.turntable.has_value(), read.turntable.has_value());
  if (written.turntable) {
    EXPECT_EQ(written.turntable->point_camera, read.turntable->point_camera);
    EXPECT_EQ(written.turntable->direction_camera, read.turntable->direction_camera);
    for (const auto& [w, r] : {std::pair{written.turntable->angle_sigma_deg, read.turntable->angle_sigma_deg},
                               std::pair{written.turntable->tilt_sigma_deg, read.turntable->tilt_sigma_deg}}) {
      ASSERT_EQ(w.has_value(), r.has_value());
      if (w) {
        EXPECT_EQ(bits(*w), bits(*r));
      }
    }
  }
  EXPECT_EQ(bits(written.reprojection_rms_px), bits(read.reprojection_rms_px));
  EXPECT_EQ(written.description, read.description);
  ASSERT_EQ(written.camera_count(), read.camera_count());
  for (std::size_t i = 0; i < written.additional_cameras.size(); ++i) {
    const AdditionalCamera& w = written.additional_cameras[i];
    const AdditionalCamera& r = read.additional_cameras[i];
    expect_intrinsics_bit_exact(w.intrinsics, r.intrinsics);
    EXPECT_LE((w.T_camera0_camera.matrix() - r.T_camera0_camera.matrix()).cwiseAbs().maxCoeff(), 1e-15) << i;
    EXPECT_EQ(w.T_camera0_camera.translation(), r.T_camera0_camera.translation()) << i;
    EXPECT_EQ(bits(w.rms_px), bits(r.rms_px)) << i;
  }
}

// A head with `cameras` cameras: the simple calibration plus cameras mirrored across the
// projector, each with intrinsics of its own.
ScannerCalibration multi_camera_calibration(int cameras) {
  ScannerCalibration c = simple_calibration();
  for (int k = 1; k < cameras; ++k) {
    AdditionalCamera extra;
    extra.intrinsics = c.camera;
    extra.intrinsics.fx += 10.25 * k;
    extra.intrinsics.cy -= 3.5 * k;
    extra.intrinsics.k1 = 0.125 * k;
    extra.T_camera0_camera =
        Pose(Eigen::Quaterniond(Eigen::AngleAxisd(-0.5 * k, Eigen::Vector3d(0.1, 1.0, 0.0).normalized())),
             Eigen::Vector3d(0.17 * k, 0.001, 0.04));
    extra.rms_px = k == 1 ? 0.0625 : -1.0;  // camera 2's RMS unknown
    c.additional_cameras.push_back(extra);
  }
  return c;
}

TEST(CalibrationFile, RoundTripIsBitExact) {
  test::TemporaryDirectory directory;
  for (const ScannerCalibration& calibration : {simple_calibration(), awkward_calibration()}) {
    const std::string path = directory.file("calibration.yml");
    write_calibration(path, calibration);
    expect_calibrations_equal(calibration, read_calibration(path));
  }
}

// One camera writes no camera_count (the file reads as it did before heads had more); two and
// three cameras round-trip bit-exactly, their keys OpenCV's matrices.
TEST(CalibrationFile, AdditionalCamerasRoundTrip) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("calibration.yml");
  write_calibration(path, multi_camera_calibration(1));
  EXPECT_EQ(read_file_text(path).find("camera_count"), std::string::npos);
  EXPECT_EQ(read_calibration(path).camera_count(), 1);
  for (const int cameras : {2, 3}) {
    const ScannerCalibration calibration = multi_camera_calibration(cameras);
    write_calibration(path, calibration);
    const std::string text = read_file_text(path);
    EXPECT_NE(text.find(fmt::format("camera_count: {}\n", cameras)), std::string::npos) << text;
    EXPECT_NE(text.find("T_camera0_camera1: !!opencv-matrix\n   rows: 4\n   cols: 4\n"), std::string::npos) << text;
    EXPECT_NE(text.find("camera1_matrix: !!opencv-matrix\n"), std::string::npos) << text;
    EXPECT_NE(text.find("camera1_rms_px: 0.0625\n"), std::string::npos) << text;
    EXPECT_EQ(text.find("camera2_rms_px"), std::string::npos) << text;
    const ScannerCalibration read = read_calibration(path);
    EXPECT_EQ(read.camera_count(), cameras);
    expect_calibrations_equal(calibration, read);
  }
}

TEST(CalibrationFile, LooksLikeOpenCvFileStorage) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("calibration.yml");
  write_calibration(path, simple_calibration());
  const std::string text = read_file_text(path);
  EXPECT_EQ(text.rfind("%YAML:1.0\n---\n", 0), 0u) << text;
  EXPECT_NE(text.find("slscan_calibration_version: 1\n"), std::string::npos) << text;
  EXPECT_NE(text.find("camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                      "   data: [ 3452.5, 0., 587.25, 0.,\n       3449.75, 521.5, 0., 0.,\n       1. ]\n"),
            std::string::npos)
      << text;
  // OpenCV's order: k1 k2 p1 p2 k3.
  EXPECT_NE(text.find("camera_distortion: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
                      "   data: [ -0.25, -0.875, -0.0625, 0.03125,\n       3.125 ]\n"),
            std::string::npos)
      << text;
  EXPECT_EQ(text.find("turntable"), std::string::npos);
}

TEST(CalibrationFile, OptionalKeysMayBeAbsent) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("calibration.yml");
  write_calibration(path, simple_calibration());
  std::string text = read_file_text(path);
  for (const char* key : {"description: ", "reprojection_rms_px: "}) {
    const std::size_t start = text.find(key);
    ASSERT_NE(start, std::string::npos);
    text.erase(start, text.find('\n', start) + 1 - start);
  }
  write_file_atomic(path, text);
  const ScannerCalibration read = read_calibration(path);
  EXPECT_EQ(read.description, "");
  EXPECT_LT(read.reprojection_rms_px, 0.0);
}

// The turntable's angle and tilt σ (turntable_angle_sigma_deg, turntable_tilt_sigma_deg) are
// optional: a file written before they existed reads with none; one with them reads them back;
// 0 (an exact table) is valid.
TEST(CalibrationFile, TurntableSigmasAreOptional) {
  test::TemporaryDirectory directory;
  const std::string path = directory.file("calibration.yml");
  ScannerCalibration calibration = simple_calibration();
  calibration.turntable = TurntableAxis{Eigen::Vector3d(0.0, 0.0, 0.25), Eigen::Vector3d(0.0, 1.0, 0.0)};
  write_calibration(path, calibration);
  EXPECT_EQ(read_file_text(path).find("_sigma_deg"), std::string::npos);
  ScannerCalibration read = read_calibration(path);
  ASSERT_TRUE(read.turntable.has_value());
  EXPECT_FALSE(read.turntable->angle_sigma_deg.has_value());
  EXPECT_FALSE(read.turntable->tilt_sigma_deg.has_value());
  for (const double sigma : {0.002, 0.0, TurntableAxis::kMaxSigmaDeg}) {
    calibration.turntable->angle_sigma_deg = sigma;
    calibration.turntable->tilt_sigma_deg.reset();
    write_calibration(path, calibration);
    EXPECT_NE(read_file_text(path).find("turntable_angle_sigma_deg: "), std::string::npos);
    EXPECT_EQ(read_file_text(path).find("turntable_tilt_sigma_deg"), std::string::npos);
    read = read_calibration(path);
    ASSERT_TRUE(read.turntable->angle_sigma_deg.has_value());
    EXPECT_EQ(*read.turntable->angle_sigma_deg, sigma);
    EXPECT_FALSE(read.turntable->tilt_sigma_deg.has_value());
    calibration.turntable->tilt_sigma_deg = 0.5 * sigma;
    write_calibration(path, calibration);
    read = read_calibration(path);
    ASSERT_TRUE(read.turntable->tilt_sigma_deg.has_value());
    EXPECT_EQ(*read.turntable->tilt_sigma_deg, 0.5 * sigma);
  }
}

// Writes the simple calibration with `from` replaced by `to` (which must occur), reads it,
// and checks the error's code and that its message contains each expected fragment.
class BrokenCalibration : public ::testing::Test {
 protected:
  void expect_error(const std::string& from, const std::string& to, ErrorCode code,
                    const std::vector<std::string>& fragments) {
    std::string text = good_text();
    const std::size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << "'" << from << "' not in\n" << text;
    text.replace(at, from.size(), to);
    expect_error_for_text(text, code, fragments);
  }

  void expect_error_for_text(const std::string& text, ErrorCode code, const std::vector<std::string>& fragments) {
    write_file_atomic(path_, text);
    try {
      read_calibration(path_);
      ADD_FAILURE() << "expected an error reading\n" << text;
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), code) << error.what();
      const std::string message = error.what();
      EXPECT_NE(message.find(path_), std::string::npos) << message;
      for (const std::string& fragment : fragments) {
        EXPECT_NE(message.find(fragment), std::string::npos) << "'" << fragment << "' not in: " << message;
      }
    }
  }

  std::string good_text() {
    ScannerCalibration calibration = simple_calibration();
    calibration.turntable = TurntableAxis{Eigen::Vector3d(0.0, 0.0, 0.25), Eigen::Vector3d(0.0, 1.0, 0.0)};
    write_calibration(path_, calibration);
    return read_file_text(path_);
  }

  test::TemporaryDirectory directory_;
  std::string path_ = directory_.file("broken.yml");
};

TEST_F(BrokenCalibration, BadTurntableAngleSigma) {
  const std::string axis_end = "turntable_axis_direction: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n"
                               "   data: [ 0., 1., 0. ]\n";
  for (const char* value : {"-0.001", ".nan", ".inf", "1.5", "7.2"}) {
    expect_error(axis_end, axis_end + "turntable_angle_sigma_deg: " + value + "\n", ErrorCode::kFormat,
                 {"turntable_angle_sigma_deg", "angle repeatability in degrees"});
    expect_error(axis_end, axis_end + "turntable_tilt_sigma_deg: " + value + "\n", ErrorCode::kFormat,
                 {"turntable_tilt_sigma_deg", "tilt (wobble)", "in degrees"});
  }
  expect_error(axis_end, axis_end + "turntable_angle_sigma_deg: fast\n", ErrorCode::kFormat,
               {"key 'turntable_angle_sigma_deg'", "a number"});
  // A σ without an axis has nothing to belong to.
  std::string text = good_text();
  for (const char* key : {"turntable_axis_point:", "turntable_axis_direction:"}) {
    const std::size_t start = text.find(key);
    ASSERT_NE(start, std::string::npos);
    text.erase(start, text.find("]\n", start) + 2 - start);
  }
  expect_error_for_text(text + "turntable_angle_sigma_deg: 0.002\n", ErrorCode::kFormat,
                        {"key 'turntable_angle_sigma_deg'", "without a turntable axis"});
  expect_error_for_text(text + "turntable_tilt_sigma_deg: 0.001\n", ErrorCode::kFormat,
                        {"key 'turntable_tilt_sigma_deg'", "without a turntable axis"});
}

// A camera the count promises but the file lacks, a count out of range, a camera's bad pose or
// intrinsics: each names its key.
TEST_F(BrokenCalibration, BadAdditionalCameras) {
  write_calibration(path_, multi_camera_calibration(2));
  const std::string two = read_file_text(path_);
  std::string text = two;
  text.replace(text.find("camera_count: 2"), 15, "camera_count: 3");
  expect_error_for_text(text, ErrorCode::kFormat, {"camera2_width", "missing"});
  for (const char* count : {"camera_count: 0", "camera_count: 17", "camera_count: two"}) {
    text = two;
    text.replace(text.find("camera_count: 2"), 15, count);
    expect_error_for_text(text, ErrorCode::kFormat, {"camera_count"});
  }
  text = two;
  text.replace(text.find("T_camera0_camera1: !!opencv-matrix\n   rows: 4"), 44,
               "T_camera0_camera1: !!opencv-matrix\n   rows: 3");
  expect_error_for_text(text, ErrorCode::kFormat, {"T_camera0_camera1", "4x4"});
  text = two;
  text.replace(text.find("camera1_width: 1280"), 19, "camera1_width: 0");
  expect_error_for_text(text, ErrorCode::kFormat, {"camera1_width", "camera1"});
  ScannerCalibration bad = multi_camera_calibration(2);
  bad.additional_cameras[0].T_camera0_camera = Pose(Eigen::Quaterniond::Identity(), Eigen::Vector3d(NAN, 0.0, 0.0));
  EXPECT_THROW(bad.validate(), Error);
  bad = multi_camera_calibration(2);
  bad.additional_cameras.resize(ScannerCalibration::kMaxCameras, bad.additional_cameras[0]);
  EXPECT_THROW(bad.validate(), Error);
}

TEST_F(BrokenCalibration, MissingKey) {
  expect_error("projector_height: 768\n", "", ErrorCode::kFormat, {"key 'projector_height'", "missing"});
  expect_error("slscan_calibration_version: 1\n", "", ErrorCode::kFormat, {"key 'slscan_calibration_version'"});
  expect_error("T_camera_projector:", "T_camera_projektor:", ErrorCode::kFormat, {"key 'T_camera_projector'"});
  expect_error("turntable_axis_direction:", "turntable_axis_dir:", ErrorCode::kFormat,
               {"key 'turntable_axis_direction'", "both a point and a direction"});
  expect_error("   dt: d\n", "", ErrorCode::kFormat, {"key 'camera_matrix'", "no 'dt'"});
  expect_error("projector_width: 1024", "projector_width:", ErrorCode::kFormat,
               {"key 'projector_width'", "has no value"});
}

TEST_F(BrokenCalibration, WrongMatrixSize) {
  expect_error("   rows: 1\n   cols: 5\n", "   rows: 1\n   cols: 4\n", ErrorCode::kFormat,
               {"key 'camera_distortion'", "has 5 values"});
  expect_error("   rows: 1\n   cols: 5\n", "   rows: 1\n   cols: 6\n", ErrorCode::kFormat,
               {"key 'camera_distortion'", "expected a 1x5 or 5x1 or 1x4 or 4x1 matrix, found 1x6"});
  expect_error("   rows: 3\n   cols: 3\n", "   rows: 3\n   cols: 4\n", ErrorCode::kFormat,
               {"key 'camera_matrix'", "expected a 3x3 matrix, found 3x4"});
  expect_error("3452.5, 0., 587.25, 0.,", "3452.5, 0., 587.25,", ErrorCode::kFormat,
               {"key 'camera_matrix'", "matrix is 3x3 but 'data' has 8 values"});
  expect_error("   rows: 4\n", "   rows: four\n", ErrorCode::kFormat,
               {"key 'T_camera_projector'", "expected an integer row count, found 'four'"});
  expect_error("   dt: d\n", "   dt: u\n", ErrorCode::kFormat, {"key 'camera_matrix'", "element type 'u'"});
}

TEST_F(BrokenCalibration, BadValues) {
  expect_error("3452.5", "3452.5x", ErrorCode::kFormat, {"key 'camera_matrix'", "data[0]", "'3452.5x'"});
  expect_error("3452.5", ".nan", ErrorCode::kFormat, {"key 'camera_matrix'", "not finite"});
  expect_error("camera_width: 1280", "camera_width: 1280.5", ErrorCode::kFormat,
               {"key 'camera_width'", "expected an integer, found '1280.5'"});
  expect_error("3452.5, 0., 587.25", "3452.5, 0.5, 587.25", ErrorCode::kFormat, {"key 'camera_matrix'", "skew"});
  // A 4x4 that is not a rigid transform.
  expect_error("T_camera_projector: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ ",
               "T_camera_projector: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ 2",
               ErrorCode::kFormat, {"key 'T_camera_projector'", "not a rigid transform"});
  expect_error("slscan_calibration_version: 1", "slscan_calibration_version: 0", ErrorCode::kFormat,
               {"key 'slscan_calibration_version'", "version 0"});
}

TEST_F(BrokenCalibration, NonPositiveFocalLength) {
  expect_error("3452.5", "-3452.5", ErrorCode::kFormat, {"camera_matrix", "focal length", "-3452.5", "positive"});
  expect_error("3893.25", "0", ErrorCode::kFormat, {"projector_matrix", "focal length", "positive"});
  expect_error("camera_height: 1024", "camera_height: 0", ErrorCode::kFormat, {"camera_height", "not positive"});
  expect_error("587.25", "-5000", ErrorCode::kFormat, {"camera_matrix", "principal point"});
  expect_error("   data: [ 0., 1., 0. ]", "   data: [ 0., 0., 0. ]", ErrorCode::kFormat,
               {"turntable_axis_direction", "unit vector"});
}

TEST_F(BrokenCalibration, CorruptOrTruncatedYaml) {
  const std::string text = good_text();
  // Cut inside the camera matrix's data list: the flow sequence never closes.
  const std::size_t cut = text.find("587.25");
  ASSERT_NE(cut, std::string::npos);
  expect_error_for_text(text.substr(0, cut), ErrorCode::kFormat, {"not valid YAML"});
  // Cut after a complete key: the YAML is fine, the next key is missing.
  const std::size_t after = text.find("camera_distortion:");
  expect_error_for_text(text.substr(0, after), ErrorCode::kFormat, {"key 'camera_distortion'", "missing"});
  // Garbage on line 5 (1-based): the error gives that line.
  std::string garbage = text;
  std::size_t line_start = 0;
  for (int line = 1; line < 5; ++line) line_start = garbage.find('\n', line_start) + 1;
  garbage.insert(line_start, "camera_width: [1, 2\n");
  expect_error_for_text(garbage, ErrorCode::kFormat, {"not valid YAML", path_ + ":"});
  try {
    write_file_atomic(path_, garbage);
    read_calibration(path_);
  } catch (const Error& error) {
    // The unclosed '[' is reported where yaml-cpp gives up, at or after line 5.
    const std::string message = error.what();
    const std::size_t colon = message.find(':', path_.size());
    const int line = std::stoi(message.substr(path_.size() + 1, colon - path_.size() - 1));
    EXPECT_GE(line, 5) << message;
  }
  expect_error_for_text("", ErrorCode::kFormat, {"not a calibration file"});
  expect_error_for_text("%YAML:1.0\n---\n- 1\n- 2\n", ErrorCode::kFormat, {"not a calibration file"});
  expect_error_for_text("%YAML:1.0\n---\nkey: value: other\n", ErrorCode::kFormat, {"not valid YAML", ":3:"});
  expect_error_for_text("%YAML:1.0\n---\ncamera_width: 1280\n camera_height: 1024\n", ErrorCode::kFormat,
                        {"not valid YAML", ":4:"});
  expect_error_for_text(std::string("\x89PNG\r\n\x1a\n\0\0", 10), ErrorCode::kFormat, {});
}

TEST_F(BrokenCalibration, NewerVersionIsAVersionMismatch) {
  expect_error("slscan_calibration_version: 1", "slscan_calibration_version: 2", ErrorCode::kVersionMismatch,
               {"version 2", "slscan_calibration_version"});
}

TEST(CalibrationFile, MissingFileIsNotFound) {
  test::TemporaryDirectory directory;
  try {
    read_calibration(directory.file("absent.yml"));
    FAIL() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kNotFound);
    EXPECT_NE(std::string(error.what()).find("absent.yml"), std::string::npos);
  }
}

TEST(CalibrationValidate, AcceptsGoodAndRejectsBad) {
  EXPECT_NO_THROW(simple_calibration().validate());
  EXPECT_NO_THROW(awkward_calibration().validate());
  auto expect_invalid = [](const ScannerCalibration& c, const std::string& fragment) {
    try {
      c.validate();
      ADD_FAILURE() << "expected " << fragment;
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
      EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos) << error.what();
    }
  };
  ScannerCalibration c = simple_calibration();
  c.camera.fy = 0.0;
  expect_invalid(c, "camera_matrix");
  c = simple_calibration();
  c.projector.width = -1;
  expect_invalid(c, "projector_width");
  c = simple_calibration();
  c.camera.cx = 1e6;
  expect_invalid(c, "principal point");
  c = simple_calibration();
  c.projector.k3 = std::nan("");
  expect_invalid(c, "projector_distortion");
  c = simple_calibration();
  c.turntable = TurntableAxis{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  expect_invalid(c, "turntable_axis_direction");
  c = simple_calibration();
  c.turntable = TurntableAxis{Eigen::Vector3d(0, std::nan(""), 0), Eigen::Vector3d::UnitY()};
  expect_invalid(c, "turntable_axis_point");
  for (const double sigma : {-1e-9, std::nan(""), HUGE_VAL, 1.0001}) {
    c = simple_calibration();
    c.turntable = TurntableAxis{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitY()};
    c.turntable->angle_sigma_deg = sigma;
    expect_invalid(c, "turntable_angle_sigma_deg");
    c.turntable->angle_sigma_deg.reset();
    c.turntable->tilt_sigma_deg = sigma;
    expect_invalid(c, "turntable_tilt_sigma_deg");
  }
  c = simple_calibration();
  c.reprojection_rms_px = HUGE_VAL;
  expect_invalid(c, "reprojection_rms_px");
  // Focal lengths no lens has (a field of view outside 0.01°..170°), and no baseline.
  for (const double focal : {1e300, 1e-300, 1e9, 1.0}) {
    c = simple_calibration();
    c.camera.fx = focal;
    expect_invalid(c, "field of view");
    c = simple_calibration();
    c.projector.fy = focal;
    expect_invalid(c, "field of view");
  }
  c = simple_calibration();
  c.T_camera_projector = Pose(c.T_camera_projector.quaternion(), Eigen::Vector3d::Zero());
  expect_invalid(c, "baseline");
}

TEST(CalibrationFile, InvalidCalibrationIsNotWritten) {
  test::TemporaryDirectory directory;
  ScannerCalibration c = simple_calibration();
  c.camera.fx = -1.0;
  const std::string path = directory.file("bad.yml");
  EXPECT_THROW(write_calibration(path, c), Error);
  EXPECT_THROW(read_file_text(path), Error);  // nothing left behind
}

}  // namespace
}  // namespace sls
