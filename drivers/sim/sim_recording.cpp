#include "drivers/sim/sim_recording.h"

#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <memory>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/sim/sim_capture.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/ply.h"
#include "sdk/core/recording.h"
#include "sdk/core/recording_writer_thread.h"
#include "sdk/core/trajectory.h"
#include "sdk/decode/hdr_fusion.h"

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


// The first key (dotted path) where two JSON documents differ, for a message.
std::string first_difference(const nlohmann::json& a, const nlohmann::json& b, const std::string& where = "") {
  if (a.is_object() && b.is_object()) {
    for (const auto& [key, value] : a.items()) {
      const std::string path = where.empty() ? key : where + "." + key;
      if (!b.contains(key)) return path;
      if (value != b.at(key)) return first_difference(value, b.at(key), path);
    }
    for (const auto& [key, value] : b.items()) {
      if (!a.contains(key)) return where.empty() ? key : where + "." + key;
    }
  }
  return where.empty() ? "(the whole file)" : where;
}

bool is_file(const std::string& path) {
  std::error_code error;
  return std::filesystem::is_regular_file(path, error);
}

// A stored ground-truth JSON (scene.json, rig.json) must equal what the options give now.
void check_same_json(const std::string& folder, const std::string& path, const std::string& expected,
                     const std::string& what) {
  if (!is_file(path)) return;  // cut off before it was written: it is written again
  const nlohmann::json stored = nlohmann::json::parse(read_file_text(path), nullptr, false);
  const nlohmann::json now = nlohmann::json::parse(expected);
  if (stored.is_discarded() || stored == now) return;  // unreadable: written again
  const std::string key = first_difference(stored, now);
  std::string pointer = "/" + key;
  for (char& c : pointer) c = c == '.' ? '/' : c;
  const auto value_at = [&pointer](const nlohmann::json& json) {
    const nlohmann::json::json_pointer at(pointer);
    return json.contains(at) ? json.at(at).dump() : std::string("nothing");
  };
  throw_error(ErrorCode::kInvalidArgument,
              "cannot resume {}: it was simulated with other {} ({}: recorded {}, these options give {})", folder, what,
              key, value_at(stored), value_at(now));
}

bool frame_ground_truth_complete(const std::string& truth_folder, int frame) {
  const std::string folder = fmt::format("{}/frames/{:06d}", truth_folder, frame);
  for (const char* name : {"depth.pfm", "projector_u.pfm", "projector_v.pfm", "depth_sigma.pfm", "valid.png"}) {
    if (!is_file(folder + "/" + name)) return false;
  }
  return true;
}

// Opens the cut-off recording at `folder` for appending after checking that `info` and the
// scanner (its URI: object, preset, frames, seed, noise, projector; rig.json and scene.json:
// every other option) are the recording's. Writes again what the listed frames lack.
RecordingWriter resume_recording(const std::string& folder, const RecordingInfo& info, SimScanner& scanner,
                                 std::vector<StampedPose>* trajectory) {
  RecordingWriter writer = RecordingWriter::append_to(folder);
  const RecordingInfo& recorded = writer.info();
  if (recorded.device.uri != info.device.uri) {
    throw_error(ErrorCode::kInvalidArgument, "cannot resume {}: it was simulated as {}; these options give {}",
                writer.folder(), recorded.device.uri, info.device.uri);
  }
  const bool same_format =
      recorded.camera.width == info.camera.width && recorded.camera.height == info.camera.height &&
      recorded.camera.bit_depth == info.camera.bit_depth && recorded.images_per_frame == info.images_per_frame &&
      nlohmann::json::parse(recorded.pattern_set_json) == nlohmann::json::parse(info.pattern_set_json) &&
      recorded.depth_offset_m == info.depth_offset_m && recorded.depth_unit_m == info.depth_unit_m &&
      recorded.exposures == info.exposures && recorded.has_groundtruth;
  if (!same_format) {
    throw_error(ErrorCode::kInvalidArgument,
                "cannot resume {}: it holds {}x{} {}-bit frames of {} images{}; these options give {}x{} {}-bit "
                "frames of {} images with ground truth (another --mode, --bit-depth, --projector or --exposures?)",
                writer.folder(), recorded.camera.width, recorded.camera.height, recorded.camera.bit_depth,
                recorded.images_per_frame, recorded.has_groundtruth ? " with ground truth" : " without ground truth",
                info.camera.width, info.camera.height, info.camera.bit_depth, info.images_per_frame);
  }
  const std::string truth_folder = writer.groundtruth_folder();
  check_same_json(writer.folder(), truth_folder + "/rig.json", rig_json(scanner.rig()), "rig options");
  check_same_json(writer.folder(), truth_folder + "/scene.json", scanner.scene().to_json(), "scene options");
  const int planned = scanner.rig().turntable.steps_per_revolution;
  if (static_cast<int>(writer.frame_count()) > planned) {
    throw_error(ErrorCode::kInvalidArgument, "cannot resume {}: it holds {} frames, more than the {} planned",
                writer.folder(), writer.frame_count(), planned);
  }
  for (std::size_t i = 0; i < writer.frame_count(); ++i) {
    const FrameInfo& frame = writer.frame(i);
    const double angle = scanner.rig().step_angle_deg(static_cast<int>(i));
    if (!frame.turntable_angle_deg || std::abs(*frame.turntable_angle_deg - angle) > 1e-9) {
      throw_error(ErrorCode::kInvalidArgument, "cannot resume {}: frame {} is at {}°, these options put it at {}°",
                  writer.folder(), i, frame.turntable_angle_deg ? fmt::format("{}", *frame.turntable_angle_deg) : "no angle",
                  angle);
    }
  }
  // The listed frames' poses, from the manifest's timestamps and the rig: the same numbers
  // (and so the same file) the first run wrote, without a pose of a frame it did not list.
  SimDevices devices = start_sim_devices(scanner);
  for (std::size_t i = 0; i < writer.frame_count(); ++i) {
    const int frame = static_cast<int>(i);
    if (!frame_ground_truth_complete(truth_folder, frame)) {
      devices.turntable->move_to_deg(scanner.rig().commanded_angle_deg(frame), kSimDeviceTimeout);
      write_frame_ground_truth(scanner.ground_truth(), truth_folder);
    }
    trajectory->push_back(
        {static_cast<double>(writer.frame(i).timestamp_ns) * 1e-9, scanner.rig().T_object_camera(frame)});
  }
  stop_sim_devices(devices);
  write_tum_trajectory(truth_folder + "/trajectory.txt", *trajectory);
  return writer;
}

