// The scan report (sdk/report/scan_report.h): splat renders that show the object and its
// shading, heat-map colours that follow the errors, the trajectory plot, the chart of the
// trajectory before and after deformation, and report.html with its figures and PNGs, with
// and without ground truth, with and without online deformation.
#include "sdk/report/scan_report.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "tests/support/test_support.h"

namespace sls::report {
namespace {

constexpr double kRadius_m = 0.005;

// Evenly spread points on a sphere of 5 mm about (1, 2, 3) cm (not the origin: the renderer
// must frame the object wherever it is), with outward normals.
PointCloud fibonacci_sphere(std::size_t count, bool with_normals = true) {
  PointCloud cloud;
  const Eigen::Vector3d centre(0.01, 0.02, 0.03);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (std::size_t n = 0; n < count; ++n) {
    const double z = 1.0 - 2.0 * (static_cast<double>(n) + 0.5) / static_cast<double>(count);
    const double r = std::sqrt(1.0 - z * z);
    const double phi = golden * static_cast<double>(n);
    const Eigen::Vector3d direction(r * std::cos(phi), r * std::sin(phi), z);
    cloud.positions.push_back((centre + kRadius_m * direction).cast<float>());
    if (with_normals) cloud.normals.push_back(direction.cast<float>());
  }
  return cloud;
}

double grey(const std::array<std::uint8_t, 3>& c) { return (c[0] + c[1] + c[2]) / 3.0; }

// Mean and spread of the covered pixels' grey values.
void covered_statistics(const RgbImage& image, double* mean, double* stddev, double* lo, double* hi) {
  double sum = 0.0, squares = 0.0;
  std::size_t count = 0;
  *lo = 255.0;
  *hi = 0.0;
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      if (image.covered[static_cast<std::size_t>(y * image.width + x)] == 0) continue;
      const double g = grey(image.at(x, y));
      sum += g;
      squares += g * g;
      *lo = std::min(*lo, g);
      *hi = std::max(*hi, g);
      ++count;
    }
  }
  *mean = sum / static_cast<double>(count);
  *stddev = std::sqrt(std::max(0.0, squares / static_cast<double>(count) - *mean * *mean));
}

std::vector<StampedPose> circle_trajectory(std::size_t frames, double drift_per_frame_m) {
  std::vector<StampedPose> poses;
  for (std::size_t i = 0; i < frames; ++i) {
    const double angle = 2.0 * M_PI * static_cast<double>(i) / static_cast<double>(frames);
    const Eigen::Vector3d position(0.1 * std::cos(angle), 0.1 * std::sin(angle),
                                   0.02 + drift_per_frame_m * static_cast<double>(i));
    poses.push_back({0.5 * static_cast<double>(i),
                     Pose(Eigen::Matrix3d(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ())), position)});
  }
  return poses;
}

nlohmann::json scan_report_json() {
  return {{"format", "slscan-scan-report"},
          {"input", "/data/rec"},
          {"device", "cpu"},
          {"poses", "groundtruth"},
          {"fusion", {{"method", "gtsdf"}}},
          {"voxel_size_m", 2.5e-05},
          {"volume", {{"voxels", {400, 320, 240}}}},
          {"frames", 24},
          {"frames_fused", 22},
          {"lost_frames",
           {{{"frame", 5}, {"reason", "frame 5: <decode> failed: 3% valid pixels"}},
            {{"frame", 17}, {"reason", "incomplete pattern stack"}}}},
          {"ms_per_stage", {{"read", 120.5}, {"decode", 880.25}, {"integrate", 412.0}, {"extract", 55.0}}},
          {"points", 20000},
          {"triangles", 40000}};
}

