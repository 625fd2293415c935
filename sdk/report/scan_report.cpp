#include "sdk/report/scan_report.h"
#include "sdk/report/scan_report_detail.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <optional>
#include <utility>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"

namespace sls::report {

namespace detail {

std::string escape_html(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

// report.json is written by other versions and other tools: every look-up tolerates absence.
const nlohmann::json* find_key(const nlohmann::json& object, std::initializer_list<const char*> path) {
  const nlohmann::json* node = &object;
  for (const char* key : path) {
    if (!node->is_object()) return nullptr;
    const auto found = node->find(key);
    if (found == node->end()) return nullptr;
    node = &*found;
  }
  return node;
}

std::optional<double> number_at(const nlohmann::json& object, std::initializer_list<const char*> path) {
  const nlohmann::json* node = find_key(object, path);
  if (node == nullptr || !node->is_number()) return std::nullopt;
  return node->get<double>();
}

std::string text_of(const nlohmann::json& value) { return value.is_string() ? value.get<std::string>() : value.dump(); }

void add_row(std::string& html, const std::string& name, const std::string& value) {
  html += fmt::format("<tr><th>{}</th><td>{}</td></tr>\n", escape_html(name), escape_html(value));
}

}  // namespace detail

using detail::add_row;
using detail::escape_html;
using detail::find_key;
using detail::number_at;
using detail::text_of;
using detail::deformation_quality_table;
using detail::deformation_tables;
using detail::fused_frame_numbers;
using detail::has_deformation;
namespace {

constexpr double kUm = 1e6;
constexpr std::array<std::uint8_t, 3> kBackground = {245, 245, 245};
constexpr std::array<double, 3> kMaterial = {0.88, 0.86, 0.82};  // a light, slightly warm grey

Eigen::Vector3d orthogonal_up(const Eigen::Vector3d& forward, const Eigen::Vector3d& up_hint) {
  Eigen::Vector3d up = up_hint - up_hint.dot(forward) * forward;
  if (up.norm() < 1e-9) up = forward.unitOrthogonal();
  return up.normalized();
}

// Principal axes as columns, largest variance first, right-handed. Signs are fixed so the
// figures do not flip between runs: each axis's largest component positive, and the first
// axis pointing up (+z) when it is mostly vertical, as a turntable's axis is.
Eigen::Matrix3d principal_axes(const std::vector<Eigen::Vector3d>& points, Eigen::Vector3d* centre) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) mean += p;
  mean /= static_cast<double>(std::max<std::size_t>(points.size(), 1));
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) covariance += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  Eigen::Matrix3d axes;
  for (int k = 0; k < 3; ++k) axes.col(k) = solver.eigenvectors().col(2 - k);  // eigenvalues ascend
  for (int k = 0; k < 2; ++k) {
    Eigen::Index largest = 0;
    axes.col(k).cwiseAbs().maxCoeff(&largest);
    if (axes(largest, k) < 0.0) axes.col(k) *= -1.0;
  }
  if (std::fabs(axes(2, 0)) >= 0.5 && axes(2, 0) < 0.0) axes.col(0) *= -1.0;
  axes.col(2) = axes.col(0).cross(axes.col(1));
  *centre = mean;
  return axes;
}

std::vector<Eigen::Vector3d> sampled_positions(const PointCloud& cloud, std::size_t at_most) {
  const std::size_t step = std::max<std::size_t>(1, cloud.size() / std::max<std::size_t>(at_most, 1));
  std::vector<Eigen::Vector3d> out;
  for (std::size_t n = 0; n < cloud.size(); n += step) out.push_back(cloud.positions[n].cast<double>());
  return out;
}

