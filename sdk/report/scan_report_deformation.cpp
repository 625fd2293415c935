// report.html's deformation parts (scan_report.h): the trajectory before and after
// deformation per frame, and the section on the graph and the loop closure.
#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "sdk/report/scan_report.h"
#include "sdk/report/scan_report_detail.h"

namespace sls::report {

using detail::add_row;
using detail::escape_html;
using detail::find_key;
using detail::number_at;
using detail::text_of;

namespace {
constexpr double kUm = 1e6;
}  // namespace

// ---------------------------------------------------------------------------------------
// Deformation: the trajectory before and after, per frame

namespace {

const StampedPose* pose_at(const std::vector<StampedPose>& poses, double timestamp_s) {
  for (const StampedPose& pose : poses) {
    if (std::fabs(pose.timestamp_s - timestamp_s) <= eval::kTimestampTolerance_s) return &pose;
  }
  return nullptr;
}

// Each pose's position error against the truth after the ATE's rigid alignment (NaN where the
// truth has no pose at its timestamp), or nothing when the ATE cannot be measured.
std::optional<std::vector<double>> aligned_position_errors(const std::vector<StampedPose>& estimated,
                                                           const std::vector<StampedPose>& truth) {
  if (estimated.empty() || truth.empty()) return std::nullopt;
  const std::optional<eval::TrajectoryErrors> errors = eval::trajectory_errors(estimated, truth);
  if (!errors) return std::nullopt;
  std::vector<double> out;
  out.reserve(estimated.size());
  for (const StampedPose& pose : estimated) {
    const StampedPose* true_pose = pose_at(truth, pose.timestamp_s);
    out.push_back(true_pose == nullptr
                      ? std::numeric_limits<double>::quiet_NaN()
                      : (errors->T_truth_estimate * pose.T_world_camera.translation() -
                         true_pose->T_world_camera.translation())
                            .norm());
  }
  return out;
}

struct ChartSeries {
  std::string label;
  const char* style;  // stroke attributes
  const char* colour;
  std::vector<std::pair<double, double>> points;  // (frame, metres)
};

double rms_of(const ChartSeries& series) {
  double sum = 0.0;
  for (const auto& point : series.points) sum += point.second * point.second;
  return series.points.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(series.points.size()));
}

// 1, 2 or 5 times a power of ten, at least `value`.
double nice_ceiling(double value) {
  if (!(value > 0.0) || !std::isfinite(value)) return 1e-6;
  const double power = std::pow(10.0, std::floor(std::log10(value)));
  for (const double step : {1.0, 2.0, 5.0, 10.0}) {
    if (step * power >= value * (1.0 - 1e-9)) return step * power;
  }
  return 10.0 * power;
}

}  // namespace

