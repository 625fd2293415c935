// Rigid poses in SE(3) on Eigen (host side). Naming convention everywhere: T_a_b maps
// coordinates in frame b to frame a (p_a = T_a_b * p_b), so T_world_camera is the camera's
// pose in the world, and T_a_c = T_a_b * T_b_c.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "sdk/core/math_shared.h"

namespace sls {

using Vector6d = Eigen::Matrix<double, 6, 1>;

class Pose {
 public:
  Pose() : rotation_(Eigen::Quaterniond::Identity()), translation_(Eigen::Vector3d::Zero()) {}
  Pose(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation);
  Pose(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation);

  static Pose identity() { return Pose(); }
  // From a 4x4 homogeneous matrix; throws sls::Error if its rotation block is not a rotation.
  static Pose from_matrix(const Eigen::Matrix4d& matrix);
  // Exponential map of a twist (rho = translation part, omega = rotation part, in that order).
  static Pose exp(const Vector6d& twist);
  static Pose from_rigid(const Rigid3d& rigid);

  const Eigen::Quaterniond& quaternion() const { return rotation_; }
  Eigen::Matrix3d rotation() const { return rotation_.toRotationMatrix(); }
  const Eigen::Vector3d& translation() const { return translation_; }
  Eigen::Matrix4d matrix() const;
  Vector6d log() const;
  // Rotation angle in radians, in [0, pi].
  double angle_rad() const;

  Pose inverse() const;
  Pose operator*(const Pose& other) const;
  Eigen::Vector3d operator*(const Eigen::Vector3d& point) const { return rotation_ * point + translation_; }

  Rigid3d to_rigid3d() const;
  Rigid3f to_rigid3f() const;

  bool is_approx(const Pose& other, double tolerance = 1e-12) const;

 private:
  Eigen::Quaterniond rotation_;  // kept normalized
  Eigen::Vector3d translation_;
};

}  // namespace sls