std::array<std::uint8_t, 3> scaled(const std::array<double, 3>& colour, double factor) {
  std::array<std::uint8_t, 3> out{};
  for (int c = 0; c < 3; ++c) {
    out[static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(
        std::clamp(std::lround(255.0 * colour[static_cast<std::size_t>(c)] * factor), 0L, 255L));
  }
  return out;
}

std::vector<LostFrame> lost_frames_of(const ScanReportInputs& inputs) {
  if (!inputs.lost_frames.empty()) return inputs.lost_frames;
  std::vector<LostFrame> out;
  const nlohmann::json* lost = find_key(inputs.report, {"lost_frames"});
  if (lost == nullptr || !lost->is_array()) return out;
  for (const nlohmann::json& entry : *lost) {
    LostFrame frame;
    if (const auto index = number_at(entry, {"frame"}); index && *index >= 0.0) {
      frame.frame = static_cast<std::size_t>(*index);
    }
    if (const auto timestamp = number_at(entry, {"timestamp_s"})) frame.timestamp_s = *timestamp;
    if (const nlohmann::json* reason = find_key(entry, {"reason"})) frame.reason = text_of(*reason);
    out.push_back(std::move(frame));
  }
  return out;
}

// Where the camera was at a lost frame (see LostFrame), or nothing.
std::optional<Eigen::Vector3d> lost_frame_position(const LostFrame& lost, const std::vector<StampedPose>& trajectory,
                                                   const std::vector<StampedPose>& truth) {
  const bool timed = std::isfinite(lost.timestamp_s);
  if (!truth.empty()) {
    if (timed) {
      for (const StampedPose& pose : truth) {
        if (std::fabs(pose.timestamp_s - lost.timestamp_s) <= eval::kTimestampTolerance_s) {
          return pose.T_world_camera.translation();
        }
      }
    } else if (lost.frame < truth.size()) {
      return truth[lost.frame].T_world_camera.translation();
    }
  }
  if (timed && !trajectory.empty()) {
    const StampedPose* before = &trajectory.front();
    for (const StampedPose& pose : trajectory) {
      if (pose.timestamp_s <= lost.timestamp_s && pose.timestamp_s >= before->timestamp_s) before = &pose;
    }
    return before->T_world_camera.translation();
  }
  return std::nullopt;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Rendering

std::size_t RgbImage::covered_count() const {
  return static_cast<std::size_t>(std::count(covered.begin(), covered.end(), std::uint8_t{1}));
}

std::array<std::uint8_t, 3> RgbImage::at(int x, int y) const {
  const std::size_t i = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3;
  return {rgb[i], rgb[i + 1], rgb[i + 2]};
}

std::vector<View> principal_views(const PointCloud& cloud) {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ(), across = Eigen::Vector3d::UnitX();
  if (!cloud.empty()) {
    const std::vector<Eigen::Vector3d> points = sampled_positions(cloud, 200000);
    Eigen::Vector3d centre;
    const Eigen::Matrix3d axes = principal_axes(points, &centre);
    // Turned objects are near rotationally symmetric: two principal extents alike, the axis
    // the odd one out, whether the longest (a screw) or the shortest (a ring, a cap).
    Eigen::Vector3d spread;
    for (int k = 0; k < 3; ++k) {
      double sum = 0.0;
      for (const Eigen::Vector3d& p : points) sum += std::pow((p - centre).dot(axes.col(k)), 2);
      spread[k] = std::sqrt(sum / static_cast<double>(points.size())) + 1e-12;
    }
    const bool shortest_is_axis = spread[1] / spread[2] > spread[0] / spread[1];
    axis = shortest_is_axis ? axes.col(2) : axes.col(0);
    across = shortest_is_axis ? axes.col(0) : axes.col(1);
    if (std::fabs(axis.z()) >= 0.5 && axis.z() < 0.0) axis = -axis;  // up is up on a turntable
  }
  const Eigen::Vector3d other = axis.cross(across);
  const Eigen::Vector3d oblique = (-across - other - 0.8 * axis).normalized();  // from above
  return {{"side: across the axis", -across, axis},
          {"side: turned 90 degrees about the axis", -other, axis},
          {"oblique, from above", oblique, orthogonal_up(oblique, axis)}};
}

double estimate_point_spacing(const PointCloud& cloud) {
  if (cloud.size() < 2) return 0.0;
  Eigen::Vector3f lo = cloud.positions.front(), hi = lo;
  for (const Eigen::Vector3f& p : cloud.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double diagonal = static_cast<double>((hi - lo).norm());
  if (!(diagonal > 0.0) || !std::isfinite(diagonal)) return 0.0;
  const double points = static_cast<double>(cloud.size());
  // A surface of area A crosses about 1.5 A / h^2 cells of side h (the mean of |nx|+|ny|+|nz|
  // over directions), provided the cells hold several points each: coarsen until they do.
  double cell = diagonal / 1024.0;
  std::vector<std::uint64_t> keys(cloud.size());
  for (int attempt = 0;; ++attempt, cell *= 2.0) {
    for (std::size_t n = 0; n < cloud.size(); ++n) {
      const Eigen::Vector3d offset = (cloud.positions[n] - lo).cast<double>() / cell;
      keys[n] = static_cast<std::uint64_t>(offset.x()) | (static_cast<std::uint64_t>(offset.y()) << 21) |
                (static_cast<std::uint64_t>(offset.z()) << 42);
    }
    std::sort(keys.begin(), keys.end());
    const auto cells = static_cast<double>(std::unique(keys.begin(), keys.end()) - keys.begin());
    if (points >= 4.0 * cells || attempt >= 10) return std::sqrt(cells * cell * cell / 1.5 / points);
  }
}

std::array<std::uint8_t, 3> viridis(double t) {
  // matplotlib's viridis at t = 0, 1/8, ..., 1.
  static constexpr std::array<std::array<double, 3>, 9> kStops = {{{68, 1, 84},
                                                                   {72, 40, 120},
                                                                   {62, 73, 137},
                                                                   {49, 104, 142},
                                                                   {38, 130, 142},
                                                                   {31, 158, 137},
                                                                   {53, 183, 121},
                                                                   {109, 205, 89},
                                                                   {253, 231, 37}}};
  const double x = std::clamp(std::isfinite(t) ? t : 1.0, 0.0, 1.0) * 8.0;
  const auto lower = static_cast<std::size_t>(std::min(std::floor(x), 7.0));
  const double f = x - static_cast<double>(lower);
  std::array<std::uint8_t, 3> out{};
  for (std::size_t c = 0; c < 3; ++c) {
    out[c] = static_cast<std::uint8_t>(std::lround((1.0 - f) * kStops[lower][c] + f * kStops[lower + 1][c]));
  }
  return out;
}

double heat_map_max_m(const std::vector<float>& point_errors_m) {
  if (point_errors_m.empty()) return 1e-6;
  std::vector<float> sorted = point_errors_m;
  const auto rank = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(sorted.size())));
  const auto nth = sorted.begin() + static_cast<std::ptrdiff_t>(std::max<std::size_t>(rank, 1) - 1);
  std::nth_element(sorted.begin(), nth, sorted.end());
  return std::max(1e-6, static_cast<double>(*nth));
}

RgbImage render_cloud(const PointCloud& cloud, const View& view, const SplatOptions& options) {
  if (options.size_px < 16 || options.size_px > 16384) {
    throw_error(ErrorCode::kInvalidArgument, "render_cloud: image size {} px is outside 16..16384", options.size_px);
  }
  if (options.point_errors_m != nullptr && options.point_errors_m->size() != cloud.size()) {
    throw_error(ErrorCode::kInvalidArgument, "render_cloud: {} point errors for {} points",
                options.point_errors_m->size(), cloud.size());
  }
  const Eigen::Vector3d forward = view.forward.normalized();
  const Eigen::Vector3d up = orthogonal_up(forward, view.up);
  const Eigen::Vector3d right = forward.cross(up);

  // Image coordinates: a along right, b along up, depth along forward (smaller is nearer).
  const std::size_t count = cloud.size();
  std::vector<Eigen::Vector3d> projected(count);
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(HUGE_VAL), hi = Eigen::Vector2d::Constant(-HUGE_VAL);
  for (std::size_t n = 0; n < count; ++n) {
    const Eigen::Vector3d p = cloud.positions[n].cast<double>();
    projected[n] = Eigen::Vector3d(p.dot(right), p.dot(up), p.dot(forward));
    lo = lo.cwiseMin(projected[n].head<2>());
    hi = hi.cwiseMax(projected[n].head<2>());
  }
  // Discs a little wider than the spacing so neighbours overlap (no holes face-on). The frame
  // holds the discs, not just their centres.
  const double radius_m = options.splat_radius_m > 0.0 ? options.splat_radius_m : 0.8 * estimate_point_spacing(cloud);
  if (count > 0) {
    lo -= Eigen::Vector2d::Constant(radius_m);
    hi += Eigen::Vector2d::Constant(radius_m);
  }
  const double size = options.size_px;
  const double margin = std::round(0.04 * size);
  double extent = count > 0 ? std::max(hi.x() - lo.x(), hi.y() - lo.y()) : 0.0;
  if (!(extent > 0.0)) extent = 1e-3;
  const double scale = (size - 2.0 * margin) / extent;  // pixels per metre
  auto side_px = [&](double span_m) {
    return count > 0 ? std::clamp(static_cast<int>(std::lround(span_m * scale + 2.0 * margin)), 1, options.size_px)
                     : options.size_px;
  };
  RgbImage image;
  image.width = side_px(hi.x() - lo.x());
  image.height = side_px(hi.y() - lo.y());
  const auto pixels = static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height);
  image.rgb.resize(pixels * 3);
  image.covered.assign(pixels, 0);
  for (std::size_t i = 0; i < pixels; ++i) std::copy(kBackground.begin(), kBackground.end(), image.rgb.begin() + static_cast<std::ptrdiff_t>(3 * i));
  if (count == 0) return image;

  // Never under 0.75 px, which always covers the pixel a point falls in.
  const double radius_px = std::clamp(radius_m * scale, 0.75, 24.0);
  std::vector<double> depth(pixels, HUGE_VAL);
  std::vector<std::int64_t> nearest(pixels, -1);
  for (std::size_t n = 0; n < count; ++n) {
    const double u = (projected[n].x() - lo.x()) * scale + margin;
    const double v = (hi.y() - projected[n].y()) * scale + margin;  // rows go down
    const int x0 = std::max(0, static_cast<int>(std::floor(u - radius_px)));
    const int x1 = std::min(image.width - 1, static_cast<int>(std::floor(u + radius_px)));
    const int y0 = std::max(0, static_cast<int>(std::floor(v - radius_px)));
    const int y1 = std::min(image.height - 1, static_cast<int>(std::floor(v + radius_px)));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double dx = x + 0.5 - u, dy = y + 0.5 - v;
        if (dx * dx + dy * dy > radius_px * radius_px) continue;
        const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(x);
        if (projected[n].z() < depth[i]) {
          depth[i] = projected[n].z();
          nearest[i] = static_cast<std::int64_t>(n);
        }
      }
    }
  }

  // Lights, as directions towards them: a key light above left of the viewer and a raking one
  // grazing from the same side (the same side keeps the shading coherent; grazing, it throws
  // relief a few micrometres deep into light and shadow).
  const Eigen::Vector3d key = (-forward + 0.5 * up - 0.5 * right).normalized();
  const Eigen::Vector3d raking = (-right + 0.3 * up - 0.2 * forward).normalized();
  const bool has_normals = cloud.has_normals();
  auto depth_at = [&](int x, int y) -> double {
    if (x < 0 || y < 0 || x >= image.width || y >= image.height) return HUGE_VAL;
    return depth[static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(x)];
  };
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) + static_cast<std::size_t>(x);
      if (nearest[i] < 0) continue;
      const auto n = static_cast<std::size_t>(nearest[i]);
      Eigen::Vector3d normal;
      if (has_normals) {
        normal = cloud.normals[n].cast<double>();
      } else {
        // No normals: the depth buffer's slope (central differences where both sides exist).
        auto slope = [&](double before, double here, double after) {
          if (std::isfinite(before) && std::isfinite(after)) return (after - before) * 0.5 * scale;
          if (std::isfinite(after)) return (after - here) * scale;
          if (std::isfinite(before)) return (here - before) * scale;
          return 0.0;
        };
        const double here = depth[i];
        const double dz_da = slope(depth_at(x - 1, y), here, depth_at(x + 1, y));
        const double dz_db = -slope(depth_at(x, y - 1), here, depth_at(x, y + 1));
        normal = dz_da * right + dz_db * up - forward;
      }
      if (!(normal.norm() > 0.0) || !normal.allFinite()) normal = -forward;
      normal.normalize();
      if (normal.dot(forward) > 0.0) normal = -normal;  // two-sided: light the side we see
      const double shade =
          std::min(1.0, 0.12 + 0.70 * std::max(0.0, normal.dot(key)) + 0.35 * std::max(0.0, normal.dot(raking)));
      std::array<std::uint8_t, 3> colour;
      if (options.point_errors_m != nullptr) {
        const auto heat = viridis(static_cast<double>((*options.point_errors_m)[n]) / std::max(options.error_max_m, 1e-12));
        // Shading kept faint: the hue carries the error, the shading only the shape.
        colour = scaled({heat[0] / 255.0, heat[1] / 255.0, heat[2] / 255.0}, 0.6 + 0.4 * shade);
      } else {
        colour = scaled(kMaterial, shade);
      }
      std::copy(colour.begin(), colour.end(), image.rgb.begin() + static_cast<std::ptrdiff_t>(3 * i));
      image.covered[i] = 1;
    }
  }
  return image;
}

