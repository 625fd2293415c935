#include "fusion/pose_prior.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <Eigen/Geometry>

#include "fusion/track_shared.h"
#include "fusion/tracker.h"
#include "fusion/tracker_internal.h"
#include "sdk/core/error.h"

namespace sls::fusion {
namespace {

using tracking_detail::Matrix6d;
using tracking_detail::normal_matrix;

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Eigen::Vector3d rotation_log(const Eigen::Quaterniond& q) {
  const Eigen::AngleAxisd angle_axis(q.normalized());
  double angle = angle_axis.angle();
  if (angle > M_PI) angle -= 2.0 * M_PI;
  return angle * angle_axis.axis();
}

// An eigenvalue of A trusted at `ratio` of its largest (and at least 1e-12 of it).
bool trusted(double value, double largest, double ratio) {
  return value > 0.0 && value >= std::max(ratio, 1e-12) * largest;
}

// Two unit vectors perpendicular to a and to each other.
void perpendicular(const Eigen::Vector3d& a, Eigen::Vector3d* e1, Eigen::Vector3d* e2) {
  const Eigen::Vector3d seed = std::fabs(a.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  *e1 = (seed - seed.dot(a) * a).normalized();
  *e2 = a.cross(*e1);
}

void check_sigma(const char* name, double sigma) {
  if (!(sigma > 0.0) || std::isnan(sigma)) {
    throw_error(ErrorCode::kInvalidArgument,
                "pose prior: {} {} rad must be positive (infinity: that rotation free; 0 would be an infinite "
                "information)",
                name, sigma);
  }
}

}  // namespace

Eigen::Matrix3d PosePrior::information() const {
  const Eigen::Matrix3d along = axis_world * axis_world.transpose();
  Eigen::Matrix3d lambda = Eigen::Matrix3d::Zero();
  if (sigma_rad < kNone) lambda += along / (sigma_rad * sigma_rad);
  if (tilt_sigma_rad < kNone) lambda += (Eigen::Matrix3d::Identity() - along) / (tilt_sigma_rad * tilt_sigma_rad);
  return lambda;
}

void PosePrior::validate() const {
  if (!T_world_camera.translation().allFinite() || !T_world_camera.quaternion().coeffs().allFinite()) {
    throw_error(ErrorCode::kInvalidArgument, "pose prior: the prior's pose is not finite");
  }
  const double length = axis_world.norm();
  if (!std::isfinite(length) || !(std::fabs(length - 1.0) <= 1e-6)) {
    throw_error(ErrorCode::kInvalidArgument, "pose prior: the axis has length {} (expected a unit vector)", length);
  }
  check_sigma("σ about the axis", sigma_rad);
  check_sigma("tilt σ", tilt_sigma_rad);
}

Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d w = skew(phi);
  // I − ½[φ]× + (1/θ² − (1 + cos θ)/(2θ sin θ)) [φ]×², whose coefficient tends to 1/12.
  const double c = theta < 1e-4 ? 1.0 / 12.0 + theta * theta / 720.0
                                : 1.0 / (theta * theta) - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  return Eigen::Matrix3d::Identity() - 0.5 * w + c * w * w;
}

Eigen::Vector3d pose_prior_offset_rad(const PosePrior& prior, const Pose& T_world_camera) {
  return rotation_log(T_world_camera.quaternion() * prior.T_world_camera.quaternion().conjugate());
}

PosePriorTerm pose_prior_term(const PosePrior& prior, const Pose& T_world_model, const Pose& T_model_live,
                              double scale_m) {
  PosePriorTerm term;
  term.residual_rad = pose_prior_offset_rad(prior, T_world_model * T_model_live);
  // A rotation δ of the update in the model frame is R_world_model δ in the world's:
  // log(exp(R_wm δ) · exp(φ)) = φ + J_l⁻¹(φ) R_wm δ, and δ = ω' / L.
  term.jacobian.rightCols<3>() = so3_left_jacobian_inverse(term.residual_rad) * T_world_model.rotation() / scale_m;
  return term;
}

namespace {

// surface_sigma_rad over A's eigen-decomposition, made once per step (solve_with_pose_prior asks
// for three rows and solves with the same decomposition).
double surface_sigma_rad(const Eigen::SelfAdjointEigenSolver<Matrix6d>& eigen, const Vector6d& jacobian,
                         double variance_m2, double min_ratio) {
  const double largest = eigen.eigenvalues()(5);
  if (!(largest > 0.0) || !std::isfinite(largest)) return std::numeric_limits<double>::infinity();
  double variance = 0.0;
  for (int i = 0; i < 6; ++i) {
    const double along = eigen.eigenvectors().col(i).dot(jacobian);
    const double value = eigen.eigenvalues()(i);
    if (!trusted(value, largest, min_ratio)) {
      if (std::fabs(along) > 1e-9 * jacobian.norm()) return std::numeric_limits<double>::infinity();
      continue;  // a free direction the rotation does not move along
    }
    variance += along * along / value;
  }
  return std::sqrt(variance_m2 * variance);
}

}  // namespace

double surface_sigma_rad(const double* sums, const Vector6d& jacobian, double variance_m2, double min_ratio) {
  return surface_sigma_rad(Eigen::SelfAdjointEigenSolver<Matrix6d>(normal_matrix(sums)), jacobian, variance_m2,
                           min_ratio);
}

PriorStep solve_with_pose_prior(const double* sums, const PosePrior& prior, double variance_m2,
                                const Pose& T_world_model, const Pose& T_model_live, double scale_m,
                                double degenerate_ratio) {
  const PosePriorTerm term = pose_prior_term(prior, T_world_model, T_model_live, scale_m);
  PriorStep step;
  // What the surface alone says about the rotation about the axis and about its tilt.
  Eigen::Vector3d e1, e2;
  perpendicular(prior.axis_world, &e1, &e2);
  const auto row = [&](const Eigen::Vector3d& direction) -> Vector6d {
    return (direction.transpose() * term.jacobian).transpose();
  };
  // A's eigen-decomposition, once a step: the three σ and the solve's basis read it (on a
  // paper-size scan this solve runs ~13 times a frame between the GPU's reductions).
  const Eigen::SelfAdjointEigenSolver<Matrix6d> surface(normal_matrix(sums));
  step.surface_sigma_rad = surface_sigma_rad(surface, row(prior.axis_world), variance_m2, degenerate_ratio);
  const double tilt1 = surface_sigma_rad(surface, row(e1), variance_m2, degenerate_ratio);
  const double tilt2 = surface_sigma_rad(surface, row(e2), variance_m2, degenerate_ratio);
  step.surface_tilt_sigma_rad = std::sqrt(0.5 * (tilt1 * tilt1 + tilt2 * tilt2));

  Vector6d b;
  for (int r = 0; r < 6; ++r) b(r) = sums[kTrackJtr + r];
  const Vector6d& values = surface.eigenvalues();  // ascending
  const double largest = values(5), smallest = values(0);
  step.condition = smallest > 0.0 ? largest / smallest : std::numeric_limits<double>::infinity();
  // The basis the step is solved in: the surface's trusted eigen-directions, with their
  // information and gradient, and those of its degenerate subspace that the prior decides.
  const Matrix6d& v = surface.eigenvectors();
  const bool any = largest > 0.0 && std::isfinite(largest);
  std::vector<Vector6d> basis;
  std::vector<double> surface_information, surface_gradient;
  Eigen::Matrix<double, 6, Eigen::Dynamic> degenerate(6, 0);
  for (int i = 0; i < 6; ++i) {
    if (any && trusted(values(i), largest, degenerate_ratio)) {
      basis.push_back(v.col(i));
      surface_information.push_back(values(i));
      surface_gradient.push_back(v.col(i).dot(b));
    } else {
      degenerate.conservativeResize(Eigen::NoChange, degenerate.cols() + 1);
      degenerate.rightCols<1>() = v.col(i);
    }
  }
  // The degenerate subspace, re-based by how much each direction turns (its rotation part's
  // singular vectors): a unit twist that turns by ω' (scaled, track_shared.h) turns about a line
  // at L·√(1/ω'² − 1) from the centre. A turn about a line through the surface (within √3 RMS
  // radii: ω' ≥ ½; a surface of revolution's spin about its own axis) is the prior's to decide,
  // since the prior is a rotation. The rest — slides, turns about far lines, which are slides
  // to first order — keep the guess as without a prior: the prior says nothing of translation,
  // and a slide with a trace of rotation in it (the noise's) would otherwise be pushed as far as
  // it takes to turn by what the prior asks, through a direction the surface does not check.
  constexpr double kMinRotationContent = 0.5;
  if (degenerate.cols() > 0 && variance_m2 > 0.0 && std::isfinite(variance_m2)) {
    const Eigen::JacobiSVD<Eigen::MatrixXd> turns(Eigen::MatrixXd(degenerate.bottomRows<3>()), Eigen::ComputeFullV);
    for (Eigen::Index k = 0; k < turns.singularValues().size(); ++k) {
      if (turns.singularValues()(k) < kMinRotationContent) continue;
      basis.push_back(degenerate * turns.matrixV().col(k));
      surface_information.push_back(0.0);
      surface_gradient.push_back(0.0);
    }
  }
  const Eigen::Index n = static_cast<Eigen::Index>(basis.size());
  step.degenerate = 6 - static_cast<int>(n);
  if (n == 0) return step;
  Eigen::Matrix<double, 6, Eigen::Dynamic> b_matrix(6, n);
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd g(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    b_matrix.col(k) = basis[static_cast<std::size_t>(k)];
    m(k, k) = surface_information[static_cast<std::size_t>(k)];
    g(k) = surface_gradient[static_cast<std::size_t>(k)];
  }
  // The prior's information against A's units (m²): s² Λ.
  if (variance_m2 > 0.0 && std::isfinite(variance_m2)) {
    const Eigen::Matrix3d lambda = variance_m2 * prior.information();
    const Eigen::Matrix<double, 3, Eigen::Dynamic> j = term.jacobian * b_matrix;
    m += j.transpose() * lambda * j;
    g += j.transpose() * lambda * term.residual_rad;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> combined(m);
  const double top = combined.eigenvalues()(n - 1);
  Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double value = combined.eigenvalues()(i);
    if (!(top > 0.0) || !(value > 1e-12 * top)) {
      ++step.degenerate;  // an admitted direction the prior does not reach after all
      continue;
    }
    const Eigen::VectorXd w = combined.eigenvectors().col(i);
    y -= w * (w.dot(g) / value);
  }
  step.twist = b_matrix * y;
  return step;
}

void report_pose_prior(const PosePrior& prior, const Pose& T_world_camera, const PriorStep& finest,
                       TrackingResult* result) {
  constexpr double kDeg = 180.0 / M_PI;
  const Eigen::Vector3d offset = pose_prior_offset_rad(prior, T_world_camera);
  const double about = prior.axis_world.dot(offset);
  result->prior = true;
  result->prior_offset_deg = about * kDeg;
  result->prior_tilt_offset_deg = (offset - about * prior.axis_world).norm() * kDeg;
  result->prior_surface_sigma_deg = finest.surface_sigma_rad * kDeg;
  result->prior_surface_tilt_sigma_deg = finest.surface_tilt_sigma_rad * kDeg;
  result->prior_sigma_deg = prior.sigma_rad * kDeg;
  result->prior_tilt_sigma_deg = prior.tilt_sigma_rad * kDeg;
}

}  // namespace sls::fusion
