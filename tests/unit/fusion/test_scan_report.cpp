// The scan report (samples/sls/scan_report.h): splat renders that show the object and its
// shading, heat-map colours that follow the errors, the trajectory plot, and report.html with
// its figures and PNGs, with and without ground truth.
#include "samples/sls/scan_report.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

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

TEST_F(ScanReport, AnEmptyReportStillWritesAPage) {
  const ScanReportFiles files = write_scan_report_html(directory_.file("bare"), ScanReportInputs());
  const std::string html = read_file_text(files.html);
  EXPECT_NE(html.find("No points to render"), std::string::npos);
  EXPECT_NE(html.find("No trajectory"), std::string::npos);
  EXPECT_TRUE(files.images.empty());
}

}  // namespace
}  // namespace sls::report