// What sls scan adds to report.json when online deformation ran and the loop was closed.
nlohmann::json with_deformation(nlohmann::json report) {
  report["deformation"] = {{"enabled", true},
                           {"nodes", 12},
                           {"links", 30},
                           {"constraints", 4567},
                           {"rotation_priors", 11},
                           {"analyses", 1},
                           {"factorizations", 14},
                           {"node_spacing_mm", 2.5},
                           {"region_radius_mm", 7.5},
                           {"worker_ms", 321.5},
                           {"keyframes",
                            {{{"frame", 0}, {"node", 0}, {"matches", 0}, {"constraints", 0}, {"iterations", 0},
                              {"energy_after", 0.0}, {"solve_ms", 0.5}, {"ms", 1.0}},
                             {{"frame", 3}, {"node", 1}, {"matches", 900}, {"constraints", 800}, {"iterations", 3},
                              {"energy_after", 1e-9}, {"solve_ms", 4.25}, {"ms", 6.0}}}}};
  report["loop_closure"] = {{"requested", true},
                            {"why", "a full turntable revolution (350.0°)"},
                            {"closed", true},
                            {"first_frame", 0},
                            {"last_frame", 23},
                            {"registration",
                             {{"inlier_fraction", 0.875}, {"residual_rms_um", 9.5}, {"degenerate_directions", 0},
                              {"iterations", 7}}},
                            {"constraints", 1234},
                            {"iterations", 5},
                            {"energy_before", 0.25},
                            {"energy_after", 0.0125},
                            {"solve_ms", 42.0},
                            {"last_pose_moved_um", 87.5},
                            {"last_pose_moved_deg", 0.0625},
                            {"last_pose_correction_um", 140.25},
                            {"last_pose_correction_deg", 0.125},
                            {"ms", 99.0}};
  report["ms_per_stage"]["deform"] = 12.5;
  report["ms_per_stage"]["loop_closure"] = 99.0;
  auto evaluation = [](double c2c_um, double ate_um, double loop_um) {
    return nlohmann::json{{"c2c_mean_um", c2c_um},      {"c2c_rms_um", 2.0 * c2c_um},
                          {"c2c_p95_um", 3.0 * c2c_um}, {"c2c_edge_mean_um", 4.0 * c2c_um},
                          {"coverage", 0.95},           {"ate_rmse_um", ate_um},
                          {"loop_closure_error_um", loop_um}, {"loop_closure_error_deg", 0.5}};
  };
  report["evaluation"] = evaluation(11.0, 21.0, 6.5);
  report["evaluation_undeformed"] = evaluation(17.0, 63.0, 150.0);
  report["evaluation_undeformed"]["c2c_edge_mean_um"] = nullptr;  // no creases measured: n/a
  return report;
}

// The src="..." of every <img> in the page.
std::vector<std::string> image_sources(const std::string& html) {
  // A plain scan, not std::regex: GCC 12's regex trips -Wmaybe-uninitialized under ASan.
  std::vector<std::string> out;
  const std::string tag = "<img src=\"";
  for (std::size_t at = html.find(tag); at != std::string::npos; at = html.find(tag, at)) {
    at += tag.size();
    const std::size_t end = html.find('"', at);
    if (end == std::string::npos) break;
    out.push_back(html.substr(at, end - at));
    at = end;
  }
  return out;
}

TEST(SplatRenderer, TheSphereFillsItsDiscAndIsShaded) {
  const PointCloud sphere = fibonacci_sphere(20000);
  const double spacing = estimate_point_spacing(sphere);
  const double exact = std::sqrt(4.0 * M_PI * kRadius_m * kRadius_m / 20000.0);
  EXPECT_GT(spacing, 0.6 * exact);
  EXPECT_LT(spacing, 1.6 * exact);

  const std::vector<View> views = principal_views(sphere);
  ASSERT_EQ(views.size(), 3u);
  for (const bool with_normals : {true, false}) {
    const PointCloud cloud = with_normals ? sphere : fibonacci_sphere(20000, false);
    for (const View& view : views) {
      SCOPED_TRACE(view.name + (with_normals ? ", normals" : ", depth-buffer normals"));
      const RgbImage image = render_cloud(cloud, view);
      EXPECT_EQ(std::max(image.width, image.height), 800);
      EXPECT_GE(std::min(image.width, image.height), 790);  // a sphere's extent is the same every way
      // A disc of 92% of the side: pi/4 * 0.92^2 = 0.665 of the image, and no holes inside.
      const double fraction = static_cast<double>(image.covered_count()) / (image.width * image.height);
      EXPECT_NEAR(fraction, 0.665, 0.02);
      EXPECT_EQ(image.covered[static_cast<std::size_t>((image.height / 2) * image.width + image.width / 2)], 1);
      EXPECT_EQ(image.covered[0], 0);
      double mean = 0.0, stddev = 0.0, lo = 0.0, hi = 0.0;
      covered_statistics(image, &mean, &stddev, &lo, &hi);
      EXPECT_GT(stddev, 20.0);
      EXPECT_GT(hi, 180.0);
      EXPECT_LT(lo, 60.0);
      // The key light is above left: the upper left of the sphere is brighter than the lower right.
      const int q = image.width / 4;
      EXPECT_GT(grey(image.at(q + q / 2, q + q / 2)), grey(image.at(3 * q - q / 2, 3 * q - q / 2)) + 30.0);
    }
  }
  // Nothing to draw: a blank image of the requested size, nothing covered.
  const RgbImage empty = render_cloud(PointCloud(), views[0]);
  EXPECT_EQ(empty.covered_count(), 0u);
  EXPECT_EQ(empty.width, 800);
}

