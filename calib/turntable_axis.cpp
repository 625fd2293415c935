#include "calib/turntable_axis.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>

#include <Eigen/Geometry>
#include <Eigen/QR>
#include <fmt/format.h>

#include "calib/least_squares.h"
#include "sdk/core/camera_model_shared.h"

namespace sls::calib {
namespace {

constexpr double kDegree = M_PI / 180.0;

Pose rotation_about_z(double angle_deg) {
  return Pose(Eigen::Quaterniond(Eigen::AngleAxisd(angle_deg * kDegree, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d::Zero());
}

// Two unit vectors perpendicular to d and to each other.
void perpendicular_basis(const Eigen::Vector3d& d, Eigen::Vector3d* e1, Eigen::Vector3d* e2) {
  const Eigen::Vector3d seed = std::fabs(d.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  *e1 = (seed - seed.dot(d) * d).normalized();
  *e2 = d.cross(*e1);
}

// The axis frame: z along d, x from e1 (fixed, so the frame's turn about d stays put).
Pose axis_frame(const Eigen::Vector3d& d, const Eigen::Vector3d& e1, const Eigen::Vector3d& point) {
  Eigen::Matrix3d r;
  r.col(2) = d;
  r.col(0) = (e1 - e1.dot(d) * d).normalized();
  r.col(1) = d.cross(r.col(0));
  return Pose(r, point);
}

Eigen::Vector2d predict(const CameraIntrinsics& c, const Eigen::Vector3d& p) {
  Vec2d pixel{};
  project(c, Vec3d{p.x(), p.y(), p.z()}, &pixel);
  return {pixel.x, pixel.y};
}

}  // namespace

AxisFit fit_turntable_axis(const std::vector<ViewObservation>& views, const std::vector<ViewSolution>& solutions,
                           const ScannerCalibration& calibration, const BoardSpec& board) {
  AxisFit fit;
  std::vector<std::size_t> used;
  for (std::size_t v = 0; v < views.size(); ++v) {
    if (solutions[v].used && views[v].turntable_angle_deg) used.push_back(v);
  }
  if (used.size() < 3) {
    fit.reason = fmt::format("{} usable board views carry a turntable angle (need 3)", used.size());
    return fit;
  }
  // Angles relative to the first view, wrapped to (−180°, 180°]: a table reports −40° as 320°.
  std::vector<double> angles(views.size(), 0.0);
  const double reference = *views[used[0]].turntable_angle_deg;
  for (std::size_t v : used) {
    const double delta = std::remainder(*views[v].turntable_angle_deg - reference, 360.0);
    angles[v] = reference + delta;
  }
  double lo = 1e300, hi = -1e300;
  for (std::size_t v : used) {
    lo = std::min(lo, angles[v]);
    hi = std::max(hi, angles[v]);
  }
  fit.angle_span_deg = hi - lo;
  if (fit.angle_span_deg < 10.0) {
    fit.reason = fmt::format("the turntable views span {:.1f}° (need 10°)", fit.angle_span_deg);
    return fit;
  }

  // Closed form: each view relative to the first is a rotation by Δθ about the axis.
  const Pose& first = solutions[used[0]].T_camera_board;
  const double first_angle = angles[used[0]];
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();
  std::vector<Pose> relative;
  for (std::size_t k = 1; k < used.size(); ++k) {
    const Pose motion = solutions[used[k]].T_camera_board * first.inverse();
    relative.push_back(motion);
    const Eigen::AngleAxisd aa(motion.rotation());
    const double delta = angles[used[k]] - first_angle;
    direction += (delta >= 0.0 ? 1.0 : -1.0) * aa.angle() * aa.axis();
  }
  if (!(direction.norm() > 1e-9)) {
    fit.reason = "the turntable views do not rotate the board";
    return fit;
  }
  direction.normalize();
  const Eigen::Vector3d board_centre_local(0.5 * (board.inner_cols - 1) * board.square_m,
                                           0.5 * (board.inner_rows - 1) * board.square_m, 0.0);
  const Eigen::Vector3d board_centre = first * board_centre_local;
  // (I − R) p = t for every motion, and p's position along the axis at the board's centre.
  Eigen::MatrixXd a(static_cast<Eigen::Index>(3 * relative.size() + 1), 3);
  Eigen::VectorXd b(a.rows());
  for (std::size_t k = 0; k < relative.size(); ++k) {
    a.block<3, 3>(static_cast<Eigen::Index>(3 * k), 0) = Eigen::Matrix3d::Identity() - relative[k].rotation();
    b.segment<3>(static_cast<Eigen::Index>(3 * k)) = relative[k].translation();
  }
  a.row(a.rows() - 1) = direction.transpose();
  b(b.rows() - 1) = direction.dot(board_centre);
  const Eigen::Vector3d point = a.colPivHouseholderQr().solve(b);

  // Refinement: axis direction (2), point across the axis (2), board on the table (6).
  Eigen::Vector3d e1, e2;
  perpendicular_basis(direction, &e1, &e2);
  const Pose T_axis_board0 = rotation_about_z(-first_angle) * axis_frame(direction, e1, point).inverse() * first;
  const std::vector<Eigen::Vector3d> board_points = board.object_points();
  std::vector<std::vector<Eigen::Vector3d>> objects(views.size());  // per view, its corners' points
  std::size_t corners_used = 0;
  for (std::size_t v : used) {
    objects[v] = view_object_points(views[v], board_points);
    corners_used += objects[v].size();
  }
  const Pose T_projector_camera = calibration.T_camera_projector.inverse();
  const auto model = [&](const Eigen::VectorXd& x, Eigen::Vector3d* d, Eigen::Vector3d* p, Pose* T_axis_board) {
    *d = (direction + x(0) * e1 + x(1) * e2).normalized();
    *p = point + x(2) * e1 + x(3) * e2;
    *T_axis_board = Pose::exp(x.segment<6>(4)) * T_axis_board0;
  };
  // One view's corner residuals (camera, then projector where it has the corner: 4 per corner)
  // at a board pose, into r from `row` on.
  const auto view_residuals = [&](std::size_t v, const Pose& T_camera_board, Eigen::VectorXd* r, Eigen::Index row) {
    const Pose T_projector_board = T_projector_camera * T_camera_board;
    const std::vector<Eigen::Vector3d>& object = objects[v];
    for (std::size_t c = 0; c < object.size(); ++c, row += 4) {
      r->segment<2>(row) = views[v].camera_corners[c] - predict(calibration.camera, T_camera_board * object[c]);
      if (views[v].projector.valid[c] != 0) {
        r->segment<2>(row + 2) =
            views[v].projector.corners[c] - predict(calibration.projector, T_projector_board * object[c]);
      }
    }
  };
  const auto residuals = [&](const Eigen::VectorXd& x, Eigen::VectorXd* r) {
    Eigen::Vector3d d, p;
    Pose T_axis_board;
    model(x, &d, &p, &T_axis_board);
    const Pose T_camera_axis = axis_frame(d, e1, p);
    r->setZero(static_cast<Eigen::Index>(4 * corners_used));
    Eigen::Index row = 0;
    for (std::size_t v : used) {
      view_residuals(v, T_camera_axis * rotation_about_z(angles[v]) * T_axis_board, r, row);
      row += static_cast<Eigen::Index>(4 * objects[v].size());
    }
  };
  const double length = board.square_m * std::max(board.inner_cols, board.inner_rows);
  Eigen::VectorXd scale(10);
  scale << 1.0, 1.0, length, length, length, length, length, 1.0, 1.0, 1.0;
  const LeastSquaresResult solved = minimize_least_squares(residuals, Eigen::VectorXd::Zero(10), scale, 50);
  Eigen::Vector3d d, p;
  Pose T_axis_board;
  model(solved.x, &d, &p, &T_axis_board);
  // Report the axis' point nearest the board's centre (the first view's), where it matters.
  const Eigen::Vector3d centre = axis_frame(d, e1, p) * rotation_about_z(first_angle) * T_axis_board * board_centre_local;
  fit.axis.direction_camera = d;
  fit.axis.point_camera = p + d * d.dot(centre - p);
  fit.views = static_cast<int>(used.size());
  // The RMS over observed corners only (the unobserved projector slots are zeros).
  std::size_t observed = 0;
  for (std::size_t v : used) observed += objects[v].size() + static_cast<std::size_t>(views[v].projector.valid_count());
  fit.rms_px = solved.rms * std::sqrt(static_cast<double>(4 * corners_used) / static_cast<double>(observed));
  fit.fitted = true;

  // The table's repeatability (AxisFit::angle_sigma_deg, tilt_sigma_deg): each view's board
  // turned about the fitted axis, the axis and the mount held, to fit its corners best, then
  // tilted about the axis frame's x and y (through the axis point near the board) with that
  // turn held (Gauss–Newton: the corners move almost linearly over millidegrees; the turn
  // first and alone, since the tilts, free with it, take up part of what the axis' fit left of
  // the turns), and those angles' σ from the corners' noise: σ_px² per coordinate from the
  // residuals left after them (the table's own errors taken out), over the coordinates less
  // the parameters (10, and 3 a view).
  const Pose T_camera_axis = axis_frame(d, e1, p);
  std::vector<Eigen::Vector3d> turns, unit_variances;  // per view: degrees; per σ_px²
  double residual_squares = 0.0;
  for (std::size_t v : used) {
    const Eigen::Index rows = static_cast<Eigen::Index>(4 * objects[v].size());
    const auto residual_at = [&](const Eigen::Vector3d& turn_deg, Eigen::VectorXd* r) {
      const double angle = turn_deg.norm();
      const Pose turn(Eigen::Quaterniond(Eigen::AngleAxisd(
                          angle * kDegree, angle > 0.0 ? Eigen::Vector3d(turn_deg / angle) : Eigen::Vector3d::UnitZ())),
                      Eigen::Vector3d::Zero());
      r->setZero(rows);
      view_residuals(v, T_camera_axis * turn * rotation_about_z(angles[v]) * T_axis_board, r, 0);
    };
    // Gauss–Newton over `components` (numeric Jacobian); their information back.
    Eigen::Vector3d turn = Eigen::Vector3d::Zero();
    const auto refine = [&](std::initializer_list<int> components) {
      constexpr double kStepDeg = 1e-3;
      const Eigen::Index count = static_cast<Eigen::Index>(components.size());
      Eigen::MatrixXd information(count, count);
      for (int iteration = 0; iteration < 3; ++iteration) {
        Eigen::VectorXd r;
        residual_at(turn, &r);
        Eigen::MatrixXd jacobian(rows, count);
        Eigen::Index column = 0;
        for (const int k : components) {
          Eigen::VectorXd plus, minus;
          residual_at(turn + kStepDeg * Eigen::Vector3d::Unit(k), &plus);
          residual_at(turn - kStepDeg * Eigen::Vector3d::Unit(k), &minus);
          jacobian.col(column++) = (plus - minus) / (2.0 * kStepDeg);
        }
        information = jacobian.transpose() * jacobian;
        const Eigen::VectorXd step = information.ldlt().solve(jacobian.transpose() * r);
        column = 0;
        for (const int k : components) turn(k) -= step(column++);
      }
      return information;
    };
    const Eigen::MatrixXd about = refine({2});
    const Eigen::MatrixXd across = refine({0, 1});
    Eigen::VectorXd r;
    residual_at(turn, &r);
    residual_squares += r.squaredNorm();
    turns.push_back(turn);
    const Eigen::Matrix2d across_inverse = Eigen::Matrix2d(across).inverse();
    Eigen::Vector3d unit(across_inverse(0, 0), across_inverse(1, 1), 1.0 / about(0, 0));
    unit_variances.push_back(unit.allFinite() ? unit : Eigen::Vector3d::Zero());
  }
  const double n = static_cast<double>(used.size());
  const double coordinates = 2.0 * static_cast<double>(observed);
  const double coordinate_variance = residual_squares / std::max(1.0, coordinates - 10.0 - 3.0 * n);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero(), noise = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < turns.size(); ++k) {
    mean += turns[k] / n;
    noise += coordinate_variance * unit_variances[k] / n;
  }
  Eigen::Vector3d spread = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& turn : turns) {
    spread += (turn - mean).cwiseAbs2();
    fit.angle_residuals_deg.push_back(turn.z());
    fit.tilt_residuals_deg.push_back({turn.x(), turn.y()});
  }
  const auto separated = [](double sigma, double noise_sigma) {
    return std::sqrt(std::max(0.0, sigma * sigma - noise_sigma * noise_sigma));
  };
  // The mount's turn takes the angles' mean and the axis' point across the view a turn
  // growing with the angle (a board's turn is seen mostly as its shift across the view: views
  // − 2 degrees of freedom; measured on synthetic captures, views − 1 reads 12 % low); the
  // axis' direction takes the tilts' means.
  fit.angle_sigma_deg = std::sqrt(spread.z() / std::max(1.0, n - 2.0));
  fit.angle_noise_deg = std::sqrt(noise.z());
  fit.angle_jitter_deg = separated(fit.angle_sigma_deg, fit.angle_noise_deg);
  fit.tilt_sigma_deg = std::sqrt((spread.x() + spread.y()) / (2.0 * (n - 1.0)));
  fit.tilt_noise_deg = std::sqrt(0.5 * (noise.x() + noise.y()));
  fit.tilt_wobble_deg = separated(fit.tilt_sigma_deg, fit.tilt_noise_deg);
  // Beyond what a calibration may hold the recorded angles are not the table's (misrecorded,
  // another unit): the axis is kept, the σ left unknown.
  if (fit.angle_sigma_deg <= TurntableAxis::kMaxSigmaDeg) fit.axis.angle_sigma_deg = fit.angle_sigma_deg;
  if (fit.tilt_sigma_deg <= TurntableAxis::kMaxSigmaDeg) fit.axis.tilt_sigma_deg = fit.tilt_sigma_deg;
  return fit;
}

}  // namespace sls::calib
