#include "samples/sls/calibration_report.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <fmt/format.h>

#include "sdk/report/scan_report_detail.h"
#include "sdk/core/file_util.h"

namespace sls::cli {

nlohmann::json intrinsics_json(const CameraIntrinsics& c) {
  return {{"width", c.width}, {"height", c.height}, {"fx", c.fx}, {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy},
          {"k1", c.k1},       {"k2", c.k2},         {"k3", c.k3}, {"p1", c.p1}, {"p2", c.p2}};
}

nlohmann::json vector_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

namespace {

// The board in calibration.json: a chessboard's inner corners and square; a ChArUco board's
// also its kind, squares, marker and dictionary.
nlohmann::json board_json(const calib::BoardSpec& board) {
  nlohmann::json json = {{"inner_corners", {board.inner_cols, board.inner_rows}}, {"square_m", board.square_m}};
  if (board.is_charuco()) {
    json["kind"] = "charuco";
    json["squares"] = {board.inner_cols + 1, board.inner_rows + 1};
    json["marker_m"] = board.marker_m;
    json["dictionary"] = board.dictionary;
  }
  return json;
}

using report::detail::add_row;
using report::detail::escape_html;

// One view's corners and residuals in an image of width x height, residuals magnified.
std::string residual_svg(const std::vector<Eigen::Vector2d>& points, const std::vector<Eigen::Vector2d>& residuals,
                         const std::vector<std::uint8_t>& used, int width, int height, double magnify,
                         const char* title) {
  const double scale = 320.0 / std::max(width, height);
  std::string svg = fmt::format(
      "<svg width='{:.0f}' height='{:.0f}' style='border:1px solid #999;margin:2px'><title>{}</title>",
      width * scale, height * scale, title);
  for (std::size_t c = 0; c < points.size(); ++c) {
    if (c >= used.size() || used[c] == 0) continue;
    const double x = points[c].x() * scale, y = points[c].y() * scale;
    svg += fmt::format("<circle cx='{:.1f}' cy='{:.1f}' r='1.5' fill='#444'/>", x, y);
    svg += fmt::format("<line x1='{:.1f}' y1='{:.1f}' x2='{:.1f}' y2='{:.1f}' stroke='#d00' stroke-width='1'/>", x, y,
                       x + residuals[c].x() * magnify * scale, y + residuals[c].y() * magnify * scale);
  }
  svg += fmt::format("<text x='4' y='12' font-size='10'>{}</text></svg>", title);
  return svg;
}

// Board outlines, camera, projector and axis seen from above (x, z) and from the side (z, y).
std::string poses_svg(const calib::CalibrateCaptureResult& result) {
  const calib::BoardSpec& board = result.board;
  const double w = (board.inner_cols - 1) * board.square_m, h = (board.inner_rows - 1) * board.square_m;
  std::vector<std::vector<Eigen::Vector3d>> outlines;
  for (const calib::ViewSolution& s : result.procam.views) {
    if (!s.used) continue;
    std::vector<Eigen::Vector3d> outline;
    for (const Eigen::Vector3d& corner : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(w, 0, 0), Eigen::Vector3d(w, h, 0),
                                          Eigen::Vector3d(0, h, 0), Eigen::Vector3d(0, 0, 0)}) {
      outline.push_back(s.T_camera_board * corner);
    }
    outlines.push_back(outline);
  }
  const Eigen::Vector3d projector = result.procam.calibration.T_camera_projector.translation();
  std::string svg;
  for (const int view : {0, 1}) {  // 0: top (x right, z up the page), 1: side (z right, y down)
    const auto project = [&](const Eigen::Vector3d& p) {
      return view == 0 ? Eigen::Vector2d(p.x(), -p.z()) : Eigen::Vector2d(p.z(), p.y());
    };
    Eigen::Vector2d lo = project(Eigen::Vector3d::Zero()), hi = lo;
    const auto extend = [&](const Eigen::Vector3d& p) {
      lo = lo.cwiseMin(project(p));
      hi = hi.cwiseMax(project(p));
    };
    extend(projector);
    for (const auto& outline : outlines)
      for (const Eigen::Vector3d& p : outline) extend(p);
    const double span = std::max((hi - lo).maxCoeff(), 1e-9);
    const auto to_svg = [&](const Eigen::Vector3d& p) {
      const Eigen::Vector2d q = (project(p) - lo) / span * 300.0 + Eigen::Vector2d(10.0, 10.0);
      return q;
    };
    svg += "<svg width='320' height='320' style='border:1px solid #999;margin:2px'>";
    for (std::size_t i = 0; i < outlines.size(); ++i) {
      std::string path;
      for (const Eigen::Vector3d& p : outlines[i]) {
        const Eigen::Vector2d q = to_svg(p);
        path += fmt::format("{}{:.1f},{:.1f} ", path.empty() ? "M" : "L", q.x(), q.y());
      }
      svg += fmt::format("<path d='{}' fill='none' stroke='hsl({},70%,40%)'/>", path, (i * 47) % 360);
    }
    const auto mark = [&](const Eigen::Vector3d& p, const char* label, const char* colour) {
      const Eigen::Vector2d q = to_svg(p);
      svg += fmt::format("<circle cx='{:.1f}' cy='{:.1f}' r='4' fill='{}'/><text x='{:.1f}' y='{:.1f}' "
                         "font-size='11'>{}</text>",
                         q.x(), q.y(), colour, q.x() + 6, q.y() + 4, label);
    };
    mark(Eigen::Vector3d::Zero(), "camera", "#000");
    mark(projector, "projector", "#06c");
    if (result.axis.fitted) {
      const TurntableAxis& axis = result.axis.axis;
      const Eigen::Vector2d a = to_svg(axis.point_camera - 0.5 * span * axis.direction_camera);
      const Eigen::Vector2d b = to_svg(axis.point_camera + 0.5 * span * axis.direction_camera);
      svg += fmt::format("<line x1='{:.1f}' y1='{:.1f}' x2='{:.1f}' y2='{:.1f}' stroke='#c60' stroke-dasharray='4'/>",
                         a.x(), a.y(), b.x(), b.y());
    }
    svg += fmt::format("<text x='4' y='316' font-size='10'>{}</text></svg>",
                       view == 0 ? "from above (camera x right, z up)" : "from the side (camera z right, y down)");
  }
  return svg;
}

}  // namespace