// ---------------------------------------------------------------------------------------
// Trajectory plot

std::string trajectory_svg(const std::vector<StampedPose>& trajectory, const std::vector<StampedPose>& truth,
                           const std::vector<LostFrame>& lost_frames) {
  auto positions_of = [](const std::vector<StampedPose>& poses) {
    std::vector<Eigen::Vector3d> out;
    for (const StampedPose& pose : poses) out.push_back(pose.T_world_camera.translation());
    return out;
  };
  const std::vector<Eigen::Vector3d> estimated = positions_of(trajectory);
  const std::vector<Eigen::Vector3d> true_positions = positions_of(truth);
  std::vector<std::pair<Eigen::Vector3d, const LostFrame*>> lost;
  for (const LostFrame& frame : lost_frames) {
    if (const auto at = lost_frame_position(frame, trajectory, truth)) lost.emplace_back(*at, &frame);
  }
  // Axes: the trajectory's own plane (principal axes) so that a turntable circle is seen
  // face-on in the top view and edge-on in the side view.
  const std::vector<Eigen::Vector3d>& basis = estimated.size() >= 3 ? estimated : true_positions;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  if (basis.size() >= 3) {
    axes = principal_axes(basis, &centre);
  } else if (!basis.empty() || !estimated.empty()) {
    const std::vector<Eigen::Vector3d>& any = basis.empty() ? estimated : basis;
    for (const Eigen::Vector3d& p : any) centre += p / static_cast<double>(any.size());
  }

  constexpr double kPanel = 400.0, kMargin = 40.0;
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" "
      "font-family=\"sans-serif\" font-size=\"12\">\n",
      2 * kPanel, kPanel + 30.0);
  struct Panel {
    const char* title;
    int horizontal;
    int vertical;
    bool equal_aspect;
  };
  // Side view: vertical not to scale, so drift along the axis (micrometres against a
  // 10 cm circle) is visible at all; its range is printed.
  const Panel panels[2] = {{"top view (plane of the trajectory)", 0, 1, true},
                           {"side view (axis up, vertical scale exaggerated)", 0, 2, false}};
  for (int k = 0; k < 2; ++k) {
    const Panel& panel = panels[k];
    auto coordinates = [&](const Eigen::Vector3d& p) {
      const Eigen::Vector3d local = axes.transpose() * (p - centre);
      return Eigen::Vector2d(local[panel.horizontal], local[panel.vertical]);
    };
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(HUGE_VAL), hi = Eigen::Vector2d::Constant(-HUGE_VAL);
    auto grow = [&](const std::vector<Eigen::Vector3d>& points) {
      for (const Eigen::Vector3d& p : points) {
        lo = lo.cwiseMin(coordinates(p));
        hi = hi.cwiseMax(coordinates(p));
      }
    };
    grow(estimated);
    grow(true_positions);
    for (const auto& entry : lost) grow({entry.first});
    const double x0 = k * kPanel;
    svg += fmt::format("<g><rect x=\"{}\" y=\"0\" width=\"{}\" height=\"{}\" fill=\"white\" stroke=\"#bbb\"/>\n",
                       x0 + 4.0, kPanel - 8.0, kPanel - 4.0);
    svg += fmt::format("<text x=\"{}\" y=\"18\" text-anchor=\"middle\">{}</text>\n", x0 + kPanel / 2.0, panel.title);
    if (!(hi.x() >= lo.x())) {
      svg += fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">no poses</text></g>\n", x0 + kPanel / 2.0,
                         kPanel / 2.0);
      continue;
    }
    Eigen::Vector2d span = (hi - lo).cwiseMax(1e-9);
    const double usable = kPanel - 2.0 * kMargin;
    Eigen::Vector2d scale(usable / span.x(), usable / span.y());
    if (panel.equal_aspect) scale.setConstant(std::min(scale.x(), scale.y()));
    const Eigen::Vector2d middle = 0.5 * (lo + hi);
    auto to_svg = [&](const Eigen::Vector3d& p) {
      const Eigen::Vector2d c = coordinates(p);
      return Eigen::Vector2d(x0 + kPanel / 2.0 + (c.x() - middle.x()) * scale.x(),
                             kPanel / 2.0 + 10.0 - (c.y() - middle.y()) * scale.y());
    };
    auto polyline = [&](const std::vector<Eigen::Vector3d>& points, const char* style) {
      if (points.empty()) return;
      std::string coordinates_text;
      for (const Eigen::Vector3d& p : points) {
        const Eigen::Vector2d s = to_svg(p);
        coordinates_text += fmt::format("{:.2f},{:.2f} ", s.x(), s.y());
      }
      svg += fmt::format("<polyline fill=\"none\" {} points=\"{}\"/>\n", style, coordinates_text);
    };
    polyline(true_positions, "stroke=\"#e07b00\" stroke-width=\"2\" stroke-dasharray=\"6 3\"");
    polyline(estimated, "stroke=\"#1f5fbf\" stroke-width=\"1.5\"");
    for (const Eigen::Vector3d& p : estimated) {
      const Eigen::Vector2d s = to_svg(p);
      svg += fmt::format("<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"2\" fill=\"#1f5fbf\"/>\n", s.x(), s.y());
    }
    if (!estimated.empty() || !true_positions.empty()) {
      const Eigen::Vector2d s = to_svg(estimated.empty() ? true_positions.front() : estimated.front());
      svg += fmt::format(
          "<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"5\" fill=\"none\" stroke=\"#1a9641\" stroke-width=\"2\">"
          "<title>first frame</title></circle>\n",
          s.x(), s.y());
    }
    for (const auto& [position, frame] : lost) {
      const Eigen::Vector2d s = to_svg(position);
      svg += fmt::format(
          "<g stroke=\"#d7191c\" stroke-width=\"2\"><title>frame {} lost: {}</title>"
          "<line x1=\"{:.2f}\" y1=\"{:.2f}\" x2=\"{:.2f}\" y2=\"{:.2f}\"/>"
          "<line x1=\"{:.2f}\" y1=\"{:.2f}\" x2=\"{:.2f}\" y2=\"{:.2f}\"/></g>\n",
          frame->frame, escape_html(frame->reason), s.x() - 5, s.y() - 5, s.x() + 5, s.y() + 5, s.x() - 5, s.y() + 5,
          s.x() + 5, s.y() - 5);
    }
    svg += fmt::format(
        "<text x=\"{}\" y=\"{}\" fill=\"#555\">horizontal {:.3f} mm, vertical {:.3f} mm{}</text></g>\n",
        x0 + 12.0, kPanel - 12.0, span.x() * 1e3, span.y() * 1e3,
        panel.equal_aspect ? "" : fmt::format(" ({:.1f} µm)", span.y() * kUm));
  }
  svg += fmt::format(
      "<g transform=\"translate(12,{})\">"
      "<line x1=\"0\" y1=\"0\" x2=\"24\" y2=\"0\" stroke=\"#1f5fbf\" stroke-width=\"2\"/>"
      "<text x=\"30\" y=\"4\">estimated</text>"
      "<line x1=\"110\" y1=\"0\" x2=\"134\" y2=\"0\" stroke=\"#e07b00\" stroke-width=\"2\" stroke-dasharray=\"6 3\"/>"
      "<text x=\"140\" y=\"4\">ground truth{}</text>"
      "<circle cx=\"262\" cy=\"0\" r=\"5\" fill=\"none\" stroke=\"#1a9641\" stroke-width=\"2\"/>"
      "<text x=\"272\" y=\"4\">first frame</text>"
      "<g stroke=\"#d7191c\" stroke-width=\"2\"><line x1=\"355\" y1=\"-5\" x2=\"365\" y2=\"5\"/>"
      "<line x1=\"355\" y1=\"5\" x2=\"365\" y2=\"-5\"/></g>"
      "<text x=\"372\" y=\"4\">lost frame ({} of {} placed)</text></g>\n",
      kPanel + 16.0, truth.empty() ? " (none)" : "", lost.size(), lost_frames.size());
  svg += "</svg>\n";
  return svg;
}


