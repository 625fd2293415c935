// The shared camera model (sdk/core/camera_model_shared.h) on the host: projection and
// unprojection invert each other over whole images, the distortion Jacobian matches finite
// differences, and the failure cases say so. OpenCV agreement is in
// tests/interop/test_camera_model_opencv.cpp.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <ostream>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "sdk/core/camera_model_shared.h"

namespace sls {
namespace {

struct NamedCamera {
  std::string name;
  CameraIntrinsics intrinsics;
};

CameraIntrinsics make_camera(int width, int height, double f, double cx, double cy, double k1, double k2,
                             double k3, double p1, double p2) {
  CameraIntrinsics c;
  c.width = width;
  c.height = height;
  c.fx = f;
  c.fy = f * 1.0007;  // slightly non-square pixels so fx/fy mix-ups show
  c.cx = cx;
  c.cy = cy;
  c.k1 = k1;
  c.k2 = k2;
  c.k3 = k3;
  c.p1 = p1;
  c.p2 = p2;
  return c;
}

// Mild: the real procam camera (shared/data/procam-calibration, 1280x1024).
CameraIntrinsics mild_camera() {
  CameraIntrinsics c;
  c.width = 1280;
  c.height = 1024;
  c.fx = 3452.3929068729908;
  c.fy = 3449.9242930993751;
  c.cx = 587.17314727289579;
  c.cy = 521.44602565518824;
  c.k1 = -0.22226531001384053;
  c.k2 = -0.86613346033377336;
  c.p1 = -7.2783909763891115e-04;
  c.p2 = -1.6883927279082831e-03;
  c.k3 = 3.1254596570907323;
  return c;
}

// Strong barrel: a wide lens, about 25 % radial displacement in the corners.
CameraIntrinsics strong_barrel_camera() {
  return make_camera(1920, 1080, 1000.0, 955.5, 541.25, -0.28, 0.09, -0.012, 1.2e-3, -8e-4);
}

// Strong pincushion with an off-centre principal point.
CameraIntrinsics strong_pincushion_camera() {
  return make_camera(1024, 768, 700.0, 540.0, 370.0, 0.18, 0.04, 0.01, -2e-3, 1.5e-3);
}

std::vector<NamedCamera> cameras() {
  return {{"mild_real_procam", mild_camera()},
          {"strong_barrel", strong_barrel_camera()},
          {"strong_pincushion", strong_pincushion_camera()}};
}

// Names the case in test listings instead of dumping its bytes.
void PrintTo(const NamedCamera& camera, std::ostream* out) { *out << camera.name; }

class CameraModelRoundTrip : public ::testing::TestWithParam<NamedCamera> {};

// Every pixel centre: unproject, then project the ray back.
TEST_P(CameraModelRoundTrip, UnprojectThenProjectOverWholeImageDouble) {
  const CameraIntrinsics& c = GetParam().intrinsics;
  double max_error = 0.0;
  int failures = 0;
  for (int y = 0; y < c.height; ++y) {
    for (int x = 0; x < c.width; ++x) {
      const Vec2d pixel{static_cast<double>(x), static_cast<double>(y)};
      Vec3d ray;
      if (!unproject(c, pixel, &ray)) {
        ++failures;
        continue;
      }
      EXPECT_EQ(ray.z, 1.0);
      Vec2d back;
      ASSERT_TRUE(project(c, ray, &back));
      max_error = std::max({max_error, std::fabs(back.x - pixel.x), std::fabs(back.y - pixel.y)});
    }
  }
  EXPECT_EQ(failures, 0);
  EXPECT_LE(max_error, 1e-9) << GetParam().name;
  std::printf("%s: double unproject -> project max |error| = %.3g px\n", GetParam().name.c_str(), max_error);
}

// The same in float: what the float ray map and float kernels would get on their own.
TEST_P(CameraModelRoundTrip, UnprojectThenProjectOverWholeImageFloat) {
  const CameraIntrinsicsF c = GetParam().intrinsics.cast<float>();
  double max_error = 0.0;
  int failures = 0;
  for (int y = 0; y < c.height; ++y) {
    for (int x = 0; x < c.width; ++x) {
      const Vec2f pixel{static_cast<float>(x), static_cast<float>(y)};
      Vec3f ray;
      if (!unproject(c, pixel, &ray)) {
        ++failures;
        continue;
      }
      Vec2f back;
      ASSERT_TRUE(project(c, ray, &back));
      max_error = std::max({max_error, std::fabs(static_cast<double>(back.x) - x),
                            std::fabs(static_cast<double>(back.y) - y)});
    }
  }
  EXPECT_EQ(failures, 0);
  EXPECT_LE(max_error, 1e-3) << GetParam().name;
  std::printf("%s: float unproject -> project max |error| = %.3g px\n", GetParam().name.c_str(), max_error);
}

// From the other side: points in front of the camera that land in the image come back as
// the same normalized direction.
TEST_P(CameraModelRoundTrip, ProjectThenUnprojectRecoversDirection) {
  const CameraIntrinsics& c = GetParam().intrinsics;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double max_error = 0.0;
  int tested = 0;
  while (tested < 20000) {
    // Random pixel, then a direction through its ideal (undistorted) position, at a random depth.
    Vec2d ideal;
    ASSERT_TRUE(undistort_pixel(c, Vec2d{u(rng) * (c.width - 1), u(rng) * (c.height - 1)}, &ideal));
    const Vec2d n = pixel_to_normalized(c, ideal);
    const double depth = 0.05 + 5.0 * u(rng);
    Vec2d pixel;
    ASSERT_TRUE(project(c, Vec3d{n.x * depth, n.y * depth, depth}, &pixel));
    Vec3d ray;
    ASSERT_TRUE(unproject(c, pixel, &ray));
    max_error = std::max({max_error, std::fabs(ray.x - n.x), std::fabs(ray.y - n.y)});
    ++tested;
  }
  // 1e-12 normalized is well below 1e-8 px at these focal lengths.
  EXPECT_LE(max_error, 1e-12) << GetParam().name;
  std::printf("%s: project -> unproject max |error| = %.3g (normalized)\n", GetParam().name.c_str(), max_error);
}

INSTANTIATE_TEST_SUITE_P(Cameras, CameraModelRoundTrip, ::testing::ValuesIn(cameras()),
                         [](const ::testing::TestParamInfo<NamedCamera>& param_info) { return param_info.param.name; });

TEST(CameraModel, DistortionJacobianMatchesFiniteDifferences) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    CameraIntrinsics c;
    c.k1 = 0.4 * u(rng);
    c.k2 = 0.2 * u(rng);
    c.k3 = 0.1 * u(rng);
    c.p1 = 0.01 * u(rng);
    c.p2 = 0.01 * u(rng);
    const Vec2d n{0.8 * u(rng), 0.6 * u(rng)};
    double j[4];
    distortion_jacobian(c, n, j);
    const double h = 1e-6;
    const Vec2d dx = distort_normalized(c, Vec2d{n.x + h, n.y}) - distort_normalized(c, Vec2d{n.x - h, n.y});
    const Vec2d dy = distort_normalized(c, Vec2d{n.x, n.y + h}) - distort_normalized(c, Vec2d{n.x, n.y - h});
    // Central differences: truncation O(h²) ≈ 1e-12, rounding ≈ 1e-16 / h = 1e-10.
    EXPECT_NEAR(j[0], dx.x / (2 * h), 1e-8) << trial;
    EXPECT_NEAR(j[2], dx.y / (2 * h), 1e-8) << trial;
    EXPECT_NEAR(j[1], dy.x / (2 * h), 1e-8) << trial;
    EXPECT_NEAR(j[3], dy.y / (2 * h), 1e-8) << trial;
  }
}