nlohmann::json calibration_json(const calib::CalibrateCaptureResult& result) {
  const calib::ProcamCalibration& procam = result.procam;
  const ScannerCalibration& calibration = procam.calibration;
  nlohmann::json views = nlohmann::json::array(), used = nlohmann::json::array(), rejected = nlohmann::json::array();
  for (std::size_t v = 0; v < result.views.size(); ++v) {
    const calib::ViewObservation& view = result.views[v];
    const calib::ViewSolution& s = procam.views[v];
    nlohmann::json entry = {{"name", view.name},
                            {"used", s.used},
                            {"turntable_angle_deg", view.turntable_angle_deg ? nlohmann::json(*view.turntable_angle_deg)
                                                                             : nlohmann::json(nullptr)},
                            {"projector_corners", view.projector.valid_count()},
                            {"decoded_fraction", view.decoded_fraction}};
    if (s.used) {
      entry["camera_rms_px"] = s.camera_rms_px;
      entry["projector_rms_px"] = s.projector_rms_px;
      entry["obliquity_deg"] = s.obliquity_deg;
      nlohmann::json corners = nlohmann::json::array();
      for (std::size_t c = 0; c < s.camera_residuals_px.size(); ++c) {
        corners.push_back({{"id", c < view.corner_ids.size() ? view.corner_ids[c] : static_cast<int>(c)},
                           {"camera_px", {view.camera_corners[c].x(), view.camera_corners[c].y()}},
                           {"camera_residual_px", {s.camera_residuals_px[c].x(), s.camera_residuals_px[c].y()}},
                           {"camera_used", s.camera_inlier[c] != 0},
                           {"projector_px", view.projector.valid[c] != 0
                                                ? nlohmann::json{view.projector.corners[c].x(), view.projector.corners[c].y()}
                                                : nlohmann::json(nullptr)},
                           {"projector_residual_px", {s.projector_residuals_px[c].x(), s.projector_residuals_px[c].y()}},
                           {"projector_used", s.projector_inlier[c] != 0}});
      }
      entry["corners"] = corners;
      used.push_back(view.name);
    } else {
      entry["reason"] = s.rejected_reason;
      rejected.push_back({{"name", view.name}, {"reason", s.rejected_reason}});
    }
    views.push_back(entry);
  }
  nlohmann::json json = {
      {"input_kind", result.input_kind},
      {"pattern_set", result.pattern_set_name},
      {"board", board_json(result.board)},
      {"camera_rms_px", procam.camera_rms_px},
      {"projector_rms_px", procam.projector_rms_px},
      {"stereo_rms_px", procam.stereo_rms_px},
      {"joint_camera_rms_px", procam.joint_camera_rms_px},
      {"joint_projector_rms_px", procam.joint_projector_rms_px},
      {"corners_dropped", {{"camera", procam.camera_outliers}, {"projector", procam.projector_outliers}}},
      // Which distortion terms the data determined (the rest held at 0), and the projector
      // residuals' weight in the joint refinement (calib/procam_calibration.h).
      {"distortion_fitted",
       {{"camera", {{"p1_p2", procam.camera_tangential}, {"k2", procam.camera_k2}}},
        {"projector", {{"p1_p2", procam.projector_tangential}, {"k2", procam.projector_k2}}}}},
      {"projector_weight", procam.projector_weight},
      {"views_used", used},
      {"views_rejected", rejected},
      {"seconds", result.seconds},
      {"seconds_per_stage",
       {{"load", result.load_s},
        {"detect", result.detect_s},
        {"decode", result.decode_s},
        {"homography", result.homography_s},
        {"solve", result.solve_s}}},
      {"calibration",
       {{"camera", intrinsics_json(calibration.camera)},
        {"projector", intrinsics_json(calibration.projector)},
        {"baseline_m", calibration.T_camera_projector.translation().norm()},
        {"T_camera_projector_translation_m", vector_json(calibration.T_camera_projector.translation())}}},
      {"turntable_axis", {{"fitted", result.axis.fitted}}},
      {"views", views}};
  if (result.axis.fitted) {
    json["turntable_axis"]["point_m"] = vector_json(result.axis.axis.point_camera);
    json["turntable_axis"]["direction"] = vector_json(result.axis.axis.direction_camera);
    json["turntable_axis"]["views"] = result.axis.views;
    json["turntable_axis"]["rms_px"] = result.axis.rms_px;
    json["turntable_axis"]["angle_span_deg"] = result.axis.angle_span_deg;
    // The table's repeatability (calib/turntable_axis.h): the bounds stored, the board poses'
    // noise in them, the two told apart, and the views' turns against their angles.
    nlohmann::json tilts = nlohmann::json::array();
    for (const std::array<double, 2>& t : result.axis.tilt_residuals_deg) tilts.push_back({t[0], t[1]});
    json["turntable_axis"].update({{"angle_sigma_deg", result.axis.angle_sigma_deg},
                                   {"angle_noise_deg", result.axis.angle_noise_deg},
                                   {"angle_jitter_deg", result.axis.angle_jitter_deg},
                                   {"angle_residuals_deg", result.axis.angle_residuals_deg},
                                   {"tilt_sigma_deg", result.axis.tilt_sigma_deg},
                                   {"tilt_noise_deg", result.axis.tilt_noise_deg},
                                   {"tilt_wobble_deg", result.axis.tilt_wobble_deg},
                                   {"tilt_residuals_deg", tilts}});
  } else {
    json["turntable_axis"]["reason"] = result.axis.reason;
  }
  if (result.errors) {
    const calib::CalibrationErrors& e = *result.errors;
    const auto optional = [](const std::optional<double>& value) {
      return value ? nlohmann::json(*value) : nlohmann::json(nullptr);
    };
    json["truth"] = {{"focal_rel_err", e.focal_rel_err()},
                     {"principal_point_err_px", e.principal_point_err_px()},
                     {"baseline_rel_err", e.baseline_rel_err},
                     {"rotation_err_deg", e.rotation_err_deg},
                     {"axis_direction_err_deg", optional(e.axis_direction_err_deg)},
                     {"axis_point_err_um", optional(e.axis_point_err_um)},
                     {"turntable_angle_sigma_true_deg", optional(e.angle_sigma_true_deg)},
                     {"turntable_angle_sigma_deg", optional(e.angle_sigma_estimated_deg)},
                     {"turntable_tilt_sigma_true_deg", optional(e.tilt_sigma_true_deg)},
                     {"turntable_tilt_sigma_deg", optional(e.tilt_sigma_estimated_deg)},
                     {"camera_focal_rel_err", e.camera_focal_rel_err},
                     {"projector_focal_rel_err", e.projector_focal_rel_err},
                     {"camera_principal_point_err_px", e.camera_principal_point_err_px},
                     {"projector_principal_point_err_px", e.projector_principal_point_err_px}};
  }
  return json;
}