TEST(SplatRenderer, HeatMapColoursFollowTheErrors) {
  const PointCloud sphere = fibonacci_sphere(20000);
  const View view = principal_views(sphere)[0];
  // 40 um on the upper half of the image, 0 on the lower half.
  std::vector<float> errors(sphere.size());
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3f& p : sphere.positions) centre += p.cast<double>() / static_cast<double>(sphere.size());
  for (std::size_t n = 0; n < sphere.size(); ++n) {
    errors[n] = (sphere.positions[n].cast<double>() - centre).dot(view.up) > 0.0 ? 40e-6f : 0.0f;
  }
  EXPECT_NEAR(heat_map_max_m(errors), 40e-6, 1e-9);
  SplatOptions options;
  options.point_errors_m = &errors;
  options.error_max_m = heat_map_max_m(errors);
  const RgbImage heat = render_cloud(sphere, view, options);
  const auto high = heat.at(heat.width / 2, heat.height * 3 / 10);
  const auto low = heat.at(heat.width / 2, heat.height * 7 / 10);
  // Viridis: yellow at the top of the scale, dark purple at the bottom.
  EXPECT_GT(high[1], 100);
  EXPECT_LT(high[2], 80);
  EXPECT_LT(low[1], 40);
  EXPECT_GT(low[2], low[0]);
  EXPECT_EQ(viridis(0.0), (std::array<std::uint8_t, 3>{68, 1, 84}));
  EXPECT_EQ(viridis(1.0), (std::array<std::uint8_t, 3>{253, 231, 37}));
  EXPECT_EQ(viridis(7.0), viridis(1.0));  // clamped

  std::vector<float> wrong(3, 0.0f);
  options.point_errors_m = &wrong;
  EXPECT_THROW(render_cloud(sphere, view, options), Error);
}

TEST(TrajectoryPlot, ShowsBothTrajectoriesAndTheLostFrames) {
  const std::vector<StampedPose> truth = circle_trajectory(24, 0.0);
  std::vector<StampedPose> estimated = circle_trajectory(24, 2e-6);
  estimated.erase(estimated.begin() + 5);
  const std::string svg = trajectory_svg(estimated, truth, {{5, 2.5, "too few valid pixels <3%>"}});
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_EQ(std::count(svg.begin(), svg.end(), '\n') > 10, true);
  EXPECT_NE(svg.find("frame 5 lost: too few valid pixels &lt;3%&gt;"), std::string::npos);
  EXPECT_NE(svg.find("stroke-dasharray"), std::string::npos);  // the truth is drawn
  EXPECT_NE(svg.find("(1 of 1 placed)"), std::string::npos);
  // Without truth or timestamps a lost frame cannot be placed, and that is said.
  const std::string alone = trajectory_svg(estimated, {}, {{5, std::nan(""), "lost"}});
  EXPECT_NE(alone.find("(0 of 1 placed)"), std::string::npos);
  EXPECT_NE(trajectory_svg({}, {}, {}).find("no poses"), std::string::npos);
}

