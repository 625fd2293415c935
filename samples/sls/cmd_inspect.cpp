// sls inspect: checks files of every format the SDK reads and prints what they hold.
// A corrupt file is reported with the SDK's error (file and problem); the exit status is 1
// when any path fails.
#include <filesystem>
#include <iostream>

#include "samples/sls/commands.h"
#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"

namespace sls::cli {
namespace {

std::string lowercase_extension(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

nlohmann::json inspect_recording(const std::string& path, bool deep, const ProgressCallback& progress) {
  const RecordingReader recording = RecordingReader::open(path);
  const RecordingInfo& info = recording.info();
  recording.verify(false);
  std::size_t incomplete = 0, with_depth = 0, with_angle = 0;
  for (std::size_t i = 0; i < recording.frame_count(); ++i) {
    const FrameInfo& frame = recording.frame(i);
    incomplete += frame.complete ? 0u : 1u;
    with_depth += frame.has_depth() ? 1u : 0u;
    with_angle += frame.turntable_angle_deg ? 1u : 0u;
    if (deep) {
      (void)recording.load_images(i);
      if (frame.has_depth()) (void)recording.load_depth_m(i);
      report_progress(progress, {"inspect", i + 1, recording.frame_count(), frame.image_files.empty() ? "" : frame.image_files[0]});
    }
  }
  return {{"kind", "recording"},
          {"device", {{"uri", info.device.uri}, {"model", info.device.model}, {"serial", info.device.serial}}},
          {"camera", {{"width", info.camera.width}, {"height", info.camera.height}, {"bit_depth", info.camera.bit_depth}}},
          {"images_per_frame", info.images_per_frame},
          {"frames", recording.frame_count()},
          {"incomplete_frames", incomplete},
          {"frames_with_depth", with_depth},
          {"frames_with_turntable_angle", with_angle},
          {"calibrated", recording.has_calibration()},
          {"groundtruth", !recording.groundtruth_folder().empty()},
          {"pixels_decoded", deep}};
}

nlohmann::json inspect_ply(const std::string& path) {
  const TriangleMesh mesh = read_ply_mesh(path);
  const PointCloud& cloud = mesh.vertices;
  nlohmann::json properties = nlohmann::json::array();
  for (const PointProperty& property : cloud.properties) properties.push_back(property.name);
  nlohmann::json result = {{"kind", mesh.faces.empty() ? "point_cloud" : "mesh"},
                           {"points", cloud.size()},
                           {"faces", mesh.faces.size()},
                           {"normals", cloud.has_normals()},
                           {"confidence", cloud.has_confidence()},
                           {"colors", cloud.has_colors()},
                           {"properties", properties}};
  if (!cloud.empty()) {
    Eigen::Vector3f low = cloud.positions[0], high = cloud.positions[0];
    for (const Eigen::Vector3f& p : cloud.positions) {
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
    }
    result["bounds_min_m"] = {low.x(), low.y(), low.z()};
    result["bounds_max_m"] = {high.x(), high.y(), high.z()};
  }
  return result;
}

nlohmann::json camera_json(const CameraIntrinsics& c) {
  return {{"width", c.width}, {"height", c.height}, {"fx", c.fx}, {"fy", c.fy}, {"cx", c.cx}, {"cy", c.cy},
          {"k1", c.k1}, {"k2", c.k2}, {"k3", c.k3}, {"p1", c.p1}, {"p2", c.p2}};
}

nlohmann::json inspect_calibration(const std::string& path) {
  const ScannerCalibration calibration = read_calibration(path);
  const Eigen::Vector3d baseline = calibration.T_camera_projector.translation();
  // A multi-camera head's other cameras: each lens and its pose against camera 0.
  nlohmann::json additional = nlohmann::json::array();
  for (const AdditionalCamera& extra : calibration.additional_cameras) {
    additional.push_back({{"camera", camera_json(extra.intrinsics)},
                          {"baseline_to_camera0_m", extra.T_camera0_camera.translation().norm()},
                          {"angle_to_camera0_deg", extra.T_camera0_camera.angle_rad() * 180.0 / M_PI}});
  }
  return {{"kind", "calibration"},
          {"camera_count", calibration.camera_count()},
          {"additional_cameras", additional},
          {"camera", camera_json(calibration.camera)},
          {"projector", camera_json(calibration.projector)},
          {"baseline_m", baseline.norm()},
          {"projector_angle_deg", calibration.T_camera_projector.angle_rad() * 180.0 / M_PI},
          {"turntable_axis", calibration.turntable.has_value()},
          {"reprojection_rms_px", calibration.reprojection_rms_px},
          {"description", calibration.description}};
}

nlohmann::json inspect_trajectory(const std::string& path) {
  const std::vector<StampedPose> poses = read_tum_trajectory(path);
  double length_m = 0.0;
  for (std::size_t i = 1; i < poses.size(); ++i) {
    length_m += (poses[i].T_world_camera.translation() - poses[i - 1].T_world_camera.translation()).norm();
  }
  return {{"kind", "trajectory"},
          {"poses", poses.size()},
          {"duration_s", poses.empty() ? 0.0 : poses.back().timestamp_s - poses.front().timestamp_s},
          {"path_length_m", length_m}};
}

nlohmann::json inspect_png(const std::string& path) {
  const PngHeader header = read_png_header(path);
  (void)read_png(path);  // decode too: a truncated image has a valid header
  return {{"kind", "image"}, {"width", header.width}, {"height", header.height}, {"bit_depth", header.bit_depth}};
}

nlohmann::json inspect_path(const std::string& path, bool deep, const ProgressCallback& progress) {
  if (std::filesystem::is_directory(path)) return inspect_recording(path, deep, progress);
  if (!std::filesystem::exists(path)) throw_error(ErrorCode::kNotFound, "{}: no such file or folder", path);
  const std::string extension = lowercase_extension(path);
  if (extension == ".ply") return inspect_ply(path);
  if (extension == ".yml" || extension == ".yaml") return inspect_calibration(path);
  if (extension == ".txt" || extension == ".tum") return inspect_trajectory(path);
  if (extension == ".png") return inspect_png(path);
  if (std::filesystem::path(path).filename() == "manifest.json") {
    return inspect_recording(std::filesystem::path(path).parent_path().string(), deep, progress);
  }
  throw_error(ErrorCode::kInvalidArgument,
              "{}: unknown kind of file (expected a recording folder, .ply, .yml/.yaml, .txt/.tum or .png)", path);
}

void print_human(const std::string& path, const nlohmann::json& result) {
  std::cout << path << ": " << result["kind"].get<std::string>() << "\n";
  for (const auto& [key, value] : result.items()) {
    if (key != "kind" && key != "path" && key != "ok") std::cout << "  " << key << ": " << value.dump() << "\n";
  }
}

}  // namespace

void add_inspect_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "inspect", "Check recordings, PLY files, calibrations, TUM trajectories and PNG images, and summarise them");
  auto paths = std::make_shared<std::vector<std::string>>();
  auto deep = std::make_shared<bool>(false);
  command->add_option("paths", *paths, "Recording folders or files")->required();
  command->add_flag("--deep", *deep, "For recordings, decode every image and depth map (slow), not only headers");
  command->callback([&context, exit_code, paths, deep] {
    run_command(context, "inspect", [&context, paths, deep] {
      nlohmann::json results = nlohmann::json::array();
      int failures = 0;
      for (const std::string& path : *paths) {
        nlohmann::json result;
        try {
          result = inspect_path(path, *deep, context.progress_callback("inspect"));
          result["ok"] = true;
          if (!context.options.json) print_human(path, result);
        } catch (const Error& error) {
          ++failures;
          result = {{"ok", false}, {"status_name", error_code_name(error.code())}, {"message", error.what()}};
          std::cerr << "sls inspect: error: " << error.what() << "\n";
        }
        result["path"] = path;
        results.push_back(result);
      }
      if (context.options.json) std::cout << nlohmann::json{{"ok", failures == 0}, {"results", results}}.dump(2) << "\n";
      return failures == 0 ? kExitOk : kExitError;
    }, exit_code);
  });
}

}  // namespace sls::cli
