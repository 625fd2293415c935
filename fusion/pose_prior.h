// A prior on the tracked pose for the ICP tracker (fusion/tracker.h), in information form: the
// registered camera's rotation expected at a given pose, about a given axis with one σ and
// about the axes perpendicular to it with another. A turntable scan's prior: the table's
// recorded angles say how far the object turned about the calibrated axis, to the table's
// repeatability (TurntableAxis::angle_sigma_deg), and that it turned about nothing else, to
// its wobble (TurntableAxis::tilt_sigma_deg).
//
// The term: φ = log(R_world_camera · R_priorᵀ) (radians, the world frame: the estimate's
// rotation beyond the prior's), E_prior = φᵀ Λ φ with Λ = a aᵀ / σ² + (I − a aᵀ) / σ_tilt²
// (a = axis_world, unit; an infinite σ contributes nothing). ICP's normal equations are those of
// E_icp = Σ w (n·(Tp − q))² in m², whose information is JᵀWJ / s², s² the point-to-plane
// residuals' variance (the inliers' mean square, the pixels taken as independent); the prior
// joins them as s² · JφᵀΛJφ (and s² · JφᵀΛφ), so the 6x6 system solved is the information form
// of both, scaled by s². Directions the surface constrains well (large eigenvalues of JᵀWJ)
// follow the surface; those it leaves weak (a surface of revolution turning about its own axis:
// a knob's spin) follow the prior; in between they are weighed by their information. σ → ∞
// adds nothing. Of the tracker's degenerate directions (TrackingOptions::degenerate_eigen_ratio:
// the surface's information there is not trusted), the turns about a line through the surface
// keep the prior's information alone; the slides keep the guess (solve_with_pose_prior).
//
// Only the rotation is constrained: where the axis lies (its point) does not enter, since a
// rotation about any parallel line is the same rotation plus a translation, and the
// translation is the surface's to decide (a knob's own axis may stand off the table's).
//
// The Jacobian is taken in the tracker's parameterisation (track_shared.h): the update is
// T_model_live ← Tr(c) · exp([ρ, ω'/L]) · Tr(−c) · T_model_live, whose rotation is exp(ω'/L)
// whatever c and ρ, so ∂φ/∂[ρ, ω'] = [0, J_l⁻¹(φ) R_world_model / L] (J_l: SO(3)'s left
// Jacobian); ρ does not enter.
#pragma once

#include <limits>

#include <Eigen/Core>

#include "sdk/core/pose.h"

namespace sls::fusion {

struct PosePrior {
  static constexpr double kNone = std::numeric_limits<double>::infinity();

  Pose T_world_camera;                                   // where the prior expects the live camera
  Eigen::Vector3d axis_world = Eigen::Vector3d::UnitZ();  // unit
  double sigma_rad = kNone;       // σ of the rotation about the axis; infinity: free
  double tilt_sigma_rad = kNone;  // σ of the rotation about each axis perpendicular to it; infinity: free
  bool active() const { return sigma_rad < kNone || tilt_sigma_rad < kNone; }
  // Λ (rad⁻²), world frame.
  Eigen::Matrix3d information() const;
  // Throws sls::Error(kInvalidArgument) naming the bad value: a pose or axis not finite, an
  // axis not of unit length, a σ not positive (0 would be an infinite information; infinity
  // leaves the direction free).
  void validate() const;
};

// The prior's residual φ at an estimate T_world_camera = T_world_model · T_model_live, and its
// Jacobian with respect to the tracker's update [ρ, ω'] about a centre with RMS radius
// scale_m (L).
struct PosePriorTerm {
  Eigen::Vector3d residual_rad = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 3, 6> jacobian = Eigen::Matrix<double, 3, 6>::Zero();
};
PosePriorTerm pose_prior_term(const PosePrior& prior, const Pose& T_world_model, const Pose& T_model_live,
                              double scale_m);

// The rotation of a pose beyond the prior's, φ (rad, world frame): aᵀφ is its turn about the
// axis, |φ − a aᵀφ| its tilt.
Eigen::Vector3d pose_prior_offset_rad(const PosePrior& prior, const Pose& T_world_camera);

// SO(3)'s inverse left Jacobian: log(exp(δ) · exp(φ)) = φ + J_l⁻¹(φ) δ + O(δ²).
Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& phi);

// One Gauss–Newton step of the tracker with the prior (fusion/tracker.cpp's solve() without):
// `sums` is one reduction's system in track_shared.h's layout (the 21 of JᵀJ's upper triangle,
// row-major, then the 6 of Jᵀr; the ICP's, the photometric term's added), `variance_m2` its
// residuals' s². The surface's directions are those of its normal matrix A; the ones below
// degenerate_ratio of its largest eigenvalue are degenerate as without a prior (their
// information is not trusted: a rim, noise); the others keep theirs with the prior's added:
// M = A_trusted + s² JφᵀΛJφ, g = b_trusted + s² JφᵀΛφ, and the step −M⁺g over M's directions
// above 1e-12 of its largest. Of the degenerate subspace, the directions that turn about a line
// within √3 RMS radii of the centre (rotation content ≥ ½ in the scaled twist: a surface of
// revolution's spin about its own axis) join M with the prior's information alone; the rest
// (slides, and turns about far lines, which are slides to first order) keep the guess, as do
// directions the prior does not reach: a rotation prior says nothing of translation, and a
// slide with a trace of the noise's rotation in it would otherwise be pushed as far as it takes
// to turn by what the prior asks (tens of µm along a knurled shaft for 0.0005° with an exact
// table's tilt). So where the surface is silent about a turn the prior's rotation is taken
// whatever its σ, and where it speaks the two are weighed; σ → ∞ leaves the surface's step.
// surface_*: the σ of the rotation about the prior's axis and of its tilt (the RMS over the two
// perpendicular axes) that the surface's trusted directions give (surface_sigma_rad).
struct PriorStep {
  Vector6d twist = Vector6d::Zero();  // [ρ, ω'] of track_shared.h
  int degenerate = 0;                 // directions that keep the guess
  double condition = 0.0;             // of the surface's A (as TrackingResult::condition)
  double surface_sigma_rad = 0.0;
  double surface_tilt_sigma_rad = 0.0;
};
PriorStep solve_with_pose_prior(const double* sums, const PosePrior& prior, double variance_m2,
                                const Pose& T_world_model, const Pose& T_model_live, double scale_m,
                                double degenerate_ratio);

struct TrackingResult;
// The tracker's report of the prior (TrackingResult::prior_*): the offsets at its final
// estimate, the surface's σ from the finest level's last step.
void report_pose_prior(const PosePrior& prior, const Pose& T_world_camera, const PriorStep& finest,
                       TrackingResult* result);

// The σ (radians) of a rotation component, `jacobian` its row (∂/∂[ρ, ω']), that the surface
// alone gives: jᵀ Cov j with Cov = s² A⁻¹ (A: the normal matrix of the sums, without the prior)
// over A's directions at or above min_ratio of its largest eigenvalue (at least 1e-12);
// infinity when the rotation moves along one of the others (the surface leaves it free).
double surface_sigma_rad(const double* sums, const Vector6d& jacobian, double variance_m2, double min_ratio = 0.0);

}  // namespace sls::fusion