// After a failure between writing trajectory.txt and listing its frame: cut the pose of the
// unlisted frame off in place (a truncation needs no free space, a full disk allows it).
void trim_trajectory(const std::string& path, const std::vector<StampedPose>& listed) {
  const std::string text = format_tum_trajectory(listed);
  std::string current;
  try {
    current = read_file_text(path);
  } catch (const Error&) {
    return;
  }
  // Best effort: the failure being reported matters more than this one.
  if (current.size() > text.size() && current.compare(0, text.size(), text) == 0) {
    if (::truncate(path.c_str(), static_cast<off_t>(text.size())) != 0) return;  // readers ignore the extra pose
  }
}

}  // namespace

SimRecordingSummary write_sim_recording(const std::string& folder, const SimRecordingOptions& options,
                                        const Device& device, const ProgressCallback& progress) {
  const std::shared_ptr<SimScanner> scanner = options.scene ? SimScanner::create(*options.scene, options.rig, device)
                                                            : SimScanner::create(options.object, options.rig, device);
  scanner->set_image_memory(options.image_memory);
  const SimRig& rig = scanner->rig();
  const bool depth_mode = options.depth_mode;
  const auto step = [&options](SimFrameStep at, int frame) {
    if (options.step_hook) options.step_hook(at, frame);
  };

  RecordingInfo info;
  info.device = {scanner->uri(), "slscan simulated scanner", "SIM-0"};
  info.camera = {rig.camera.width, rig.camera.height, rig.optics.camera_sensor.bit_depth};
  info.pattern_set_json = depth_mode ? "{}" : pattern_set_to_json(rig.patterns);
  const HdrExposures exposures = options.exposures.empty() ? HdrExposures{} : HdrExposures{options.exposures};
  exposures.validate();
  if (depth_mode && exposures.is_hdr()) {
    throw_error(ErrorCode::kInvalidArgument, "HDR exposures are for pattern images, not the depth-only mode");
  }
  if (exposures.is_hdr()) info.exposures = exposures.scales;
  info.images_per_frame = depth_mode ? 0 : static_cast<int>(rig.patterns.size() * exposures.count());
  info.has_groundtruth = true;
  // Depth maps around the 100 mm working distance: store 70 .. 135.5 mm at 1 µm steps.
  info.depth_offset_m = rig.optics.working_distance_m - 0.030;
  if (options.resume && !options.record) {
    throw_error(ErrorCode::kInvalidArgument,
                "resume continues the recording at {}; a capture that records nothing has none to continue", folder);
  }
  std::vector<StampedPose> trajectory;
  std::optional<RecordingWriter> writer;
  std::string truth_folder, trajectory_path;
  if (options.record) {
    writer.emplace(options.resume ? resume_recording(folder, info, *scanner, &trajectory)
                                  : RecordingWriter::create(folder, info, rig.calibration()));
    truth_folder = writer->groundtruth_folder();
    trajectory_path = truth_folder + "/trajectory.txt";
    const double spacing = options.reference_spacing_m > 0.0 ? options.reference_spacing_m
                                                             : default_reference_spacing_m(options.rig.preset);
    bool scene_written = true;
    for (const char* name : {"scene.json", "rig.json", "reference.ply", "creases.ply"}) {
      scene_written = scene_written && is_file(truth_folder + "/" + name);
    }
    if (!options.resume || !scene_written) write_scene_ground_truth(*scanner, truth_folder, spacing);
  }
  if (options.described) options.described(writer ? writer->info() : info, rig.calibration());

  // The frames' writes beside the capture (recording_writer_thread.h); destroyed before the
  // writer and the trajectory they use: unwinding writes every frame captured.
  RecordingWriterThread writes(folder, options.write_queue_frames);
  const auto keep_write_statistics = [&] {
    if (options.write_statistics != nullptr) *options.write_statistics = writes.statistics();
  };
  SimDevices devices = start_sim_devices(*scanner);
  const int frames = rig.turntable.steps_per_revolution;
  const int first = writer ? static_cast<int>(writer->frame_count()) : 0;
  try {
    for (int frame = first; frame < frames; ++frame) {
      devices.turntable->move_to_deg(rig.commanded_angle_deg(frame), kSimDeviceTimeout);
      FrameMetadata metadata;
      metadata.turntable_angle_deg = devices.turntable->position_deg();
      std::vector<Image16u> images;
      Image32f depth;
      if (depth_mode) {
        depth = scanner->depth_map();
        metadata.timestamp_ns = static_cast<std::int64_t>(frame) * 333'333'333;
      } else {
        // Exposure-major: the whole stack at each exposure in turn, as the capture sequencer does.
        for (std::size_t e = 0; e < exposures.count(); ++e) {
          if (exposures.is_hdr()) devices.camera->set_exposure_us(kSimNominalExposureUs * exposures.scales[e]);
          std::int64_t timestamp_ns = 0;
          std::vector<Image16u> stack =
              capture_pattern_stack(devices, static_cast<int>(rig.patterns.size()), &timestamp_ns);
          if (e == 0) metadata.timestamp_ns = timestamp_ns;
          for (Image16u& image : stack) images.push_back(std::move(image));
        }
      }
      step(SimFrameStep::kCaptured, frame);
      // Shared read-only between the writer thread and the scan that fuses the frame.
      auto stack = std::make_shared<const std::vector<Image16u>>(std::move(images));
      auto stored_depth = depth_mode ? std::make_shared<const Image32f>(std::move(depth)) : nullptr;
      if (writer) {
        // Everything of the frame goes to disk before the manifest lists it (sim_recording.h);
        // the ground truth of this turntable position is rendered now, written with the frame.
        auto truth = std::make_shared<const GroundTruthFrame>(scanner->ground_truth());
        writes.push(frame, [&, frame, stack, truth, stored_depth, metadata] {
          const auto before_listing = [&](int index) {
            if (index != frame) {
              throw_error(ErrorCode::kInternal, "{}: the recording numbers frame {} as {}", writer->folder(), frame,
                          index);
            }
            step(SimFrameStep::kImagesWritten, frame);
            write_frame_ground_truth(*truth, truth_folder);
            step(SimFrameStep::kGroundTruthWritten, frame);
            trajectory.push_back({static_cast<double>(metadata.timestamp_ns) * 1e-9, rig.T_object_camera(frame)});
            write_tum_trajectory(trajectory_path, trajectory);
            step(SimFrameStep::kTrajectoryWritten, frame);
          };
          try {
            writer->append_frame(*stack, metadata, stored_depth.get(), before_listing);
          } catch (...) {
            if (static_cast<int>(trajectory.size()) > frame) {
              trajectory.pop_back();
              trim_trajectory(trajectory_path, trajectory);
            }
            throw;
          }
          step(SimFrameStep::kListed, frame);
        });
      }
      if (options.on_recorded) {
        if (depth_mode) depth = recorded_depth_m(*stored_depth, info);  // as a replay reads it back
        options.on_recorded(frame, stack, metadata, depth_mode ? &depth : nullptr);
      }
      report_progress(progress, {"capture", static_cast<std::size_t>(frame + 1), static_cast<std::size_t>(frames), ""});
    }
    writes.finish();
  } catch (...) {
    // Every frame captured is written before this rethrows (a write error then is logged).
    writes.drain();
    keep_write_statistics();
    throw;
  }
  keep_write_statistics();
  stop_sim_devices(devices);
  if (writer) writer->close();

  SimRecordingSummary summary = recording_summary(*scanner, frames, info.images_per_frame, truth_folder);
  summary.resumed_from = options.resume ? first : 0;
  return summary;
}

}  // namespace sls::sim