// ---------------------------------------------------------------------------------------
// The report

namespace {


std::string um(double metres) { return fmt::format("{:.2f} µm", metres * kUm); }

void summary_table(std::string& html, const ScanReportInputs& inputs, const std::vector<LostFrame>& lost) {
  const nlohmann::json& report = inputs.report;
  html += "<h2>Summary</h2>\n<table>\n";
  for (const auto& [key, name] : {std::pair<const char*, const char*>{"input", "recording"}, {"device", "device"},
                                  {"poses", "poses"}}) {
    if (const nlohmann::json* value = find_key(report, {key})) add_row(html, name, text_of(*value));
  }
  const auto frames = number_at(report, {"frames"});
  const auto fused = number_at(report, {"frames_fused"});
  if (frames) {
    add_row(html, "frames", fmt::format("{} fused of {}, {} lost", fused ? fmt::format("{:.0f}", *fused) : "?",
                                        *frames, lost.size()));
  }
  if (const nlohmann::json* method = find_key(report, {"fusion", "method"})) add_row(html, "fusion", text_of(*method));
  if (const auto voxel = number_at(report, {"voxel_size_m"})) add_row(html, "voxel size", um(*voxel));
  if (const nlohmann::json* voxels = find_key(report, {"volume", "voxels"})) add_row(html, "volume (voxels)", voxels->dump());
  if (const auto points = number_at(report, {"points"})) add_row(html, "points", fmt::format("{:.0f}", *points));
  if (const auto triangles = number_at(report, {"triangles"})) add_row(html, "triangles", fmt::format("{:.0f}", *triangles));
  html += "</table>\n";

  if (const nlohmann::json* stages = find_key(report, {"ms_per_stage"}); stages != nullptr && stages->is_object()) {
    html += "<h2>Time per stage</h2>\n<table>\n<tr><th>stage</th><th>total</th><th>per frame</th></tr>\n";
    double total = 0.0;
    const double per = fused && *fused > 0.0 ? *fused : 1.0;
    for (auto it = stages->begin(); it != stages->end(); ++it) {
      if (!it->is_number()) continue;
      const double ms = it->get<double>();
      total += ms;
      html += fmt::format("<tr><td>{}</td><td>{:.1f} ms</td><td>{:.2f} ms</td></tr>\n", escape_html(it.key()), ms,
                          ms / per);
    }
    html += fmt::format("<tr><th>total</th><th>{:.1f} ms</th><th>{:.2f} ms</th></tr>\n</table>\n", total, total / per);
  }

  if (!lost.empty()) {
    html += "<h2>Lost frames</h2>\n<table>\n<tr><th>frame</th><th>reason</th></tr>\n";
    for (const LostFrame& frame : lost) {
      html += fmt::format("<tr><td>{}</td><td>{}</td></tr>\n", frame.frame, escape_html(frame.reason));
    }
    html += "</table>\n";
  }

  if (inputs.evaluation != nullptr) {
    const eval::EvalReport& e = *inputs.evaluation;
    html += "<h2>Quality against ground truth</h2>\n<table>\n";
    if (!e.scene_name.empty()) add_row(html, "scene", e.scene_name);
    if (e.cloud.all.count > 0) {
      add_row(html, "C2C mean / RMS / p95",
              fmt::format("{} / {} / {}", um(e.cloud.all.mean_m), um(e.cloud.all.rms_m), um(e.cloud.all.p95_m)));
    }
    add_row(html, "edge C2C mean / RMS",
            e.cloud.edge.count > 0 ? fmt::format("{} / {} ({} points within {})", um(e.cloud.edge.mean_m),
                                                 um(e.cloud.edge.rms_m), e.cloud.edge.count, um(e.edge_band_m))
                                   : std::string("n/a (no creases)"));
    if (e.coverage.considered > 0) {
      add_row(html, "coverage", fmt::format("{:.4f} ({} of {} {} reference points within {})", e.coverage.fraction(),
                                            e.coverage.covered, e.coverage.considered, e.coverage_basis,
                                            um(e.coverage_radius_m)));
    }
    if (e.trajectory) {
      const eval::TrajectoryErrors& t = *e.trajectory;
      add_row(html, "ATE RMSE / max", fmt::format("{} / {} over {} frames", um(t.ate_rmse_m), um(t.ate_max_m),
                                                  t.matched_frames));
      add_row(html, "loop closure error",
              fmt::format("{}, {:.4f}°", um(t.loop_closure_error_m), t.loop_closure_error_rad * 180.0 / M_PI));
    } else if (!e.trajectory_note.empty()) {
      add_row(html, "trajectory", "n/a: " + e.trajectory_note);
    }
    html += "</table>\n";
  }
}

// `id`: the gradient's, unique in the page.
std::string colour_bar_svg(double max_m, const char* id = "viridis") {
  std::string stops;
  for (int k = 0; k <= 8; ++k) {
    const auto c = viridis(k / 8.0);
    stops += fmt::format("<stop offset=\"{:.3f}\" stop-color=\"rgb({},{},{})\"/>", k / 8.0, c[0], c[1], c[2]);
  }
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"520\" height=\"54\" font-family=\"sans-serif\" "
      "font-size=\"12\"><defs><linearGradient id=\"{1}\" x1=\"0\" x2=\"1\" y1=\"0\" y2=\"0\">{0}</linearGradient>"
      "</defs><rect x=\"10\" y=\"4\" width=\"500\" height=\"20\" fill=\"url(#{1})\" stroke=\"#555\"/>",
      stops, id);
  for (int k = 0; k <= 4; ++k) {
    const double x = 10.0 + 125.0 * k;
    svg += fmt::format("<line x1=\"{0}\" y1=\"24\" x2=\"{0}\" y2=\"30\" stroke=\"#555\"/>"
                       "<text x=\"{0}\" y=\"44\" text-anchor=\"middle\">{1}{2:.1f} µm</text>",
                       x, k == 4 ? "≥ " : "", max_m * kUm * k / 4.0);
  }
  return svg + "</svg>\n";
}

}  // namespace