TEST(CameraModel, DistortionMatchesTheBrownConradyFormula) {
  // Written out independently of the implementation (OpenCV's documented formula).
  const CameraIntrinsics c = strong_barrel_camera();
  const double x = 0.31, y = -0.47;
  const double r2 = x * x + y * y;
  const double radial = 1 + c.k1 * r2 + c.k2 * r2 * r2 + c.k3 * r2 * r2 * r2;
  const double xd = x * radial + 2 * c.p1 * x * y + c.p2 * (r2 + 2 * x * x);
  const double yd = y * radial + c.p1 * (r2 + 2 * y * y) + 2 * c.p2 * x * y;
  const Vec2d d = distort_normalized(c, Vec2d{x, y});
  EXPECT_NEAR(d.x, xd, 1e-15);
  EXPECT_NEAR(d.y, yd, 1e-15);
}

TEST(CameraModel, PointsAtOrBehindTheCameraAreRejected) {
  const CameraIntrinsics c = mild_camera();
  Vec2d pixel{-7.0, -7.0};
  EXPECT_FALSE(project(c, Vec3d{0.1, 0.2, 0.0}, &pixel));
  EXPECT_FALSE(project(c, Vec3d{0.1, 0.2, -0.5}, &pixel));
  EXPECT_FALSE(project(c, Vec3d{0.0, 0.0, -1e-300}, &pixel));
  EXPECT_FALSE(project(c, Vec3d{0.0, 0.0, std::numeric_limits<double>::quiet_NaN()}, &pixel));
  EXPECT_EQ(pixel.x, -7.0);  // untouched on failure
  EXPECT_TRUE(project(c, Vec3d{0.0, 0.0, 1e-9}, &pixel));
  EXPECT_DOUBLE_EQ(pixel.x, c.cx);
  EXPECT_DOUBLE_EQ(pixel.y, c.cy);
  const CameraIntrinsicsF cf = c.cast<float>();
  Vec2f pixel_f;
  EXPECT_FALSE(project(cf, Vec3f{0.1f, 0.2f, -0.5f}, &pixel_f));
  EXPECT_FALSE(project(cf, Vec3f{0.1f, 0.2f, 0.0f}, &pixel_f));
}

