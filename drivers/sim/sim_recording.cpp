#include "drivers/sim/sim_recording.h"

#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/sim/sim_scanner.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"

namespace sls::sim {
namespace {

// Reference sampling per preset: about the scan's own resolution, capped so the file stays
// in the hundreds of MB.
double default_reference_spacing_m(const std::string& preset) {
  if (preset == "ci") return 100e-6;
  if (preset == "demo") return 30e-6;
  return 10e-6;
}

nlohmann::json pose_json(const Pose& pose) {
  const Eigen::Matrix4d m = pose.matrix();
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

nlohmann::json rig_json(const SimRig& rig) {
  const RigOptics& o = rig.optics;
  return {
      {"preset", rig.preset},
      {"camera_sensor",
       {{"width", o.camera_sensor.width}, {"height", o.camera_sensor.height},
        {"pixel_pitch_m", o.camera_sensor.pixel_pitch_m}, {"full_well_e", o.camera_sensor.full_well_e},
        {"read_noise_e", o.camera_sensor.read_noise_e}, {"bit_depth", o.camera_sensor.bit_depth},
        {"gain_e_per_dn", o.camera_sensor.gain_e_per_dn}, {"black_level_dn", o.camera_sensor.black_level_dn},
        {"gamma", o.camera_sensor.gamma}}},
      {"camera_lens",
       {{"focal_length_m", o.camera_lens.focal_length_m}, {"f_number", o.camera_lens.f_number},
        {"focus_distance_m", o.camera_lens.focus_distance_m}}},
      {"projector",
       {{"width", o.projector.width}, {"height", o.projector.height},
        {"pixel_pitch_x_m", o.projector.pixel_pitch_x_m}, {"pixel_pitch_y_m", o.projector.pixel_pitch_y_m},
        {"focal_length_m", o.projector.lens.focal_length_m}, {"f_number", o.projector.lens.f_number},
        {"focus_distance_m", o.projector.lens.focus_distance_m}, {"contrast_ratio", o.projector.contrast_ratio},
        {"white_electrons", o.projector.white_electrons}}},
      {"triangulation_angle_deg", o.triangulation_angle_rad * 180.0 / M_PI},
      {"baseline_m", o.baseline_m},
      {"ambient_electrons", o.ambient_electrons},
      {"T_world_camera", pose_json(rig.T_world_camera)},
      {"T_camera_projector", pose_json(rig.T_camera_projector)},
      {"T_table_object", pose_json(rig.T_table_object)},
      {"turntable",
       {{"steps_per_revolution", rig.turntable.steps_per_revolution},
        {"angle_jitter_deg", rig.turntable.angle_jitter_deg}, {"mount_tilt_deg", rig.turntable.mount_tilt_deg},
        {"mount_offset_m", rig.turntable.mount_offset_m}, {"seed", rig.turntable.seed}}},
      {"noise", rig.noise},
      {"noise_seed", rig.noise_seed},
  };
}

void write_scene_ground_truth(const SimScanner& scanner, const std::string& folder, double spacing_m) {
  write_file_atomic(folder + "/scene.json", scanner.scene().to_json());
  write_file_atomic(folder + "/rig.json", rig_json(scanner.rig()).dump(2));
  write_ply(folder + "/reference.ply", scanner.scene().reference_cloud(spacing_m));
  PointCloud creases;
  PointProperty polyline{"polyline", {}};
  const std::vector<Polyline>& lines = scanner.scene().creases();
  for (std::size_t i = 0; i < lines.size(); ++i) {
    for (const Eigen::Vector3d& p : lines[i]) {
      creases.positions.push_back(p.cast<float>());
      polyline.values.push_back(static_cast<float>(i));
    }
  }
  creases.properties.push_back(std::move(polyline));
  write_ply(folder + "/creases.ply", creases);
}

void write_frame_ground_truth(const GroundTruthFrame& truth, const std::string& folder) {
  const std::string frame_folder = fmt::format("{}/frames/{:06d}", folder, truth.frame);
  create_directories(frame_folder);
  write_pfm(frame_folder + "/depth.pfm", truth.depth_m);
  write_pfm(frame_folder + "/projector_u.pfm", truth.projector_u);
  write_pfm(frame_folder + "/projector_v.pfm", truth.projector_v);
  write_pfm(frame_folder + "/depth_sigma.pfm", truth.depth_sigma_m);
  Image8u valid(truth.valid.width(), truth.valid.height());
  for (std::size_t i = 0; i < valid.pixel_count(); ++i) valid.data()[i] = truth.valid.data()[i] != 0 ? 255 : 0;
  write_png(frame_folder + "/valid.png", valid);
}

}  // namespace

SimRecordingSummary write_sim_recording(const std::string& folder, const SimRecordingOptions& options,
                                        const Device& device, const ProgressCallback& progress) {
  const std::shared_ptr<SimScanner> scanner = SimScanner::create(options.object, options.rig, device);
  const SimRig& rig = scanner->rig();
  const bool depth_mode = options.depth_mode;

  RecordingInfo info;
  info.device = {scanner->uri(), "slscan simulated scanner", "SIM-0"};
  info.camera = {rig.camera.width, rig.camera.height, rig.optics.camera_sensor.bit_depth};
  info.pattern_set_json = depth_mode ? "{}" : pattern_set_to_json(rig.patterns);
  info.images_per_frame = depth_mode ? 0 : static_cast<int>(rig.patterns.size());
  info.has_groundtruth = true;
  // Depth maps around the 100 mm working distance: store 70 .. 135.5 mm at 1 µm steps.
  info.depth_offset_m = rig.optics.working_distance_m - 0.030;
  RecordingWriter writer = RecordingWriter::create(folder, info, rig.calibration());
  const std::string truth_folder = writer.groundtruth_folder();
  const double spacing =
      options.reference_spacing_m > 0.0 ? options.reference_spacing_m : default_reference_spacing_m(options.rig.preset);
  write_scene_ground_truth(*scanner, truth_folder, spacing);

  std::unique_ptr<drivers::Camera> camera = scanner->camera();
  std::unique_ptr<drivers::Projector> projector = scanner->projector();
  std::unique_ptr<drivers::Turntable> turntable = scanner->turntable();
  const std::chrono::milliseconds timeout(5000);
  projector->load_patterns(rig.patterns);
  turntable->home(timeout);
  camera->set_trigger_source(drivers::TriggerSource::kSoftware);
  camera->start();

  const int frames = rig.turntable.steps_per_revolution;
  std::vector<StampedPose> trajectory;
  for (int frame = 0; frame < frames; ++frame) {
    turntable->move_to_deg(rig.commanded_angle_deg(frame), timeout);
    FrameMetadata metadata;
    metadata.turntable_angle_deg = turntable->position_deg();
    std::vector<Image16u> images;
    Image32f depth;
    if (depth_mode) {
      depth = scanner->depth_map();
      metadata.timestamp_ns = static_cast<std::int64_t>(frame) * 333'333'333;
    } else {
      for (int pattern = 0; pattern < static_cast<int>(rig.patterns.size()); ++pattern) {
        projector->show_pattern(pattern);
        camera->software_trigger();
        drivers::CapturedImage captured = camera->wait_image(timeout);
        if (pattern == 0) metadata.timestamp_ns = captured.timestamp_ns;
        images.push_back(std::move(captured.image));
      }
    }
    writer.append_frame(images, metadata, depth_mode ? &depth : nullptr);
    const GroundTruthFrame truth = scanner->ground_truth();
    write_frame_ground_truth(truth, truth_folder);
    trajectory.push_back({static_cast<double>(metadata.timestamp_ns) * 1e-9, truth.T_object_camera});
    // Rewritten every frame so an interrupted run keeps a trajectory for the frames it has.
    write_tum_trajectory(truth_folder + "/trajectory.txt", trajectory);
    report_progress(progress, {"capture", static_cast<std::size_t>(frame + 1), static_cast<std::size_t>(frames), ""});
  }
  camera->stop();
  projector->go_dark();
  writer.close();

  SimRecordingSummary summary;
  summary.uri = scanner->uri();
  summary.frames = frames;
  summary.images_per_frame = info.images_per_frame;
  summary.width = rig.camera.width;
  summary.height = rig.camera.height;
  summary.groundtruth_folder = truth_folder;
  return summary;
}

}  // namespace sls::sim