TEST(ScanReportDeformationChart, PositionErrorsBeforeAndAfterAgainstTheTruth) {
  const std::vector<StampedPose> truth = circle_trajectory(24, 0.0);
  std::vector<StampedPose> tracked = circle_trajectory(24, 3e-6);   // drifts 3 um a frame
  std::vector<StampedPose> deformed = circle_trajectory(24, 0.3e-6);  // a tenth of that
  tracked.erase(tracked.begin() + 5);                                 // frame 5 lost
  deformed.erase(deformed.begin() + 5);
  std::vector<std::size_t> frames;
  for (std::size_t i = 0; i < 24; ++i) {
    if (i != 5) frames.push_back(i);
  }
  const std::string svg = deformation_chart_svg(deformed, tracked, truth, frames);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_NE(svg.find("position error against the truth"), std::string::npos);
  // Two curves, each aligned as the ATE is: their RMS are the two ATEs.
  std::size_t polylines = 0;
  for (std::size_t at = svg.find("<polyline"); at != std::string::npos; at = svg.find("<polyline", at + 1)) ++polylines;
  EXPECT_EQ(polylines, 2u);
  const auto before = eval::trajectory_errors(tracked, truth);
  const auto after = eval::trajectory_errors(deformed, truth);
  ASSERT_TRUE(before && after);
  EXPECT_GT(before->ate_rmse_m, 5.0 * after->ate_rmse_m);
  EXPECT_NE(svg.find(fmt::format("as tracked (RMS {:.2f} µm", before->ate_rmse_m * 1e6)), std::string::npos) << svg;
  EXPECT_NE(svg.find(fmt::format("deformed (RMS {:.2f} µm", after->ate_rmse_m * 1e6)), std::string::npos);
  EXPECT_NE(svg.find("23 frames)"), std::string::npos);
  EXPECT_NE(svg.find(">frame<"), std::string::npos);           // recording frames on the x axis
  EXPECT_NE(svg.find("deformed: frame 23,"), std::string::npos);  // the last point at frame 23
  EXPECT_EQ(svg.find("deformed: frame 5,"), std::string::npos);   // the lost frame has none
}

TEST(ScanReportDeformationChart, WithoutTruthTheCorrectionPerFrame) {
  const std::vector<StampedPose> tracked = circle_trajectory(10, 4e-6);
  const std::vector<StampedPose> deformed = circle_trajectory(10, 0.0);
  const std::string svg = deformation_chart_svg(deformed, tracked, {});
  EXPECT_NE(svg.find("correction per frame"), std::string::npos);
  EXPECT_EQ(svg.find("against the truth"), std::string::npos);
  // One curve, 0 at the first frame and 36 um (9 frames of 4 um) at the last.
  EXPECT_EQ(svg.find("<polyline"), svg.rfind("<polyline"));
  EXPECT_NE(svg.find("correction: frame 0, 0.00 µm"), std::string::npos);
  EXPECT_NE(svg.find("correction: frame 9, 36.00 µm"), std::string::npos);
  EXPECT_NE(svg.find("max 36.00 µm, 10 frames"), std::string::npos);
  EXPECT_NE(svg.find(">fused frame<"), std::string::npos);  // no frame numbers given
  // A truth that matches no timestamp is no truth: the correction again.
  std::vector<StampedPose> elsewhere = circle_trajectory(10, 0.0);
  for (StampedPose& pose : elsewhere) pose.timestamp_s += 1000.0;
  EXPECT_NE(deformation_chart_svg(deformed, tracked, elsewhere).find("correction per frame"), std::string::npos);
  EXPECT_NE(deformation_chart_svg({}, {}, {}).find("no poses to compare"), std::string::npos);
}

class ScanReport : public ::testing::Test {
 protected:
  test::TemporaryDirectory directory_;
  PointCloud sphere_ = fibonacci_sphere(20000);

  // Checks the page's images exist as 8-bit RGB PNGs of about 800 px.
  std::vector<std::string> check_images(const std::string& folder, const std::string& html) {
    const std::vector<std::string> sources = image_sources(html);
    for (const std::string& source : sources) {
      SCOPED_TRACE(source);
      EXPECT_EQ(source.find('/'), std::string::npos);  // relative, beside report.html
      const PngHeader header = read_png_header(folder + "/" + source);
      EXPECT_EQ(header.channels, 3);
      EXPECT_EQ(std::max(header.width, header.height), 800);
    }
    return sources;
  }
};