std::string deformation_chart_svg(const std::vector<StampedPose>& deformed,
                                  const std::vector<StampedPose>& undeformed,
                                  const std::vector<StampedPose>& truth,
                                  const std::vector<std::size_t>& frame_numbers) {
  auto frame_of = [&](std::size_t index) {
    return frame_numbers.size() == deformed.size() ? static_cast<double>(frame_numbers[index])
                                                   : static_cast<double>(index);
  };
  // An undeformed pose's frame: that of the deformed pose with its timestamp.
  auto frame_at = [&](double timestamp_s) -> std::optional<double> {
    for (std::size_t i = 0; i < deformed.size(); ++i) {
      if (std::fabs(deformed[i].timestamp_s - timestamp_s) <= eval::kTimestampTolerance_s) return frame_of(i);
    }
    return std::nullopt;
  };

  std::vector<ChartSeries> series;
  std::string title;
  const std::optional<std::vector<double>> deformed_errors = aligned_position_errors(deformed, truth);
  if (deformed_errors) {
    title = "camera position error against the truth per frame (each trajectory aligned as the ATE)";
    if (const auto undeformed_errors = aligned_position_errors(undeformed, truth)) {
      ChartSeries before{"as tracked", "stroke=\"#e07b00\" stroke-width=\"1.5\" stroke-dasharray=\"6 3\"",
                         "#e07b00", {}};
      for (std::size_t i = 0; i < undeformed.size(); ++i) {
        const auto frame = frame_at(undeformed[i].timestamp_s);
        if (frame && std::isfinite((*undeformed_errors)[i])) before.points.emplace_back(*frame, (*undeformed_errors)[i]);
      }
      series.push_back(std::move(before));
    }
    ChartSeries after{"deformed", "stroke=\"#1f5fbf\" stroke-width=\"1.5\"", "#1f5fbf", {}};
    for (std::size_t i = 0; i < deformed.size(); ++i) {
      if (std::isfinite((*deformed_errors)[i])) after.points.emplace_back(frame_of(i), (*deformed_errors)[i]);
    }
    series.push_back(std::move(after));
  } else {
    title = "correction per frame: distance between the deformed and the tracked camera position";
    ChartSeries correction{"correction", "stroke=\"#1f5fbf\" stroke-width=\"1.5\"", "#1f5fbf", {}};
    for (std::size_t i = 0; i < deformed.size(); ++i) {
      if (const StampedPose* tracked = pose_at(undeformed, deformed[i].timestamp_s)) {
        correction.points.emplace_back(
            frame_of(i), (deformed[i].T_world_camera.translation() - tracked->T_world_camera.translation()).norm());
      }
    }
    series.push_back(std::move(correction));
  }

  constexpr double kWidth = 800.0, kHeight = 320.0;
  constexpr double kLeft = 70.0, kRight = 20.0, kTop = 30.0, kBottom = 60.0;
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" "
      "font-family=\"sans-serif\" font-size=\"12\" class=\"deformation-chart\">\n"
      "<rect x=\"0.5\" y=\"0.5\" width=\"{2}\" height=\"{3}\" fill=\"white\" stroke=\"#bbb\"/>\n"
      "<text x=\"{4}\" y=\"18\" text-anchor=\"middle\">{5}</text>\n",
      kWidth, kHeight, kWidth - 1.0, kHeight - 1.0, kWidth / 2.0, escape_html(title));
  double x_lo = HUGE_VAL, x_hi = -HUGE_VAL, y_hi = 0.0;
  for (const ChartSeries& s : series) {
    for (const auto& [x, y] : s.points) {
      x_lo = std::min(x_lo, x);
      x_hi = std::max(x_hi, x);
      y_hi = std::max(y_hi, y);
    }
  }
  if (!(x_hi >= x_lo)) {
    svg += fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">no poses to compare</text>\n</svg>\n",
                       kWidth / 2.0, kHeight / 2.0);
    return svg;
  }
  if (x_hi - x_lo < 1.0) x_hi = x_lo + 1.0;
  const double y_top = nice_ceiling(y_hi);
  const double plot_w = kWidth - kLeft - kRight, plot_h = kHeight - kTop - kBottom;
  auto sx = [&](double x) { return kLeft + (x - x_lo) / (x_hi - x_lo) * plot_w; };
  auto sy = [&](double y) { return kTop + plot_h - y / y_top * plot_h; };
  // Axes, grid and ticks: five steps up to a round top in µm, about eight along the frames.
  svg += fmt::format("<g stroke=\"#555\"><line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\"/>"
                     "<line x1=\"{0}\" y1=\"{2}\" x2=\"{3}\" y2=\"{2}\"/></g>\n",
                     kLeft, kTop, kTop + plot_h, kLeft + plot_w);
  for (int k = 0; k <= 5; ++k) {
    const double value = y_top * k / 5.0;
    svg += fmt::format("<line x1=\"{0}\" y1=\"{1:.2f}\" x2=\"{2}\" y2=\"{1:.2f}\" stroke=\"#e4e4e4\"/>"
                       "<text x=\"{3}\" y=\"{4:.2f}\" text-anchor=\"end\">{5:.{6}f}</text>\n",
                       kLeft, sy(value), kLeft + plot_w, kLeft - 6.0, sy(value) + 4.0, value * kUm,
                       y_top * kUm >= 10.0 ? 0 : 2);
  }
  const double x_step = std::max(1.0, nice_ceiling((x_hi - x_lo) / 8.0));
  for (double x = std::ceil(x_lo / x_step) * x_step; x <= x_hi + 1e-9; x += x_step) {
    svg += fmt::format("<line x1=\"{0:.2f}\" y1=\"{1}\" x2=\"{0:.2f}\" y2=\"{2}\" stroke=\"#555\"/>"
                       "<text x=\"{0:.2f}\" y=\"{3}\" text-anchor=\"middle\">{4:.0f}</text>\n",
                       sx(x), kTop + plot_h, kTop + plot_h + 5.0, kTop + plot_h + 18.0, x);
  }
  svg += fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n", kLeft + plot_w / 2.0,
                     kTop + plot_h + 34.0,
                     frame_numbers.size() == deformed.size() ? "frame" : "fused frame");
  svg += fmt::format("<text transform=\"translate(16,{}) rotate(-90)\" text-anchor=\"middle\">µm</text>\n",
                     kTop + plot_h / 2.0);
  for (const ChartSeries& s : series) {
    if (s.points.empty()) continue;
    std::string coordinates;
    for (const auto& [x, y] : s.points) coordinates += fmt::format("{:.2f},{:.2f} ", sx(x), sy(y));
    svg += fmt::format("<polyline fill=\"none\" {} points=\"{}\"><title>{}</title></polyline>\n", s.style,
                       coordinates, escape_html(s.label));
    for (const auto& [x, y] : s.points) {
      svg += fmt::format("<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"1.8\" fill=\"{}\"><title>{}: frame {:.0f}, "
                         "{:.2f} µm</title></circle>\n",
                         sx(x), sy(y), s.colour, escape_html(s.label), x, y * kUm);
    }
  }
  // Legend: each series with its RMS and largest value.
  double legend_x = kLeft;
  for (const ChartSeries& s : series) {
    double largest = 0.0;
    for (const auto& point : s.points) largest = std::max(largest, point.second);
    const std::string text = fmt::format("{} (RMS {:.2f} µm, max {:.2f} µm, {} frames)", s.label, rms_of(s) * kUm,
                                         largest * kUm, s.points.size());
    svg += fmt::format("<g transform=\"translate({},{})\"><line x1=\"0\" y1=\"0\" x2=\"24\" y2=\"0\" {}/>"
                       "<text x=\"30\" y=\"4\">{}</text></g>\n",
                       legend_x, kHeight - 10.0, s.style, escape_html(text));
    legend_x += 360.0;
  }
  svg += "</svg>\n";
  return svg;
}

