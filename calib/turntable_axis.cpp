#include "calib/turntable_axis.h"

#include <algorithm>
#include <cmath>

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
  const std::vector<Eigen::Vector3d> object = board.object_points();
  const Pose T_projector_camera = calibration.T_camera_projector.inverse();
  const auto model = [&](const Eigen::VectorXd& x, Eigen::Vector3d* d, Eigen::Vector3d* p, Pose* T_axis_board) {
    *d = (direction + x(0) * e1 + x(1) * e2).normalized();
    *p = point + x(2) * e1 + x(3) * e2;
    *T_axis_board = Pose::exp(x.segment<6>(4)) * T_axis_board0;
  };
  const auto residuals = [&](const Eigen::VectorXd& x, Eigen::VectorXd* r) {
    Eigen::Vector3d d, p;
    Pose T_axis_board;
    model(x, &d, &p, &T_axis_board);
    const Pose T_camera_axis = axis_frame(d, e1, p);
    r->setZero(static_cast<Eigen::Index>(4 * object.size() * used.size()));
    Eigen::Index row = 0;
    for (std::size_t v : used) {
      const Pose T_camera_board = T_camera_axis * rotation_about_z(angles[v]) * T_axis_board;
      const Pose T_projector_board = T_projector_camera * T_camera_board;
      for (std::size_t c = 0; c < object.size(); ++c, row += 4) {
        r->segment<2>(row) = views[v].camera_corners[c] - predict(calibration.camera, T_camera_board * object[c]);
        if (views[v].projector.valid[c] != 0) {
          r->segment<2>(row + 2) =
              views[v].projector.corners[c] - predict(calibration.projector, T_projector_board * object[c]);
        }
      }
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
  for (std::size_t v : used) observed += object.size() + static_cast<std::size_t>(views[v].projector.valid_count());
  fit.rms_px = solved.rms * std::sqrt(static_cast<double>(4 * object.size() * used.size()) / static_cast<double>(observed));
  fit.fitted = true;
  return fit;
}

}  // namespace sls::calib