TEST_F(ScanReport, WithoutGroundTruth) {
  ScanReportInputs inputs;
  inputs.report = scan_report_json();
  inputs.cloud = &sphere_;
  inputs.trajectory = circle_trajectory(24, 0.0);
  const std::string out = directory_.file("out");
  const ScanReportFiles files = write_scan_report_html(out, inputs);
  EXPECT_EQ(files.html, out + "/report.html");
  const std::string html = read_file_text(files.html);
  const std::vector<std::string> sources = check_images(out, html);
  EXPECT_EQ(sources, (std::vector<std::string>{"report_view_0.png", "report_view_1.png", "report_view_2.png"}));
  EXPECT_EQ(files.images.size(), 3u);
  EXPECT_FALSE(std::filesystem::exists(out + "/report_error_0.png"));
  for (const char* needle : {"gtsdf", "25.00 µm", "22 fused of 24, 2 lost", "880.2 ms", "1467.8 ms", "[400,320,240]",
                             "20000", "frame 5: &lt;decode&gt; failed", "incomplete pattern stack", "<svg",
                             "Camera trajectory", "(0 of 2 placed)"}) {
    EXPECT_NE(html.find(needle), std::string::npos) << needle;
  }
  EXPECT_EQ(html.find("<decode>"), std::string::npos);  // escaped
  EXPECT_EQ(html.find("Error against ground truth"), std::string::npos);
  EXPECT_EQ(html.find("Quality against ground truth"), std::string::npos);
  EXPECT_EQ(html.find("Deformation and loop closure"), std::string::npos);
  EXPECT_EQ(html.find("deformation-chart"), std::string::npos);
}