namespace detail {

// Online deformation ran: report.json says so (or the caller gave the tracked poses).
bool has_deformation(const ScanReportInputs& inputs) {
  const nlohmann::json* enabled = find_key(inputs.report, {"deformation", "enabled"});
  return (enabled != nullptr && enabled->is_boolean() && enabled->get<bool>()) ||
         !inputs.trajectory_undeformed.empty();
}

static std::string number_text(const nlohmann::json& object, std::initializer_list<const char*> path,
                               const char* format) {
  const auto value = number_at(object, path);
  return value ? fmt::format(fmt::runtime(format), *value) : std::string("?");
}

// The graph's figures and the loop closure's (or why it was not closed).
void deformation_tables(std::string& html, const nlohmann::json& report) {
  html += "<h3>Deformation graph</h3>\n<table>\n";
  if (const nlohmann::json* deformation = find_key(report, {"deformation"}); deformation != nullptr &&
                                                                              deformation->is_object()) {
    const nlohmann::json& d = *deformation;
    add_row(html, "graph",
            fmt::format("{} nodes, {} links, {} constraints", number_text(d, {"nodes"}, "{:.0f}"),
                        number_text(d, {"links"}, "{:.0f}"), number_text(d, {"constraints"}, "{:.0f}")));
    if (number_at(d, {"rotation_priors"}).value_or(0.0) > 0.0) {
      add_row(html, "turntable rotation priors", number_text(d, {"rotation_priors"}, "{:.0f} frames"));
    }
    add_row(html, "node spacing / region radius",
            fmt::format("{} mm / {} mm", number_text(d, {"node_spacing_mm"}, "{:.3f}"),
                        number_text(d, {"region_radius_mm"}, "{:.3f}")));
    if (const nlohmann::json* keyframes = find_key(d, {"keyframes"}); keyframes != nullptr && keyframes->is_array()) {
      std::vector<double> solve_ms;
      double iterations = 0.0;
      for (const nlohmann::json& k : *keyframes) {
        if (const auto ms = number_at(k, {"solve_ms"})) solve_ms.push_back(*ms);
        iterations += number_at(k, {"iterations"}).value_or(0.0);
      }
      std::sort(solve_ms.begin(), solve_ms.end());
      add_row(html, "keyframes",
              solve_ms.empty() ? fmt::format("{}", keyframes->size())
                               : fmt::format("{}: {:.0f} Gauss–Newton iterations in all, median solve {:.2f} ms, "
                                             "largest {:.2f} ms",
                                             keyframes->size(), iterations, solve_ms[solve_ms.size() / 2],
                                             solve_ms.back()));
    }
    add_row(html, "CHOLMOD", fmt::format("{} analyses, {} factorizations", number_text(d, {"analyses"}, "{:.0f}"),
                                         number_text(d, {"factorizations"}, "{:.0f}")));
    if (number_at(d, {"worker_ms"})) add_row(html, "worker time", number_text(d, {"worker_ms"}, "{:.1f} ms"));
    if (const nlohmann::json* error = find_key(d, {"error"})) add_row(html, "error", text_of(*error));
  } else {
    add_row(html, "graph", "n/a (report.json has no \"deformation\")");
  }
  html += "</table>\n";

  html += "<h3>Loop closure</h3>\n<table>\n";
  const nlohmann::json* loop = find_key(report, {"loop_closure"});
  if (loop == nullptr || !loop->is_object()) {
    add_row(html, "loop closure", "n/a (report.json has no \"loop_closure\")");
    html += "</table>\n";
    return;
  }
  const nlohmann::json& l = *loop;
  const nlohmann::json* requested = find_key(l, {"requested"});
  const nlohmann::json* closed = find_key(l, {"closed"});
  const nlohmann::json* why = find_key(l, {"why"});
  const nlohmann::json* reason = find_key(l, {"reason"});
  const std::string because = why != nullptr ? text_of(*why) : std::string("?");
  if (requested == nullptr || !requested->is_boolean() || !requested->get<bool>()) {
    add_row(html, "loop closure", "not requested: " + because);
  } else if (closed == nullptr) {
    add_row(html, "loop closure", "requested (" + because + "), not run: the scan was interrupted");
  } else if (!closed->is_boolean() || !closed->get<bool>()) {
    add_row(html, "loop closure", "not closed: " + (reason != nullptr ? text_of(*reason) : std::string("?")) +
                                      " (requested: " + because + ")");
  } else {
    add_row(html, "loop closure", "closed (" + because + ")");
    add_row(html, "frames", fmt::format("the last, {}, registered to the first, {}",
                                        number_text(l, {"last_frame"}, "{:.0f}"),
                                        number_text(l, {"first_frame"}, "{:.0f}")));
    add_row(html, "registration",
            fmt::format("inlier fraction {}, residual RMS {} µm, {} iterations, {} degenerate directions",
                        number_text(l, {"registration", "inlier_fraction"}, "{:.3f}"),
                        number_text(l, {"registration", "residual_rms_um"}, "{:.2f}"),
                        number_text(l, {"registration", "iterations"}, "{:.0f}"),
                        number_text(l, {"registration", "degenerate_directions"}, "{:.0f}")));
    add_row(html, "solve",
            fmt::format("{} constraints, {} iterations, energy {} → {}, {} ms",
                        number_text(l, {"constraints"}, "{:.0f}"), number_text(l, {"iterations"}, "{:.0f}"),
                        number_text(l, {"energy_before"}, "{:.4g}"), number_text(l, {"energy_after"}, "{:.4g}"),
                        number_text(l, {"solve_ms"}, "{:.1f}")));
    add_row(html, "last pose moved by the closure",
            fmt::format("{} µm, {}°", number_text(l, {"last_pose_moved_um"}, "{:.2f}"),
                        number_text(l, {"last_pose_moved_deg"}, "{:.4f}")));
    add_row(html, "last pose, deformed against tracked",
            fmt::format("{} µm, {}°", number_text(l, {"last_pose_correction_um"}, "{:.2f}"),
                        number_text(l, {"last_pose_correction_deg"}, "{:.4f}")));
    if (number_at(l, {"ms"})) add_row(html, "time", number_text(l, {"ms"}, "{:.1f} ms"));
  }
  html += "</table>\n";
}

// report["evaluation"] (deformed) and report["evaluation_undeformed"] (as tracked) side by side.
void deformation_quality_table(std::string& html, const nlohmann::json& report) {
  const nlohmann::json* deformed = find_key(report, {"evaluation"});
  const nlohmann::json* tracked = find_key(report, {"evaluation_undeformed"});
  if (deformed == nullptr || tracked == nullptr || !deformed->is_object() || !tracked->is_object()) return;
  html += "<h3>Quality with and without deformation</h3>\n"
          "<table class=\"deformation-quality\">\n<tr><th>figure</th><th>as tracked (undeformed)</th>"
          "<th>deformed</th><th>change</th></tr>\n";
  for (const eval::SideBySideFigure& figure : eval::kSideBySideFigures) {
    const auto before = number_at(*tracked, {figure.key});
    const auto after = number_at(*deformed, {figure.key});
    const char* unit = figure.unit == eval::FigureUnit::kMicrometres ? " µm"
                       : figure.unit == eval::FigureUnit::kDegrees   ? "°"
                                                                     : "";
    const auto format = [&](double value) { return fmt::format("{:.{}f}{}", value, figure.decimals, unit); };
    auto text = [&](const std::optional<double>& value) { return value ? format(*value) : std::string("n/a"); };
    const std::string change =
        before && after ? (*after >= *before ? "+" : "-") + format(std::fabs(*after - *before)) : std::string();
    html += fmt::format("<tr><th>{}</th><td>{}</td><td>{}</td><td>{}</td></tr>\n", escape_html(figure.label),
                        escape_html(text(before)), escape_html(text(after)), escape_html(change));
  }
  html += "</table>\n";
}

// The recording frame of each fused pose, from report["per_frame"] (empty when they disagree).
std::vector<std::size_t> fused_frame_numbers(const nlohmann::json& report, std::size_t poses) {
  std::vector<std::size_t> out;
  const nlohmann::json* frames = find_key(report, {"per_frame"});
  if (frames == nullptr || !frames->is_array()) return out;
  for (const nlohmann::json& entry : *frames) {
    const nlohmann::json* status = find_key(entry, {"status"});
    const auto frame = number_at(entry, {"frame"});
    if (status != nullptr && status->is_string() && status->get<std::string>() == "fused" && frame && *frame >= 0.0) {
      out.push_back(static_cast<std::size_t>(*frame));
    }
  }
  if (out.size() != poses) out.clear();
  return out;
}

}  // namespace detail

}  // namespace sls::report