void write_calibration_report(const std::string& folder, const calib::CalibrateCaptureResult& result,
                              const nlohmann::json& json) {
  create_directories(folder);
  write_file_atomic(folder + "/calibration.json", json.dump(2));
  const calib::ProcamCalibration& procam = result.procam;
  const ScannerCalibration& calibration = procam.calibration;
  std::string html =
      "<!doctype html><html><head><meta charset='utf-8'><title>slscan calibration</title><style>"
      "body{font-family:sans-serif;margin:1.5em}table{border-collapse:collapse}td,th{border:1px solid #ccc;"
      "padding:2px 8px;text-align:left}</style></head><body><h1>Calibration</h1><table>";
  add_row(html, "input", result.input_kind + ", pattern set " + result.pattern_set_name);
  add_row(html, "board", result.board.describe());
  add_row(html, "views", fmt::format("{} used of {}", procam.views_used, result.views.size()));
  add_row(html, "RMS", fmt::format("camera {:.3f} px, projector {:.3f} px, stereo (joint) {:.3f} px",
                                   procam.camera_rms_px, procam.projector_rms_px, procam.stereo_rms_px));
  add_row(html, "corners dropped as mislocated",
          fmt::format("camera {}, projector {}", procam.camera_outliers, procam.projector_outliers));
  add_row(html, "camera", fmt::format("fx {:.2f} fy {:.2f} cx {:.2f} cy {:.2f} px, k1 {:.4f} k2 {:.4f} p1 {:.2e} p2 {:.2e}",
                                      calibration.camera.fx, calibration.camera.fy, calibration.camera.cx,
                                      calibration.camera.cy, calibration.camera.k1, calibration.camera.k2,
                                      calibration.camera.p1, calibration.camera.p2));
  add_row(html, "projector",
          fmt::format("fx {:.2f} fy {:.2f} cx {:.2f} cy {:.2f} px, k1 {:.4f} k2 {:.4f}", calibration.projector.fx,
                      calibration.projector.fy, calibration.projector.cx, calibration.projector.cy,
                      calibration.projector.k1, calibration.projector.k2));
  add_row(html, "baseline", fmt::format("{:.6f} m", calibration.T_camera_projector.translation().norm()));
  add_row(html, "turntable axis",
          result.axis.fitted ? fmt::format("from {} views over {:.0f}°, residual {:.3f} px; angle σ ≤ {:.4f}° "
                                           "(board noise {:.4f}°, without it {:.4f}°), tilt σ ≤ {:.4f}° (board "
                                           "noise {:.4f}°, without it {:.4f}°)",
                                           result.axis.views, result.axis.angle_span_deg, result.axis.rms_px,
                                           result.axis.angle_sigma_deg, result.axis.angle_noise_deg,
                                           result.axis.angle_jitter_deg, result.axis.tilt_sigma_deg,
                                           result.axis.tilt_noise_deg, result.axis.tilt_wobble_deg)
                             : "not fitted: " + result.axis.reason);
  if (json.contains("truth")) {
    for (const auto& [key, value] : json["truth"].items()) add_row(html, "truth: " + key, value.dump());
  }
  html += "</table><h2>Board poses</h2>" + poses_svg(result);
  // One magnification for every view, so the drawings compare: the largest residual a tenth of
  // the image.
  double largest = 1e-9;
  for (const calib::ViewSolution& s : procam.views) {
    for (const Eigen::Vector2d& r : s.camera_residuals_px) largest = std::max(largest, r.norm());
    for (const Eigen::Vector2d& r : s.projector_residuals_px) largest = std::max(largest, r.norm());
  }
  const double magnify = 0.1 * std::max(calibration.camera.width, calibration.camera.height) / largest;
  html += fmt::format("<h2>Views</h2><p>Corners (dots) and residuals observed − predicted (red), magnified {:.0f}×; "
                      "corners dropped as mislocated are not drawn.</p><table>",
                      magnify);
  for (std::size_t v = 0; v < result.views.size(); ++v) {
    const calib::ViewObservation& view = result.views[v];
    const calib::ViewSolution& s = procam.views[v];
    html += "<tr><td>" + escape_html(view.name) + "</td><td>";
    if (!s.used) {
      html += "rejected: " + escape_html(s.rejected_reason) + "</td></tr>";
      continue;
    }
    html += fmt::format("camera {:.3f} px, projector {:.3f} px, tilt {:.1f}°{}</td><td>", s.camera_rms_px,
                        s.projector_rms_px, s.obliquity_deg,
                        view.turntable_angle_deg ? fmt::format(", table {:.2f}°", *view.turntable_angle_deg) : "");
    html += residual_svg(view.camera_corners, s.camera_residuals_px, s.camera_inlier, calibration.camera.width,
                         calibration.camera.height, magnify, "camera");
    html += residual_svg(view.projector.corners, s.projector_residuals_px, s.projector_inlier,
                         calibration.projector.width, calibration.projector.height, magnify, "projector");
    html += "</td></tr>";
  }
  html += "</table></body></html>\n";
  write_file_atomic(folder + "/calibration_report.html", html);
}

}  // namespace sls::cli