TEST_F(ScanReport, WithGroundTruthErrorsAndEvaluation) {
  ScanReportInputs inputs;
  inputs.report = scan_report_json();
  inputs.cloud = &sphere_;
  inputs.truth = circle_trajectory(24, 0.0);
  inputs.trajectory = circle_trajectory(24, 1e-6);
  inputs.trajectory.erase(inputs.trajectory.begin() + 17);
  inputs.trajectory.erase(inputs.trajectory.begin() + 5);
  inputs.point_errors_m.resize(sphere_.size());
  for (std::size_t n = 0; n < sphere_.size(); ++n) inputs.point_errors_m[n] = static_cast<float>(n % 100) * 1e-7f;
  eval::EvalReport evaluation;
  evaluation.scene_name = "sphere";
  evaluation.cloud.all = {20000, 3.21e-6, 4.5e-6, 9.87e-6, 20e-6};
  evaluation.coverage = {1000, 990};
  evaluation.coverage_basis = "visible";
  evaluation.coverage_radius_m = 50e-6;
  eval::TrajectoryErrors trajectory;
  trajectory.matched_frames = 22;
  trajectory.ate_rmse_m = 5.7e-6;
  trajectory.ate_max_m = 9.1e-6;
  trajectory.loop_closure_error_m = 23e-6;
  trajectory.loop_closure_error_rad = 0.5 * M_PI / 180.0;
  evaluation.trajectory = trajectory;
  inputs.evaluation = &evaluation;
  // SLS_KEEP_SCAN_REPORT=folder keeps this report for a look in a browser.
  const char* keep = std::getenv("SLS_KEEP_SCAN_REPORT");
  const std::string out = keep != nullptr ? std::string(keep) : directory_.file("out");
  const ScanReportFiles files = write_scan_report_html(out, inputs);
  const std::string html = read_file_text(files.html);
  const std::vector<std::string> sources = check_images(out, html);
  EXPECT_EQ(sources.size(), 6u);
  EXPECT_TRUE(std::filesystem::exists(out + "/report_error_2.png"));
  for (const char* needle : {"3.21 µm / 4.50 µm / 9.87 µm", "n/a (no creases)", "0.9900", "5.70 µm / 9.10 µm over 22",
                             "23.00 µm, 0.5000°", "Error against ground truth", "linearGradient", "≥ 9.4 µm",
                             "(2 of 2 placed)", "ground truth"}) {
    EXPECT_NE(html.find(needle), std::string::npos) << needle;
  }
  EXPECT_EQ(html.find("Deformation and loop closure"), std::string::npos);
  EXPECT_EQ(html.find("Quality with and without deformation"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(out + "/report_correction_0.png"));

  // The lead's own lost frames (with timestamps) take precedence over report.json's.
  inputs.lost_frames = {{5, 2.5, "dropped"}};
  const std::string again = read_file_text(write_scan_report_html(out, inputs).html);
  EXPECT_NE(again.find("(1 of 1 placed)"), std::string::npos);
  EXPECT_NE(again.find("dropped"), std::string::npos);

  inputs.point_errors_m.pop_back();
  try {
    write_scan_report_html(out, inputs);
    ADD_FAILURE() << "no error for mismatched point errors";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
  }
}

TEST_F(ScanReport, WithDeformationAndLoopClosure) {
  ScanReportInputs inputs;
  inputs.report = with_deformation(scan_report_json());
  PointCloud cloud = sphere_;
  PointProperty correction{"correction", {}};
  for (std::size_t n = 0; n < cloud.size(); ++n) correction.values.push_back(static_cast<float>(n % 50) * 1e-6f);
  cloud.properties.push_back(correction);
  inputs.cloud = &cloud;
  inputs.truth = circle_trajectory(24, 0.0);
  inputs.trajectory = circle_trajectory(24, 0.3e-6);
  inputs.trajectory_undeformed = circle_trajectory(24, 3e-6);
  // SLS_KEEP_SCAN_REPORT=folder keeps this report too (in folder/deformation).
  const char* keep = std::getenv("SLS_KEEP_SCAN_REPORT");
  const std::string out = keep != nullptr ? std::string(keep) + "/deformation" : directory_.file("out");
  const ScanReportFiles files = write_scan_report_html(out, inputs);
  const std::string html = read_file_text(files.html);
  const std::vector<std::string> sources = check_images(out, html);
  // The three views, and the correction heat map from the same three.
  EXPECT_EQ(sources, (std::vector<std::string>{"report_view_0.png", "report_view_1.png", "report_view_2.png",
                                               "report_correction_0.png", "report_correction_1.png",
                                               "report_correction_2.png"}));
  for (int k = 0; k < 3; ++k) {
    const std::string name = out + fmt::format("/report_correction_{}.png", k);
    EXPECT_TRUE(std::filesystem::exists(name)) << name;
    EXPECT_NE(read_file_text(name), read_file_text(out + fmt::format("/report_view_{}.png", k)));
  }
  EXPECT_EQ(files.images.size(), 6u);
  const std::string scale = fmt::format("≥ {:.1f} µm", heat_map_max_m(correction.values) * 1e6);
  for (const std::string& needle : std::vector<std::string>{
           "Deformation and loop closure", "12 nodes, 30 links, 4567 constraints",
           "turntable rotation priors", "11 frames", "2.500 mm / 7.500 mm",
           "2: 3 Gauss–Newton iterations in all, median solve 4.25 ms", "1 analyses, 14 factorizations", "321.5 ms",
           "closed (a full turntable revolution (350.0°))", "the last, 23, registered to the first, 0",
           "inlier fraction 0.875, residual RMS 9.50 µm, 7 iterations", "1234 constraints, 5 iterations, energy "
           "0.25 → 0.0125, 42.0 ms", "87.50 µm, 0.0625°", "140.25 µm, 0.1250°",
           // The quality as tracked and deformed, side by side.
           "Quality with and without deformation",
           "<tr><th>C2C mean</th><td>17.00 µm</td><td>11.00 µm</td><td>-6.00 µm</td></tr>",
           "<tr><th>C2C p95</th><td>51.00 µm</td><td>33.00 µm</td><td>-18.00 µm</td></tr>",
           "<tr><th>edge C2C mean</th><td>n/a</td><td>44.00 µm</td><td></td></tr>",
           "<tr><th>coverage</th><td>0.9500</td><td>0.9500</td><td>+0.0000</td></tr>",
           "<tr><th>ATE RMSE</th><td>63.00 µm</td><td>21.00 µm</td><td>-42.00 µm</td></tr>",
           "<tr><th>loop closure error</th><td>150.00 µm</td><td>6.50 µm</td><td>-143.50 µm</td></tr>",
           "<tr><th>loop closure angle</th><td>0.5000°</td><td>0.5000°</td><td>+0.0000°</td></tr>",
           // The chart against the truth, the correction's colour bar, the new stages.
           "Trajectory before and after deformation", "deformation-chart", "position error against the truth",
           "as tracked (RMS", "viridis-correction", scale, "<td>deform</td><td>12.5 ms", "<td>loop_closure</td>"}) {
    EXPECT_NE(html.find(needle), std::string::npos) << needle;
  }
  // The existing figures stay.
  EXPECT_NE(html.find("Camera trajectory"), std::string::npos);
  EXPECT_NE(html.find("(2 of 2 placed)"), std::string::npos);

  // No truth: the chart shows the correction per frame.
  inputs.truth.clear();
  const std::string without_truth = read_file_text(write_scan_report_html(out, inputs).html);
  EXPECT_NE(without_truth.find("correction per frame"), std::string::npos);
  EXPECT_EQ(without_truth.find("position error against the truth"), std::string::npos);

  // A loop closure that failed says why; one not asked for says why not; no undeformed
  // evaluation: no side-by-side table.
  inputs.report["loop_closure"] = {{"requested", true},
                                   {"why", "--loop-closure on"},
                                   {"closed", false},
                                   {"reason", "the last frame does not register: <too few matches>"}};
  inputs.report.erase("evaluation_undeformed");
  const std::string failed = read_file_text(write_scan_report_html(out, inputs).html);
  EXPECT_NE(failed.find("not closed: the last frame does not register: &lt;too few matches&gt; (requested: "
                        "--loop-closure on)"),
            std::string::npos);
  EXPECT_EQ(failed.find("Quality with and without deformation"), std::string::npos);
  EXPECT_NE(failed.find("Deformation and loop closure"), std::string::npos);
  inputs.report["loop_closure"] = {{"requested", false}, {"why", "--loop-closure off"}};
  EXPECT_NE(read_file_text(write_scan_report_html(out, inputs).html).find("not requested: --loop-closure off"),
            std::string::npos);
}

TEST_F(ScanReport, WithoutDeformationNothingOfIt) {
  // --deformation off: report.json says so, no tracked poses; even a cloud with a
  // "correction" property gets no correction heat map.
  ScanReportInputs inputs;
  inputs.report = scan_report_json();
  inputs.report["deformation"] = {{"enabled", false}};
  inputs.report["loop_closure"] = {{"requested", false}, {"why", "--deformation off"}};
  PointCloud cloud = sphere_;
  cloud.properties.push_back({"correction", std::vector<float>(cloud.size(), 1e-6f)});
  inputs.cloud = &cloud;
  inputs.trajectory = circle_trajectory(24, 0.0);
  const std::string out = directory_.file("out");
  const std::string html = read_file_text(write_scan_report_html(out, inputs).html);
  for (const char* needle : {"Deformation and loop closure", "Quality with and without deformation",
                             "deformation-chart", "viridis-correction", "report_correction_"}) {
    EXPECT_EQ(html.find(needle), std::string::npos) << needle;
  }
  EXPECT_FALSE(std::filesystem::exists(out + "/report_correction_0.png"));
  EXPECT_EQ(check_images(out, html).size(), 3u);
}

TEST_F(ScanReport, AnEmptyReportStillWritesAPage) {
  const ScanReportFiles files = write_scan_report_html(directory_.file("bare"), ScanReportInputs());
  const std::string html = read_file_text(files.html);
  EXPECT_NE(html.find("No points to render"), std::string::npos);
  EXPECT_NE(html.find("No trajectory"), std::string::npos);
  EXPECT_TRUE(files.images.empty());
}

}  // namespace
}  // namespace sls::report
