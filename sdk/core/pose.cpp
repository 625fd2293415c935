#include "sdk/core/pose.h"

#include <cmath>

#include "sdk/core/error.h"

namespace sls {
namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Left Jacobian of SO(3): V in t = V * rho. Series near zero keeps it exact to rounding.
Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& omega) {
  const double theta = omega.norm();
  const Eigen::Matrix3d w = skew(omega);
  double a, b;
  if (theta < 1e-5) {
    const double t2 = theta * theta;
    a = 0.5 - t2 / 24.0;
    b = 1.0 / 6.0 - t2 / 120.0;
  } else {
    a = (1.0 - std::cos(theta)) / (theta * theta);
    b = (theta - std::sin(theta)) / (theta * theta * theta);
  }
  return Eigen::Matrix3d::Identity() + a * w + b * w * w;
}

}  // namespace

Pose::Pose(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
    : rotation_(rotation.normalized()), translation_(translation) {}

Pose::Pose(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& translation)
    : rotation_(Eigen::Quaterniond(rotation).normalized()), translation_(translation) {}

Pose Pose::from_matrix(const Eigen::Matrix4d& matrix) {
  const Eigen::Matrix3d r = matrix.topLeftCorner<3, 3>();
  const double orthogonality = (r.transpose() * r - Eigen::Matrix3d::Identity()).norm();
  if (!(orthogonality < 1e-6) || !(std::fabs(r.determinant() - 1.0) < 1e-6) ||
      !matrix.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1))) {
    throw_error(ErrorCode::kInvalidArgument,
                "matrix is not a rigid transform (|RᵀR − I| = {:.3g}, det R = {:.6f})", orthogonality,
                r.determinant());
  }
  return Pose(r, matrix.topRightCorner<3, 1>());
}

Pose Pose::exp(const Vector6d& twist) {
  const Eigen::Vector3d rho = twist.head<3>();
  const Eigen::Vector3d omega = twist.tail<3>();
  const double theta = omega.norm();
  const Eigen::Quaterniond q =
      theta < 1e-12 ? Eigen::Quaterniond(1.0, 0.5 * omega.x(), 0.5 * omega.y(), 0.5 * omega.z())
                    : Eigen::Quaterniond(Eigen::AngleAxisd(theta, omega / theta));
  return Pose(q, so3_left_jacobian(omega) * rho);
}

Pose Pose::from_rigid(const Rigid3d& rigid) {
  Eigen::Matrix3d r;
  for (int i = 0; i < 9; ++i) r(i / 3, i % 3) = rigid.rotation.m[i];
  return Pose(r, Eigen::Vector3d(rigid.translation.x, rigid.translation.y, rigid.translation.z));
}

Eigen::Matrix4d Pose::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = rotation();
  m.topRightCorner<3, 1>() = translation_;
  return m;
}

Vector6d Pose::log() const {
  const Eigen::AngleAxisd angle_axis(rotation_);
  Eigen::Vector3d omega = angle_axis.angle() * angle_axis.axis();
  if (angle_axis.angle() > M_PI) omega = (angle_axis.angle() - 2.0 * M_PI) * angle_axis.axis();
  Vector6d twist;
  twist.head<3>() = so3_left_jacobian(omega).inverse() * translation_;
  twist.tail<3>() = omega;
  return twist;
}

double Pose::angle_rad() const {
  // atan2 form stays accurate for tiny angles, where acos(w) loses half the digits.
  const double w = std::fabs(rotation_.w());
  return 2.0 * std::atan2(rotation_.vec().norm(), w);
}

Pose Pose::inverse() const {
  const Eigen::Quaterniond inverse_rotation = rotation_.conjugate();
  return Pose(inverse_rotation, -(inverse_rotation * translation_));
}

Pose Pose::operator*(const Pose& other) const {
  return Pose(rotation_ * other.rotation_, rotation_ * other.translation_ + translation_);
}

Rigid3d Pose::to_rigid3d() const {
  const Eigen::Matrix3d r = rotation();
  Rigid3d out;
  for (int i = 0; i < 9; ++i) out.rotation.m[i] = r(i / 3, i % 3);
  out.translation = {translation_.x(), translation_.y(), translation_.z()};
  return out;
}

Rigid3f Pose::to_rigid3f() const {
  const Rigid3d d = to_rigid3d();
  Rigid3f out;
  for (int i = 0; i < 9; ++i) out.rotation.m[i] = static_cast<float>(d.rotation.m[i]);
  out.translation = {static_cast<float>(d.translation.x), static_cast<float>(d.translation.y),
                     static_cast<float>(d.translation.z)};
  return out;
}

bool Pose::is_approx(const Pose& other, double tolerance) const {
  return (translation_ - other.translation_).norm() <= tolerance &&
         (inverse() * other).angle_rad() <= tolerance;
}

}  // namespace sls
