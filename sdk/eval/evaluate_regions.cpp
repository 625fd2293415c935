#include "sdk/eval/evaluate_regions.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/ray_map.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"

namespace sls::eval {

ViewRegionErrors view_region_errors(const PointCloud& model_world, const Image32f& raw_depth_m,
                                    const CameraIntrinsics& camera, const Pose& T_world_camera,
                                    const sim::Scene* scene, const Pose& T_object_world,
                                    const RegionOptions& options) {
  if (!model_world.empty() && !model_world.has_normals()) {
    throw_error(ErrorCode::kInvalidArgument, "region errors: the model has no normals (the view test needs them)");
  }
  if (raw_depth_m.width() != camera.width || raw_depth_m.height() != camera.height) {
    throw_error(ErrorCode::kInvalidArgument, "region errors: a {}x{} raw depth map for a {}x{} camera",
                raw_depth_m.width(), raw_depth_m.height(), camera.width, camera.height);
  }
  if (options.window_radius_px < 0 || options.window_radius_px > 64 || !(options.visibility_gate_m > 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "region errors: window radius {} px (0..64) or gate {} m (> 0)",
                options.window_radius_px, options.visibility_gate_m);
  }
  const RayMap rays = compute_ray_map(camera);
  const Pose T_camera_world = T_world_camera.inverse();
  const Eigen::Vector3d camera_centre_world = T_world_camera.translation();
  const int width = camera.width;
  const int height = camera.height;
  const int r = options.window_radius_px;
  const auto count = static_cast<std::ptrdiff_t>(model_world.size());
  // Per point: its region (-1: not seen) and its distance to the raw scan.
  std::vector<std::int8_t> region(model_world.size(), -1);
  std::vector<double> to_raw(model_world.size(), 0.0);
#pragma omp parallel for schedule(dynamic, 4096)
  for (std::ptrdiff_t n = 0; n < count; ++n) {
    const auto i = static_cast<std::size_t>(n);
    const Eigen::Vector3d p_world = model_world.positions[i].cast<double>();
    const Eigen::Vector3d n_world = model_world.normals[i].cast<double>();
    if (n_world.dot(camera_centre_world - p_world) <= 0.0) continue;  // faces away
    const Eigen::Vector3d p = T_camera_world * p_world;
    Vec2d pixel;
    if (!project(camera, Vec3d{p.x(), p.y(), p.z()}, &pixel)) continue;
    const int u = static_cast<int>(std::lround(pixel.x));
    const int v = static_cast<int>(std::lround(pixel.y));
    if (u < 0 || v < 0 || u >= width || v >= height) continue;
    const float z_raw = raw_depth_m(u, v);
    if (!(z_raw > 0.0f) || std::fabs(p.z() - static_cast<double>(z_raw)) > options.visibility_gate_m) continue;
    double best = std::numeric_limits<double>::infinity();
    for (int y = std::max(v - r, 0); y <= std::min(v + r, height - 1); ++y) {
      for (int x = std::max(u - r, 0); x <= std::min(u + r, width - 1); ++x) {
        const float z = raw_depth_m(x, y);
        if (!(z > 0.0f) || !rays.is_valid(x, y)) continue;
        const Vec3f& ray = rays.ray(x, y);
        const double depth = static_cast<double>(z);
        const Eigen::Vector3d q(static_cast<double>(ray.x) * depth, static_cast<double>(ray.y) * depth, depth);
        best = std::min(best, (q - p).squaredNorm());
      }
    }
    to_raw[i] = std::sqrt(best);  // the centre pixel is valid, so finite
    region[i] = static_cast<std::int8_t>((v < height / 2 ? 0 : 2) + (u < width / 2 ? 0 : 1));
  }

  ViewRegionErrors errors;
  errors.model_points = model_world.size();
  static const char* const kNames[4] = {"upper-left", "upper-right", "lower-left", "lower-right"};
  std::vector<Eigen::Vector3d> seen_object;
  std::vector<std::int8_t> seen_region;
  std::vector<double> raw_by_region[4], raw_all;
  for (std::size_t i = 0; i < model_world.size(); ++i) {
    if (region[i] < 0) continue;
    raw_by_region[static_cast<std::size_t>(region[i])].push_back(to_raw[i]);
    raw_all.push_back(to_raw[i]);
    seen_region.push_back(region[i]);
    if (scene != nullptr) seen_object.push_back(T_object_world * model_world.positions[i].cast<double>());
  }
  errors.visible_points = raw_all.size();
  std::vector<double> surface_by_region[4], surface_all;
  if (scene != nullptr) {
    std::vector<float> point_errors;
    surface_errors(seen_object, *scene, 0.0, &point_errors);
    for (std::size_t k = 0; k < point_errors.size(); ++k) {
      surface_by_region[static_cast<std::size_t>(seen_region[k])].push_back(point_errors[k]);
      surface_all.push_back(point_errors[k]);
    }
  }
  for (std::size_t q = 0; q < 4; ++q) {
    errors.regions[q].name = kNames[q];
    errors.regions[q].to_raw_scan = distance_stats(std::move(raw_by_region[q]));
    errors.regions[q].to_surface = distance_stats(std::move(surface_by_region[q]));
  }
  errors.all.name = "all";
  errors.all.to_raw_scan = distance_stats(std::move(raw_all));
  errors.all.to_surface = distance_stats(std::move(surface_all));
  return errors;
}

ViewRegionErrors result_region_errors(const EvalReport& report, const std::string& raw_depth_path, int frame_index,
                                      const RegionOptions& options) {
  const RecordingReader recording = RecordingReader::open(report.recording_folder);
  if (frame_index < 0 || static_cast<std::size_t>(frame_index) >= recording.frame_count()) {
    throw_error(ErrorCode::kInvalidArgument, "--raw-scan-frame {}: {} has frames 0..{}", frame_index,
                report.recording_folder, recording.frame_count() - 1);
  }
  const double timestamp_s = static_cast<double>(recording.frame(static_cast<std::size_t>(frame_index)).timestamp_ns) * 1e-9;
  const std::string trajectory_path = report.result_folder + "/trajectory.txt";
  if (!std::filesystem::exists(trajectory_path)) {
    throw_error(ErrorCode::kNotFound, "{} not found: the raw scan is registered by the result's pose of its view",
                trajectory_path);
  }
  std::optional<Pose> T_world_camera;
  for (const StampedPose& pose : read_tum_trajectory(trajectory_path)) {
    if (std::fabs(pose.timestamp_s - timestamp_s) <= kTimestampTolerance_s) T_world_camera = pose.T_world_camera;
  }
  if (!T_world_camera) {
    throw_error(ErrorCode::kInvalidArgument, "{} has no pose of frame {} (t = {} s): was it lost?", trajectory_path,
                frame_index, timestamp_s);
  }
  // The camera the result was decoded with: report.json names the calibration when it is not
  // the recording's own (`sls scan --calibration`).
  std::string calibration_path = recording.folder() + "/calibration.yml";
  const std::string scan_report = report.result_folder + "/report.json";
  if (std::filesystem::exists(scan_report)) {
    const nlohmann::json json = nlohmann::json::parse(read_file_text(scan_report), nullptr, false);
    if (json.is_object() && json.contains("calibration") && json["calibration"].is_string()) {
      calibration_path = json["calibration"].get<std::string>();
    }
  }
  const CameraIntrinsics camera = read_calibration(calibration_path).camera;
  const Image32f raw_depth = read_pfm(raw_depth_path);
  const sim::Scene scene = sim::scene_from_json(read_file_text(recording.groundtruth_folder() + "/scene.json"));
  return view_region_errors(read_ply_cloud(report.result_folder + "/cloud.ply"), raw_depth, camera, *T_world_camera,
                            &scene, report.T_object_world, options);
}

}  // namespace sls::eval