ScanReportFiles write_scan_report_html(const std::string& out_dir, const ScanReportInputs& inputs) {
  const PointCloud* cloud = inputs.cloud;
  if (cloud != nullptr && !inputs.point_errors_m.empty() && inputs.point_errors_m.size() != cloud->size()) {
    throw_error(ErrorCode::kInvalidArgument, "scan report: {} point errors for a cloud of {} points",
                inputs.point_errors_m.size(), cloud->size());
  }
  create_directories(out_dir);
  ScanReportFiles files;
  const std::vector<LostFrame> lost = lost_frames_of(inputs);

  std::string html = fmt::format(R"(<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{0}</title>
<style>
body {{ font-family: sans-serif; margin: 2em; color: #222; max-width: 1700px; }}
table {{ border-collapse: collapse; margin-bottom: 1em; }}
th, td {{ border: 1px solid #ccc; padding: 3px 10px; text-align: left; }}
th {{ background: #f2f2f2; }}
figure {{ display: inline-block; margin: 0 1em 1em 0; vertical-align: top; }}
figure img {{ max-width: 800px; border: 1px solid #ddd; }}
figcaption {{ font-size: 90%; color: #555; }}
</style></head><body>
<h1>{0}</h1>
)",
                                 escape_html(inputs.title));
  summary_table(html, inputs, lost);

  SplatOptions options;
  options.size_px = inputs.image_size_px;
  const std::vector<View> views = cloud != nullptr ? principal_views(*cloud) : std::vector<View>{};
  auto figure = [&](const std::string& name, const RgbImage& image, const std::string& caption) {
    write_png_rgb(out_dir + "/" + name, image.rgb.data(), image.width, image.height);
    files.images.push_back(out_dir + "/" + name);
    html += fmt::format("<figure><img src=\"{}\" width=\"{}\" height=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>\n",
                        name, image.width, image.height, escape_html(caption), escape_html(caption));
  };
  html += "<h2>Model</h2>\n";
  if (cloud == nullptr || cloud->empty()) {
    html += "<p>No points to render.</p>\n";
  } else {
    html += fmt::format("<p>{} points{}, orthographic splats, key and raking light.</p>\n", cloud->size(),
                        cloud->has_normals() ? " with normals" : " (normals from the depth buffer)");
    for (std::size_t k = 0; k < views.size(); ++k) {
      figure(fmt::format("report_view_{}.png", k), render_cloud(*cloud, views[k], options), views[k].name);
    }
  }

  if (cloud != nullptr && !cloud->empty() && !inputs.point_errors_m.empty()) {
    const double max_m = heat_map_max_m(inputs.point_errors_m);
    html += "<h2>Error against ground truth</h2>\n";
    html += fmt::format("<p>|distance| of each point to the true surface, 0 to {} (the 95th percentile; larger errors "
                        "clipped).</p>\n",
                        um(max_m));
    html += colour_bar_svg(max_m);
    html += "<br>\n";
    SplatOptions heat = options;
    heat.point_errors_m = &inputs.point_errors_m;
    heat.error_max_m = max_m;
    for (std::size_t k = 0; k < views.size(); ++k) {
      figure(fmt::format("report_error_{}.png", k), render_cloud(*cloud, views[k], heat), views[k].name);
    }
  }

  html += "<h2>Camera trajectory</h2>\n";
  if (inputs.trajectory.empty() && inputs.truth.empty()) {
    html += "<p>No trajectory.</p>\n";
  } else {
    html += fmt::format("<p>{} estimated poses{}.</p>\n", inputs.trajectory.size(),
                        inputs.truth.empty() ? "" : fmt::format(", {} true poses", inputs.truth.size()));
    html += trajectory_svg(inputs.trajectory, inputs.truth, lost);
  }

  if (has_deformation(inputs)) {
    html += "<h2>Deformation and loop closure</h2>\n";
    html += "<p>The deformation graph corrects the tracking's drift beside the frame loop; after a full turntable "
            "revolution the loop closure registers the last frame to the first and solves the graph again. The "
            "model, trajectory and figures above are deformed; OUT/undeformed holds them as tracked.</p>\n";
    deformation_tables(html, inputs.report);
    deformation_quality_table(html, inputs.report);
    if (!inputs.trajectory_undeformed.empty() && !inputs.trajectory.empty()) {
      html += "<h3>Trajectory before and after deformation</h3>\n";
      html += deformation_chart_svg(inputs.trajectory, inputs.trajectory_undeformed, inputs.truth,
                                    fused_frame_numbers(inputs.report, inputs.trajectory.size()));
    }
    const PointProperty* correction = cloud != nullptr ? cloud->find_property("correction") : nullptr;
    if (correction != nullptr && !cloud->empty() && correction->values.size() == cloud->size()) {
      const double max_m = heat_map_max_m(correction->values);
      html += "<h3>Correction</h3>\n";
      html += fmt::format("<p>How far deformation moved each point of the model, 0 to {} (the 95th percentile; "
                          "larger corrections clipped).</p>\n",
                          um(max_m));
      html += colour_bar_svg(max_m, "viridis-correction");
      html += "<br>\n";
      SplatOptions heat = options;
      heat.point_errors_m = &correction->values;
      heat.error_max_m = max_m;
      for (std::size_t k = 0; k < views.size(); ++k) {
        figure(fmt::format("report_correction_{}.png", k), render_cloud(*cloud, views[k], heat), views[k].name);
      }
    }
  }
  html += "</body></html>\n";
  files.html = out_dir + "/report.html";
  write_file_atomic(files.html, html);
  return files;
}

}  // namespace sls::report
