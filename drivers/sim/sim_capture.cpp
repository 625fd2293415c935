#include "drivers/sim/sim_capture.h"

#include <cmath>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"

namespace sls::sim {
namespace {

nlohmann::json pose_json(const Pose& pose) {
  const Eigen::Matrix4d m = pose.matrix();
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

}  // namespace

SimDevices start_sim_devices(SimScanner& scanner) {
  SimDevices devices{scanner.camera(), scanner.projector(), scanner.turntable()};
  devices.projector->load_patterns(scanner.rig().patterns);
  devices.turntable->home(kSimDeviceTimeout);
  devices.camera->set_trigger_source(drivers::TriggerSource::kSoftware);
  devices.camera->start();
  return devices;
}

void stop_sim_devices(SimDevices& devices) {
  devices.camera->stop();
  devices.projector->go_dark();
}

std::vector<Image16u> capture_pattern_stack(SimDevices& devices, int count, std::int64_t* first_timestamp_ns) {
  std::vector<Image16u> images;
  images.reserve(static_cast<std::size_t>(count));
  for (int pattern = 0; pattern < count; ++pattern) {
    devices.projector->show_pattern(pattern);
    devices.camera->software_trigger();
    drivers::CapturedImage captured = devices.camera->wait_image(kSimDeviceTimeout);
    if (pattern == 0) *first_timestamp_ns = captured.timestamp_ns;
    images.push_back(std::move(captured.image));
  }
  return images;
}

std::string rig_json(const SimRig& rig) {
  const RigOptics& o = rig.optics;
  const nlohmann::json json = {
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
        {"gamma", o.projector.gamma},
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
  return json.dump(2);
}

std::string write_frame_ground_truth(const GroundTruthFrame& truth, const std::string& groundtruth_folder) {
  const std::string frame_folder = fmt::format("{}/frames/{:06d}", groundtruth_folder, truth.frame);
  create_directories(frame_folder);
  // The new folder's entry is on disk before the files in it count (each is fsynced and
  // renamed into place by write_pfm / write_png).
  sync_directory(groundtruth_folder + "/frames");
  write_pfm(frame_folder + "/depth.pfm", truth.depth_m);
  write_pfm(frame_folder + "/projector_u.pfm", truth.projector_u);
  write_pfm(frame_folder + "/projector_v.pfm", truth.projector_v);
  write_pfm(frame_folder + "/depth_sigma.pfm", truth.depth_sigma_m);
  Image8u valid(truth.valid.width(), truth.valid.height());
  for (std::size_t i = 0; i < valid.pixel_count(); ++i) valid.data()[i] = truth.valid.data()[i] != 0 ? 255 : 0;
  write_png(frame_folder + "/valid.png", valid);
  return frame_folder;
}

SimRecordingSummary recording_summary(const SimScanner& scanner, int frames, int images_per_frame,
                                      const std::string& groundtruth_folder) {
  SimRecordingSummary summary;
  summary.uri = scanner.uri();
  summary.frames = frames;
  summary.images_per_frame = images_per_frame;
  summary.width = scanner.rig().camera.width;
  summary.height = scanner.rig().camera.height;
  summary.groundtruth_folder = groundtruth_folder;
  return summary;
}

}  // namespace sls::sim
