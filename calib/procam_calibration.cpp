#include "calib/procam_calibration.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "calib/least_squares.h"
#include "calib/opencv_conversions.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/error.h"

namespace sls::calib {
namespace {

constexpr double kDegree = M_PI / 180.0;

Eigen::Vector2d predict(const CameraIntrinsics& c, const Eigen::Vector3d& point_camera) {
  Vec2d pixel{};
  project(c, Vec3d{point_camera.x(), point_camera.y(), point_camera.z()}, &pixel);
  return {pixel.x, pixel.y};
}

double obliquity_deg(const Pose& T_camera_board) {
  const Eigen::Vector3d normal = T_camera_board.rotation().col(2);
  return std::acos(std::min(1.0, std::fabs(normal.z()))) / kDegree;
}

struct Subsets {
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> points;
  std::vector<std::vector<cv::Point2f>> second;  // the projector's, for the joint subsets
};

// Per used view, the corners `take(view, corner)` accepts: camera (and projector) points.
// objects[v]: view v's corners in the board frame (view_object_points).
template <typename Take>
Subsets collect(const std::vector<ViewObservation>& views, const std::vector<ViewSolution>& solutions,
                const std::vector<std::vector<Eigen::Vector3d>>& objects, bool projector_points, bool with_second,
                Take take) {
  Subsets out;
  for (std::size_t v = 0; v < views.size(); ++v) {
    if (!solutions[v].used) continue;
    out.object.emplace_back();
    out.points.emplace_back();
    out.second.emplace_back();
    const std::vector<Eigen::Vector3d>& object = objects[v];
    for (std::size_t c = 0; c < object.size(); ++c) {
      if (!take(v, c)) continue;
      out.object.back().push_back(to_cv(std::vector<Eigen::Vector3d>{object[c]}).front());
      out.points.back().push_back(
          to_cv(projector_points ? views[v].projector.corners[c] : views[v].camera_corners[c]));
      if (with_second) out.second.back().push_back(to_cv(views[v].projector.corners[c]));
    }
  }
  return out;
}

// Corners whose residual under a first solve exceeds kOutlierSigmas robust standard
// deviations (σ from the median residual: for 2-D Gaussian errors the median length is
// 1.177 σ) are mislocated (a corner in a defocused far end, a speck on the board): they are
// dropped and the device solved again. At 5 σ a Gaussian error is dropped once in 10^5.
constexpr double kOutlierSigmas = 5.0;
// A residual below this is never an outlier, however small the median (exact corners).
constexpr double kOutlierFloorPx = 0.1;

// A narrow field of view makes focal length and distance nearly interchangeable: the cost's
// valley is long and flat, and OpenCV's default stop (30 iterations) leaves the focal length
// 0.4 % off even from exact corners. Run to convergence instead. (With p1, p2 or k2 held the
// last steps are slow, 9 s of the demo capture's solve, but a looser 1e-10 stops early in the
// flat valley: the camera's principal point 1.2 px from the converged one.)
const cv::TermCriteria kConvergence(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 500, 1e-15);

int reject_outliers(const std::vector<ViewObservation>& views, std::vector<ViewSolution>* solutions,
                    const std::vector<std::vector<Eigen::Vector3d>>& objects, const cv::Mat& k, const cv::Mat& d,
                    const std::vector<cv::Mat>& rvecs, const std::vector<cv::Mat>& tvecs, bool projector) {
  std::vector<std::pair<std::size_t, std::size_t>> where;
  std::vector<double> lengths;
  std::size_t used = 0;
  for (std::size_t v = 0; v < views.size(); ++v) {
    ViewSolution& s = (*solutions)[v];
    if (!s.used) continue;
    const std::vector<Eigen::Vector3d>& object = objects[v];
    std::vector<cv::Point2f> predicted;
    cv::projectPoints(to_cv(object), rvecs[used], tvecs[used], k, d, predicted);
    ++used;
    std::vector<std::uint8_t>& inlier = projector ? s.projector_inlier : s.camera_inlier;
    for (std::size_t c = 0; c < object.size(); ++c) {
      if (inlier[c] == 0) continue;
      const Eigen::Vector2d observed = projector ? views[v].projector.corners[c] : views[v].camera_corners[c];
      lengths.push_back(std::hypot(observed.x() - static_cast<double>(predicted[c].x),
                                   observed.y() - static_cast<double>(predicted[c].y)));
      where.emplace_back(v, c);
    }
  }
  if (lengths.empty()) return 0;
  std::vector<double> sorted = lengths;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
  const double threshold = std::max(kOutlierFloorPx, kOutlierSigmas * sorted[sorted.size() / 2] / 1.177);
  int rejected = 0;
  for (std::size_t i = 0; i < lengths.size(); ++i) {
    if (lengths[i] <= threshold) continue;
    ViewSolution& s = (*solutions)[where[i].first];
    (projector ? s.projector_inlier : s.camera_inlier)[where[i].second] = 0;
    ++rejected;
  }
  return rejected;
}

// Whether the fuller of two nested fits (`extra` more parameters, `parameters` in all) lowers
// the residual significantly: its F statistic against F(extra, ∞)'s value at p = 0.001.
// Corners are independent and Gaussian to the extent the outlier rejection made them so.
bool significant(double rms_simple, double rms_full, std::size_t corners, int parameters, int extra) {
  const double n = static_cast<double>(corners);
  const double dof = 2.0 * n - parameters;
  if (dof <= 0.0 || rms_full <= 0.0) return false;
  const double critical = extra == 1 ? 10.83 : 6.91;  // χ²(extra) at p = 0.001, over extra
  const double sse_simple = rms_simple * rms_simple * n, sse_full = rms_full * rms_full * n;
  return ((sse_simple - sse_full) / extra) / (sse_full / dof) > critical;
}

std::size_t corner_count(const std::vector<std::vector<cv::Point2f>>& points) {
  std::size_t n = 0;
  for (const auto& view : points) n += view.size();
  return n;
}

double rms_of(const std::vector<Eigen::Vector2d>& residuals, const std::vector<std::uint8_t>* valid) {
  double sum = 0.0;
  int count = 0;
  for (std::size_t i = 0; i < residuals.size(); ++i) {
    if (valid != nullptr && (*valid)[i] == 0) continue;
    sum += residuals[i].squaredNorm();
    ++count;
  }
  return count > 0 ? std::sqrt(sum / count) : 0.0;
}

}  // namespace

void view_residuals(const ViewObservation& view, const ScannerCalibration& calibration, const BoardSpec& board,
                    const Pose& T_camera_board, ViewSolution* solution) {
  const std::vector<Eigen::Vector3d> object = view_object_points(view, board.object_points());
  const Pose T_projector_board = calibration.T_camera_projector.inverse() * T_camera_board;
  solution->camera_residuals_px.assign(object.size(), Eigen::Vector2d::Zero());
  solution->projector_residuals_px.assign(object.size(), Eigen::Vector2d::Zero());
  for (std::size_t c = 0; c < object.size(); ++c) {
    solution->camera_residuals_px[c] = view.camera_corners[c] - predict(calibration.camera, T_camera_board * object[c]);
    if (view.projector.valid[c] != 0) {
      solution->projector_residuals_px[c] =
          view.projector.corners[c] - predict(calibration.projector, T_projector_board * object[c]);
    }
  }
  solution->camera_rms_px =
      rms_of(solution->camera_residuals_px, solution->camera_inlier.empty() ? nullptr : &solution->camera_inlier);
  solution->projector_rms_px = rms_of(solution->projector_residuals_px, solution->projector_inlier.empty()
                                                                           ? &view.projector.valid
                                                                           : &solution->projector_inlier);
}

Pose refine_board_pose(const ViewObservation& view, const ScannerCalibration& calibration, const BoardSpec& board,
                       const Pose& initial, const ViewSolution* masks, double projector_weight) {
  const auto camera_used = [&](std::size_t c) { return masks == nullptr || masks->camera_inlier[c] != 0; };
  const auto projector_used = [&](std::size_t c) {
    return masks == nullptr ? view.projector.valid[c] != 0 : masks->projector_inlier[c] != 0;
  };
  const std::vector<Eigen::Vector3d> object = view_object_points(view, board.object_points());
  const Pose T_projector_camera = calibration.T_camera_projector.inverse();
  const auto residuals = [&](const Eigen::VectorXd& x, Eigen::VectorXd* r) {
    const Pose T_camera_board = Pose::exp(x.head<6>()) * initial;
    const Pose T_projector_board = T_projector_camera * T_camera_board;
    r->resize(static_cast<Eigen::Index>(4 * object.size()));
    for (std::size_t c = 0; c < object.size(); ++c) {
      Eigen::Vector2d camera = Eigen::Vector2d::Zero(), projector = Eigen::Vector2d::Zero();
      if (camera_used(c)) camera = view.camera_corners[c] - predict(calibration.camera, T_camera_board * object[c]);
      if (projector_used(c)) {
        projector = view.projector.corners[c] - predict(calibration.projector, T_projector_board * object[c]);
      }
      r->segment<2>(static_cast<Eigen::Index>(4 * c)) = camera;
      r->segment<2>(static_cast<Eigen::Index>(4 * c + 2)) = projector_weight * projector;
    }
  };
  const double length = board.square_m * std::max(board.inner_cols, board.inner_rows);
  Eigen::VectorXd scale(6);
  scale << length, length, length, 1.0, 1.0, 1.0;
  const LeastSquaresResult fit = minimize_least_squares(residuals, Eigen::VectorXd::Zero(6), scale, 30);
  return Pose::exp(fit.x.head<6>()) * initial;
}

ProcamCalibration calibrate_procam(const std::vector<ViewObservation>& views, const ProcamSettings& settings,
                                   const ProgressCallback& progress) {
  settings.board.validate();
  if (settings.camera_width <= 0 || settings.camera_height <= 0 || settings.projector_width <= 0 ||
      settings.projector_height <= 0) {
    throw_error(ErrorCode::kInvalidArgument, "calibration: camera {}x{} or projector {}x{} size missing",
                settings.camera_width, settings.camera_height, settings.projector_width, settings.projector_height);
  }
  ProcamCalibration result;
  result.views.resize(views.size());
  const std::vector<Eigen::Vector3d> board_points = settings.board.object_points();
  // OpenCV solves in board squares, not metres: translations of ~100 squares beside focal
  // lengths of thousands of pixels keep its unscaled Levenberg–Marquardt well conditioned
  // (in metres, translations of 0.1 left the focal length 0.4 % off even from exact corners).
  const double unit = settings.board.square_m;
  // Per view, its corners' board points (a ChArUco view has those it found), in squares.
  std::vector<std::vector<Eigen::Vector3d>> object_units(views.size());
  for (std::size_t v = 0; v < views.size(); ++v) {
    ViewSolution& s = result.views[v];
    s.used = views[v].rejected_reason.empty() && views[v].board_found;
    s.rejected_reason = views[v].rejected_reason;
    if (!s.used) continue;
    for (const Eigen::Vector3d& p : view_object_points(views[v], board_points)) object_units[v].push_back(p / unit);
    s.camera_inlier.assign(object_units[v].size(), 1);
    s.projector_inlier = views[v].projector.valid;
  }
  const int flags = settings.estimate_k3 ? 0 : cv::CALIB_FIX_K3;
  const cv::Size camera_size(settings.camera_width, settings.camera_height);
  const cv::Size projector_size(settings.projector_width, settings.projector_height);
  const auto camera_take = [&](std::size_t v, std::size_t c) { return result.views[v].camera_inlier[c] != 0; };
  const auto projector_take = [&](std::size_t v, std::size_t c) { return result.views[v].projector_inlier[c] != 0; };
  const auto require_views = [&] {
    int used = 0;
    for (const ViewSolution& s : result.views) used += s.used ? 1 : 0;
    if (used >= settings.min_views) return;
    std::string reasons;
    for (std::size_t v = 0; v < views.size(); ++v) {
      if (!result.views[v].used) reasons += fmt::format("; {}: {}", views[v].name, result.views[v].rejected_reason);
    }
    throw_error(ErrorCode::kInvalidArgument, "calibration needs {} usable board views, {} of {} are usable{}",
                settings.min_views, used, views.size(), reasons);
  };

  // The camera alone: views it sees too obliquely are dropped, then mislocated corners, each
  // followed by a new solve (with p1, p2 free); the last solve chooses the distortion model.
  cv::Mat camera_k, camera_d, projector_k, projector_d;
  std::vector<cv::Mat> rvecs, tvecs;
  using Tangential = ProcamSettings::Tangential;
  // Solves one device over `subsets`. With `choose_model` (and kAuto) the distortion model is
  // chosen: p1, p2 are dropped (fixed at 0) unless they lower the residual significantly,
  // then k2 likewise. Returns whether p1, p2 and k2 are free.
  struct Model {
    bool tangential = true, k2 = true;
  };
  const auto solve_device = [&](const Subsets& subsets, const cv::Size& size, cv::Mat* k, cv::Mat* d, double* rms,
                                bool choose_model) {
    Model model;
    model.tangential = settings.tangential != Tangential::kZero;
    const auto model_flags = [&](const Model& m) {
      return flags | (m.tangential ? 0 : cv::CALIB_ZERO_TANGENT_DIST) | (m.k2 ? 0 : cv::CALIB_FIX_K2);
    };
    *k = cv::Mat();
    *d = cv::Mat();
    *rms = cv::calibrateCamera(subsets.object, subsets.points, size, *k, *d, rvecs, tvecs, model_flags(model),
                               kConvergence);
    if (!choose_model || settings.tangential != Tangential::kAuto) return model;
    const std::size_t corners = corner_count(subsets.points);
    const int views_in = static_cast<int>(subsets.points.size());
    // Tries `simpler` (`dropped` parameters fewer); keeps it unless the current model is
    // significantly better.
    const auto try_simpler = [&](const Model& simpler, int dropped) {
      cv::Mat k_simple, d_simple;
      std::vector<cv::Mat> rvecs_simple, tvecs_simple;
      const double rms_simple = cv::calibrateCamera(subsets.object, subsets.points, size, k_simple, d_simple,
                                                    rvecs_simple, tvecs_simple, model_flags(simpler), kConvergence);
      const int parameters = 4 + (settings.estimate_k3 ? 1 : 0) + 1 + (model.k2 ? 1 : 0) +
                             (model.tangential ? 2 : 0) + 6 * views_in;
      if (significant(rms_simple, *rms, corners, parameters, dropped)) return;
      model = simpler;
      *k = k_simple;
      *d = d_simple;
      *rms = rms_simple;
      rvecs = std::move(rvecs_simple);
      tvecs = std::move(tvecs_simple);
    };
    try_simpler({false, true}, 2);
    try_simpler({model.tangential, false}, 1);
    return model;
  };
  const auto solve_camera = [&](bool choose_model) {
    require_views();
    const Subsets subsets = collect(views, result.views, object_units, false, false, camera_take);
    const Model model = solve_device(subsets, camera_size, &camera_k, &camera_d, &result.camera_rms_px, choose_model);
    result.camera_tangential = model.tangential;
    result.camera_k2 = model.k2;
  };
  report_progress(progress, {"solve", 0, kProcamSolveSteps, "camera"});
  solve_camera(false);
  bool dropped = false;
  std::size_t k = 0;
  for (ViewSolution& s : result.views) {
    if (!s.used) continue;
    s.T_camera_board = pose_from(rvecs[k], tvecs[k] * unit);
    s.obliquity_deg = obliquity_deg(s.T_camera_board);
    ++k;
    if (s.obliquity_deg > settings.max_obliquity_deg) {
      s.used = false;
      s.rejected_reason = fmt::format("too oblique: the board is tilted {:.0f}° from the camera's axis (limit {:.0f}°)",
                                      s.obliquity_deg, settings.max_obliquity_deg);
      dropped = true;
    }
  }
  if (dropped) solve_camera(false);
  result.camera_outliers =
      reject_outliers(views, &result.views, object_units, camera_k, camera_d, rvecs, tvecs, false);
  solve_camera(true);

  const auto solve_projector = [&](bool choose_model) {
    const Subsets subsets = collect(views, result.views, object_units, true, false, projector_take);
    const Model model =
        solve_device(subsets, projector_size, &projector_k, &projector_d, &result.projector_rms_px, choose_model);
    result.projector_tangential = model.tangential;
    result.projector_k2 = model.k2;
  };
  report_progress(progress, {"solve", 1, kProcamSolveSteps, "projector"});
  solve_projector(false);
  result.projector_outliers =
      reject_outliers(views, &result.views, object_units, projector_k, projector_d, rvecs, tvecs, true);
  solve_projector(true);

  // One joint refinement of both devices and their pose, over the corners both kept. Each
  // device's residuals weigh 1/σ² (σ its RMS alone): scaling the projector's pixels by
  // w = σ_camera / σ_projector scales its residuals by w and its camera matrix by w, nothing
  // else (distortion acts before the camera matrix), so stereoCalibrate minimises the weighted
  // sum; the matrix is scaled back after. p1, p2 (k2) stay free if either device's model has them.
  report_progress(progress, {"solve", 2, kProcamSolveSteps, "camera and projector"});
  const Subsets joint = collect(views, result.views, object_units, false, true, [&](std::size_t v, std::size_t c) {
    return camera_take(v, c) && projector_take(v, c);
  });
  const double weight = settings.weight_joint_by_noise && result.projector_rms_px > 0.0
                            ? std::clamp(result.camera_rms_px / result.projector_rms_px, 0.1, 10.0)
                            : 1.0;
  result.projector_weight = weight;
  std::vector<std::vector<cv::Point2f>> projector_points = joint.second;
  for (std::vector<cv::Point2f>& view : projector_points) {
    for (cv::Point2f& p : view) p *= static_cast<float>(weight);
  }
  projector_k.rowRange(0, 2) *= weight;
  const int joint_flags = flags | cv::CALIB_USE_INTRINSIC_GUESS |
                          (result.camera_tangential || result.projector_tangential ? 0 : cv::CALIB_ZERO_TANGENT_DIST) |
                          (result.camera_k2 || result.projector_k2 ? 0 : cv::CALIB_FIX_K2);
  cv::Mat rotation, translation, essential, fundamental;
  result.stereo_rms_px =
      cv::stereoCalibrate(joint.object, joint.points, projector_points, camera_k, camera_d, projector_k, projector_d,
                          camera_size, rotation, translation, essential, fundamental, joint_flags, kConvergence);
  projector_k.rowRange(0, 2) /= weight;

  ScannerCalibration& calibration = result.calibration;
  calibration.camera = intrinsics_from(camera_k, camera_d, settings.camera_width, settings.camera_height);
  calibration.projector = intrinsics_from(projector_k, projector_d, settings.projector_width, settings.projector_height);
  Eigen::Matrix3d r;
  for (int i = 0; i < 9; ++i) r(i / 3, i % 3) = rotation.at<double>(i / 3, i % 3);
  // OpenCV's stereo convention: X_projector = R X_camera + T.
  calibration.T_camera_projector =
      Pose(r, unit * Eigen::Vector3d(translation.at<double>(0), translation.at<double>(1), translation.at<double>(2)))
          .inverse();
  calibration.reprojection_rms_px = result.stereo_rms_px;

  double camera_sum = 0.0, projector_sum = 0.0, joint_sum = 0.0;
  int camera_count = 0, projector_count = 0, joint_count = 0;
  for (std::size_t v = 0; v < views.size(); ++v) {
    ViewSolution& s = result.views[v];
    if (!s.used) continue;
    s.T_camera_board = refine_board_pose(views[v], calibration, settings.board, s.T_camera_board, &s, weight);
    s.obliquity_deg = obliquity_deg(s.T_camera_board);
    view_residuals(views[v], calibration, settings.board, s.T_camera_board, &s);
    for (std::size_t c = 0; c < object_units[v].size(); ++c) {
      if (s.camera_inlier[c] != 0) {
        camera_sum += s.camera_residuals_px[c].squaredNorm();
        ++camera_count;
      }
      if (s.projector_inlier[c] != 0) {
        projector_sum += s.projector_residuals_px[c].squaredNorm();
        ++projector_count;
      }
      if (s.camera_inlier[c] != 0 && s.projector_inlier[c] != 0) {
        joint_sum += s.camera_residuals_px[c].squaredNorm() + s.projector_residuals_px[c].squaredNorm();
        joint_count += 2;
      }
    }
    ++result.views_used;
  }
  result.joint_camera_rms_px = camera_count > 0 ? std::sqrt(camera_sum / camera_count) : 0.0;
  result.joint_projector_rms_px = projector_count > 0 ? std::sqrt(projector_sum / projector_count) : 0.0;
  // stereoCalibrate's RMS is of the weighted residuals; the one reported is in pixels.
  if (weight != 1.0 && joint_count > 0) {
    result.stereo_rms_px = std::sqrt(joint_sum / joint_count);
    calibration.reprojection_rms_px = result.stereo_rms_px;
  }
  return result;
}

}  // namespace sls::calib
