#include "drivers/sim/sim_recording.h"

#include "drivers/sim/sim_capture.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
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

void write_scene_ground_truth(const SimScanner& scanner, const std::string& folder, double spacing_m) {
  write_file_atomic(folder + "/scene.json", scanner.scene().to_json());
  write_file_atomic(folder + "/rig.json", rig_json(scanner.rig()));
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

  SimDevices devices = start_sim_devices(*scanner);
  const int frames = rig.turntable.steps_per_revolution;
  std::vector<StampedPose> trajectory;
  for (int frame = 0; frame < frames; ++frame) {
    devices.turntable->move_to_deg(rig.commanded_angle_deg(frame), kSimDeviceTimeout);
    FrameMetadata metadata;
    metadata.turntable_angle_deg = devices.turntable->position_deg();
    std::vector<Image16u> images;
    Image32f depth;
    if (depth_mode) {
      depth = scanner->depth_map();
      metadata.timestamp_ns = static_cast<std::int64_t>(frame) * 333'333'333;
    } else {
      images = capture_pattern_stack(devices, static_cast<int>(rig.patterns.size()), &metadata.timestamp_ns);
    }
    writer.append_frame(images, metadata, depth_mode ? &depth : nullptr);
    const GroundTruthFrame truth = scanner->ground_truth();
    write_frame_ground_truth(truth, truth_folder);
    trajectory.push_back({static_cast<double>(metadata.timestamp_ns) * 1e-9, truth.T_object_camera});
    // Rewritten every frame so an interrupted run keeps a trajectory for the frames it has.
    write_tum_trajectory(truth_folder + "/trajectory.txt", trajectory);
    report_progress(progress, {"capture", static_cast<std::size_t>(frame + 1), static_cast<std::size_t>(frames), ""});
  }
  stop_sim_devices(devices);
  writer.close();

  return recording_summary(*scanner, frames, info.images_per_frame, truth_folder);
}

}  // namespace sls::sim
