// Our camera model against OpenCV's (cv::projectPoints, cv::undistortPoints): same model,
// same coefficient meaning, so the pixels must agree to far below a micro-pixel.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ostream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "calib/opencv_conversions.h"
#include "sdk/core/camera_model_shared.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

struct NamedCamera {
  std::string name;
  CameraIntrinsics intrinsics;
};

cv::Mat camera_matrix(const CameraIntrinsics& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
}

// OpenCV's order: k1 k2 p1 p2 k3.
cv::Mat distortion(const CameraIntrinsics& c) { return (cv::Mat_<double>(1, 5) << c.k1, c.k2, c.p1, c.p2, c.k3); }

// The real camera of shared/data/procam-calibration (1280x1024), read with OpenCV.
CameraIntrinsics real_procam_camera() {
  const std::string path = test::shared_data_path("procam-calibration/calibration_result.xml");
  cv::FileStorage storage(path, cv::FileStorage::READ);
  if (!storage.isOpened()) throw std::runtime_error("cannot open " + path);
  cv::Mat k, d;
  storage["cam_int"] >> k;
  storage["cam_dist"] >> d;
  if (k.rows != 3 || k.cols != 3 || d.total() != 5) throw std::runtime_error("unexpected matrices in " + path);
  return calib::intrinsics_from(k, d, 1280, 1024);
}

// A 4000x3000 camera behind a long lens, as in the paper's scanner.
CameraIntrinsics high_resolution_camera() {
  CameraIntrinsics c;
  c.width = 4000;
  c.height = 3000;
  c.fx = 13041.7;
  c.fy = 13037.2;
  c.cx = 1987.4;
  c.cy = 1512.9;
  c.k1 = -0.137;
  c.k2 = 0.86;
  c.k3 = -4.2;
  c.p1 = 3.3e-4;
  c.p2 = -5.1e-4;
  return c;
}

// Random but realistic: f from wide to long lenses, distortion mild enough that OpenCV's
// fixed-point undistortion converges over the whole image.
CameraIntrinsics random_camera(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  CameraIntrinsics c;
  const int sizes[][2] = {{640, 480}, {1280, 1024}, {1920, 1200}, {2448, 2048}, {4000, 3000}};
  const auto& size = sizes[std::uniform_int_distribution<int>(0, 4)(rng)];
  c.width = size[0];
  c.height = size[1];
  // f between 1.2 and 4 image widths: fields of view from about 45 to 14 degrees.
  c.fx = c.width * (2.6 + 1.4 * u(rng));
  c.fy = c.fx * (1.0 + 1e-3 * u(rng));
  c.cx = 0.5 * (c.width - 1) + 0.03 * c.width * u(rng);
  c.cy = 0.5 * (c.height - 1) + 0.03 * c.height * u(rng);
  c.k1 = 0.3 * u(rng);
  c.k2 = 0.8 * u(rng);
  c.k3 = 2.0 * u(rng);
  c.p1 = 2e-3 * u(rng);
  c.p2 = 2e-3 * u(rng);
  return c;
}

std::vector<NamedCamera> cameras() {
  std::vector<NamedCamera> out = {{"real_procam", real_procam_camera()},
                                  {"high_resolution_4000x3000", high_resolution_camera()}};
  std::mt19937 rng(2024);
  for (int i = 0; i < 8; ++i) out.push_back({"random_" + std::to_string(i), random_camera(rng)});
  return out;
}

// Names the case in test listings instead of dumping its bytes.
void PrintTo(const NamedCamera& camera, std::ostream* out) { *out << camera.name; }

class CameraModelVsOpenCv : public ::testing::TestWithParam<NamedCamera> {};

TEST_P(CameraModelVsOpenCv, ProjectMatchesProjectPoints) {
  const CameraIntrinsics& c = GetParam().intrinsics;
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  // Points whose images cover the frame and a 10 % margin around it, at depths 5 cm to 5 m.
  std::vector<cv::Point3d> points;
  for (int i = 0; i < 20000; ++i) {
    const double px = (-0.1 + 1.2 * u(rng)) * c.width;
    const double py = (-0.1 + 1.2 * u(rng)) * c.height;
    const Vec2d n = pixel_to_normalized(c, Vec2d{px, py});  // ignoring distortion: any direction will do
    const double depth = 0.05 + 5.0 * u(rng);
    points.emplace_back(n.x * depth, n.y * depth, depth);
  }
  std::vector<cv::Point2d> expected;
  cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), camera_matrix(c), distortion(c), expected);
  ASSERT_EQ(expected.size(), points.size());
  double max_error = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    Vec2d pixel;
    ASSERT_TRUE(project(c, Vec3d{points[i].x, points[i].y, points[i].z}, &pixel));
    max_error = std::max({max_error, std::fabs(pixel.x - expected[i].x), std::fabs(pixel.y - expected[i].y)});
  }
  EXPECT_LE(max_error, 1e-6) << GetParam().name;
  std::printf("%s: project vs cv::projectPoints max |error| = %.3g px\n", GetParam().name.c_str(), max_error);
}

TEST_P(CameraModelVsOpenCv, UndistortMatchesUndistortPoints) {
  const CameraIntrinsics& c = GetParam().intrinsics;
  std::mt19937 rng(19);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<cv::Point2d> pixels;
  // Every corner and edge midpoint (the worst places), then random pixels.
  for (const double fx : {0.0, 0.5, 1.0}) {
    for (const double fy : {0.0, 0.5, 1.0}) pixels.emplace_back(fx * (c.width - 1), fy * (c.height - 1));
  }
  for (int i = 0; i < 20000; ++i) pixels.emplace_back(u(rng) * (c.width - 1), u(rng) * (c.height - 1));
  std::vector<cv::Point2d> expected;
  // OpenCV iterates a fixed point (linear convergence); the default 5 iterations are far from
  // converged, so ask for convergence to 1e-11 px (its error is measured in pixels).
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 2000, 1e-11);
  const cv::Mat k = camera_matrix(c);
  cv::undistortPoints(pixels, expected, k, distortion(c), cv::noArray(), k, criteria);
  ASSERT_EQ(expected.size(), pixels.size());
  double max_error = 0.0;
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    Vec2d ideal;
    ASSERT_TRUE(undistort_pixel(c, Vec2d{pixels[i].x, pixels[i].y}, &ideal)) << pixels[i];
    max_error = std::max({max_error, std::fabs(ideal.x - expected[i].x), std::fabs(ideal.y - expected[i].y)});
  }
  EXPECT_LE(max_error, 1e-6) << GetParam().name;
  std::printf("%s: undistort vs cv::undistortPoints max |error| = %.3g px\n", GetParam().name.c_str(), max_error);
}

INSTANTIATE_TEST_SUITE_P(Cameras, CameraModelVsOpenCv, ::testing::ValuesIn(cameras()),
                         [](const ::testing::TestParamInfo<NamedCamera>& param_info) { return param_info.param.name; });

}  // namespace
}  // namespace sls
