#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/pose.h"

namespace sls {
namespace {

Pose random_pose(std::mt19937& rng, double max_angle_rad = M_PI) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Eigen::Vector3d axis(unit(rng), unit(rng), unit(rng));
  axis.normalize();
  const double angle = max_angle_rad * std::fabs(unit(rng));
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis)), Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
}

TEST(Pose, ComposeAndInverseMatchMatrices) {
  std::mt19937 rng(1);
  for (int i = 0; i < 100; ++i) {
    const Pose a = random_pose(rng), b = random_pose(rng);
    EXPECT_TRUE((a * b).matrix().isApprox(a.matrix() * b.matrix(), 1e-12));
    EXPECT_TRUE(a.inverse().matrix().isApprox(a.matrix().inverse(), 1e-12));
    const Eigen::Vector3d p(0.3, -0.2, 0.7);
    EXPECT_TRUE((a * p).isApprox((a.matrix() * p.homogeneous()).head<3>(), 1e-12));
  }
}

TEST(Pose, ExpLogRoundTrip) {
  std::mt19937 rng(2);
  for (int i = 0; i < 200; ++i) {
    // Angles up to just below pi, and tiny ones where the series branch is used.
    const Pose pose = random_pose(rng, i % 2 == 0 ? 3.1 : 1e-7);
    EXPECT_TRUE(Pose::exp(pose.log()).is_approx(pose, 1e-9)) << i;
  }
}

TEST(Pose, ExpOfPureTranslationAndRotation) {
  Vector6d twist = Vector6d::Zero();
  twist << 0.1, 0.2, 0.3, 0, 0, 0;
  EXPECT_TRUE(Pose::exp(twist).translation().isApprox(Eigen::Vector3d(0.1, 0.2, 0.3)));
  twist << 0, 0, 0, 0, 0, M_PI / 2;
  const Pose rotation = Pose::exp(twist);
  EXPECT_NEAR(rotation.angle_rad(), M_PI / 2, 1e-12);
  EXPECT_TRUE((rotation * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

TEST(Pose, FromMatrixRejectsNonRigid) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 0) = 2.0;
  EXPECT_THROW(Pose::from_matrix(m), Error);
  m = Eigen::Matrix4d::Identity();
  m(0, 0) = -1.0;  // a reflection
  EXPECT_THROW(Pose::from_matrix(m), Error);
}

TEST(Pose, RigidConversionMatches) {
  std::mt19937 rng(3);
  const Pose pose = random_pose(rng);
  const Rigid3d rigid = pose.to_rigid3d();
  const Vec3d p = transform_point(rigid, Vec3d{0.1, 0.2, 0.3});
  const Eigen::Vector3d expected = pose * Eigen::Vector3d(0.1, 0.2, 0.3);
  EXPECT_NEAR(p.x, expected.x(), 1e-15);
  EXPECT_NEAR(p.y, expected.y(), 1e-15);
  EXPECT_NEAR(p.z, expected.z(), 1e-15);
  EXPECT_TRUE(Pose::from_rigid(rigid).is_approx(pose, 1e-12));
  const Vec3d back = transform_point(inverse(rigid), p);
  EXPECT_NEAR(back.x, 0.1, 1e-15);
}

}  // namespace
}  // namespace sls