TEST(CameraModel, UndistortionFailsWhereTheLensFolds) {
  // r_d = r (1 − 0.5 r²) peaks at r_d ≈ 0.544 (r = 0.816): farther distorted radii have no
  // preimage, so Newton cannot converge and unproject must say so.
  CameraIntrinsics c = make_camera(2000, 2000, 1000.0, 1000.0, 1000.0, -0.5, 0.0, 0.0, 0.0, 0.0);
  c.fy = c.fx;
  Vec3d ray;
  EXPECT_TRUE(unproject(c, Vec2d{1000.0 + 500.0, 1000.0}, &ray));    // r_d = 0.5: fine
  EXPECT_FALSE(unproject(c, Vec2d{1000.0 + 800.0, 1000.0}, &ray));   // r_d = 0.8: none
  EXPECT_FALSE(unproject(c, Vec2d{1000.0 + 700.0, 1000.0 + 700.0}, &ray));
  Vec2d ideal;
  EXPECT_FALSE(undistort_pixel(c, Vec2d{1000.0 - 900.0, 1000.0}, &ideal));
  Vec3f ray_f;
  EXPECT_FALSE(unproject(c.cast<float>(), Vec2f{1800.0f, 1000.0f}, &ray_f));
  // Past the fold the polynomial goes negative: r − 0.5 r³ = −1.246 at r ≈ 1.83, so the
  // corner pixel has a preimage mirrored through the centre. Newton can find it; it is not a ray.
  const Vec2d corner = pixel_to_normalized(c, Vec2d{2.5, 252.5});
  const double r_d = std::hypot(corner.x, corner.y);
  double r = 1.8;
  for (int i = 0; i < 50; ++i) r -= (r - 0.5 * r * r * r + r_d) / (1.0 - 1.5 * r * r);
  const Vec2d mirrored{-corner.x / r_d * r, -corner.y / r_d * r};
  const Vec2d check = distort_normalized(c, mirrored);
  ASSERT_NEAR(check.x, corner.x, 1e-12);
  ASSERT_NEAR(check.y, corner.y, 1e-12);
  EXPECT_FALSE(unproject(c, Vec2d{2.5, 252.5}, &ray));
  EXPECT_FALSE(inside_first_fold(c, mirrored.x * mirrored.x + mirrored.y * mirrored.y));
  EXPECT_TRUE(inside_first_fold(c, 0.6));  // the fold is at r² = 2/3
  EXPECT_FALSE(inside_first_fold(c, 0.7));
  // With k2 > 0 the curve turns up again after r² = 2: there the slope is positive again, but
  // the dip in between still rules it out.
  c.k2 = 0.1;
  EXPECT_FALSE(inside_first_fold(c, 3.0));
  EXPECT_GT(radial_slope(c, 3.0), 0.0);
  EXPECT_TRUE(inside_first_fold(c, 0.9));
  const Vec2d far_branch = distort_normalized(c, Vec2d{std::sqrt(3.0), 0.0});  // r_d ≈ 0.69 > 0.6 = first-branch max
  EXPECT_FALSE(unproject(c, normalized_to_pixel(c, far_branch), &ray));
  // NaN pixels are not "converged" either.
  EXPECT_FALSE(unproject(c, Vec2d{std::numeric_limits<double>::quiet_NaN(), 1000.0}, &ray));
}

TEST(CameraModel, NoDistortionIsThePlainPinhole) {
  CameraIntrinsics c = make_camera(640, 480, 500.0, 320.0, 240.0, 0, 0, 0, 0, 0);
  EXPECT_FALSE(c.has_distortion());
  Vec3d ray;
  ASSERT_TRUE(unproject(c, Vec2d{100.0, 400.0}, &ray));
  EXPECT_DOUBLE_EQ(ray.x, (100.0 - 320.0) / c.fx);
  EXPECT_DOUBLE_EQ(ray.y, (400.0 - 240.0) / c.fy);
  EXPECT_EQ(ray.z, 1.0);
  Vec2d pixel;
  ASSERT_TRUE(project(c, Vec3d{0.2, -0.1, 2.0}, &pixel));
  EXPECT_DOUBLE_EQ(pixel.x, 320.0 + 500.0 * 0.1);
  EXPECT_DOUBLE_EQ(pixel.y, 240.0 - c.fy * 0.05);
}

TEST(CameraModel, UndistortPixelKeepsTheIntrinsics) {
  const CameraIntrinsics c = strong_barrel_camera();
  // The principal point does not move; corners move outwards under barrel distortion.
  Vec2d ideal;
  ASSERT_TRUE(undistort_pixel(c, Vec2d{c.cx, c.cy}, &ideal));
  EXPECT_NEAR(ideal.x, c.cx, 1e-9);
  EXPECT_NEAR(ideal.y, c.cy, 1e-9);
  ASSERT_TRUE(undistort_pixel(c, Vec2d{0.0, 0.0}, &ideal));
  EXPECT_LT(ideal.x, -50.0);
  EXPECT_LT(ideal.y, -50.0);
}

}  // namespace
}  // namespace sls
