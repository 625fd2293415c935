#include "sdk/session/scan_setup.h"

#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <utility>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/device_registry.h"
#include "drivers/interfaces/device_uri.h"
#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/ply.h"
#include "sdk/session/hdr_frame.h"
#include "sdk/session/sim_charuco_board.h"

namespace sls::session {

PatternSet scan_pattern_set(const drivers::Projector& projector) {
  const drivers::ProjectorInfo info = projector.info();
  GrayPhaseOptions options;
  options.projector_width = info.width;
  options.projector_height = info.height;
  return make_gray_phase_pattern_set(options);
}

namespace {

// The writer that continues `folder` (request.resume): its recording must be what these devices
// capture (camera size and depth, pattern set, projector) and its frames where this frame count
// puts them; `capture` then starts at its first missing frame.
RecordingWriter resume_writer(const std::string& folder, const drivers::Projector& projector,
                              const drivers::Camera& camera, const drivers::Turntable* turntable,
                              const PatternSet& patterns, CaptureOptions* capture) {
  RecordingWriter writer = append_to_recording_of(folder, projector, camera, patterns, capture->exposures);
  const int listed = static_cast<int>(writer.frame_count());
  if (listed > capture->frames) {
    throw_error(ErrorCode::kInvalidArgument, "resume: {} holds {} frames, more than the {} asked for", folder, listed,
                capture->frames);
  }
  // Each recorded angle must be where this frame count puts that frame: another frame count
  // or another turntable would fill the revolution with frames at the wrong angles.
  const double step_deg = 360.0 / capture->frames_per_revolution;
  for (int i = 0; i < listed; ++i) {
    const std::optional<double>& angle = writer.frame(static_cast<std::size_t>(i)).turntable_angle_deg;
    if (angle.has_value() != (turntable != nullptr)) {
      throw_error(ErrorCode::kInvalidArgument, "resume: {} was captured {} a turntable; give {} turntable", folder,
                  angle ? "with" : "without", angle ? "the same" : "no");
    }
    if (angle && std::abs(*angle - step_deg * i) > 0.5 * step_deg) {
      throw_error(ErrorCode::kInvalidArgument,
                  "resume: frame {} of {} is at {:.3f} deg; {} frames per revolution put it at {:.3f} deg (another "
                  "frame count?)",
                  i, folder, *angle, capture->frames_per_revolution, step_deg * i);
    }
  }
  capture->first_frame = listed;
  return writer;
}

}  // namespace

RecordingWriter append_to_recording_of(const std::string& folder, const drivers::Projector& projector,
                                       const drivers::Camera& camera, const PatternSet& patterns,
                                       const std::vector<double>& exposures) {
  RecordingWriter writer = RecordingWriter::append_to(folder);
  const RecordingInfo& recorded = writer.info();
  const RecordingInfo now = make_recording_info(projector, camera, patterns, exposures);
  if (recorded.device.uri != now.device.uri) {
    throw_error(ErrorCode::kInvalidArgument, "resume: {} was captured with projector {}, not {}", folder,
                recorded.device.uri, now.device.uri);
  }
  if (recorded.camera.width != now.camera.width || recorded.camera.height != now.camera.height ||
      recorded.camera.bit_depth != now.camera.bit_depth || recorded.images_per_frame != now.images_per_frame ||
      recorded.exposures != now.exposures ||
      nlohmann::json::parse(recorded.pattern_set_json) != nlohmann::json::parse(now.pattern_set_json)) {
    throw_error(ErrorCode::kInvalidArgument,
                "resume: {} holds {}x{} {}-bit frames of {} patterns; this camera and pattern set give {}x{} {}-bit "
                "with {} patterns ('{}')",
                folder, recorded.camera.width, recorded.camera.height, recorded.camera.bit_depth,
                recorded.images_per_frame, now.camera.width, now.camera.height, now.camera.bit_depth,
                now.images_per_frame, patterns.name);
  }
  return writer;
}

DeviceCapture capture_from_devices(const std::string& folder, const DeviceCaptureRequest& request,
                                   const ProgressCallback& progress,
                                   const std::function<void(ScanFrame&& frame)>& recorded) {
  if (request.camera_uri.empty()) throw_error(ErrorCode::kInvalidArgument, "capture: no camera URI");
  if (request.projector_uri.empty()) {
    throw_error(ErrorCode::kInvalidArgument, "capture with {}: no projector URI (the device that shows the patterns)",
                request.camera_uri);
  }
  if (request.frames < 0) throw_error(ErrorCode::kInvalidArgument, "capture: {} frames (0 or more)", request.frames);
  if (request.resume && !request.record) {
    throw_error(ErrorCode::kInvalidArgument,
                "resume continues the recording at {}; a capture that records nothing has none to continue", folder);
  }
  if (request.resume && !request.calibration_path.empty()) {
    throw_error(ErrorCode::kInvalidArgument,
                "resume keeps the calibration {} was captured with; leave the calibration out", folder);
  }
  // Read before any device is touched: a bad calibration file fails at once.
  std::optional<ScannerCalibration> calibration;
  if (!request.calibration_path.empty()) calibration = read_calibration(request.calibration_path);

  const drivers::OpenOptions open_options = device_open_options(request.sim_device);
  const drivers::ScannerDevices opened =
      drivers::open_scanner_devices(request.projector_uri, request.camera_uri, request.turntable_uri, open_options);
  drivers::Projector* const projector = opened.projector.get();
  drivers::Camera* const camera = opened.camera.get();
  camera->set_image_memory(request.image_memory);
  drivers::Turntable* const turntable = opened.turntable.get();
  const PatternSet patterns = scan_pattern_set(*projector);
  CaptureOptions capture;
  capture.frames_per_revolution = request.frames > 0 ? request.frames : (turntable ? 36 : 1);
  capture.frames = capture.frames_per_revolution;
  capture.exposures = request.exposures;
  // A replay:// camera plays a recording that carries what its capture needs: its calibration
  // (unless one is given, or a resumed capture keeps its own) and, unless a frame count is
  // given, its frames (a turntable's revolution at the recorded steps).
  const drivers::DeviceUri camera_uri = drivers::parse_device_uri(request.camera_uri);
  if (camera_uri.scheme == "replay") {
    const RecordingReader replayed = RecordingReader::open(camera_uri.target);
    if (!calibration && !request.resume && replayed.has_calibration()) calibration = replayed.calibration();
    if (request.frames == 0) {
      capture.frames = static_cast<int>(replayed.frame_count());
      // A replay turntable's steps are the recorded ones (drivers/replay).
      const bool replay_turntable = turntable && drivers::parse_device_uri(request.turntable_uri).scheme == "replay";
      capture.frames_per_revolution = replay_turntable ? turntable->steps_per_revolution() : capture.frames;
    }
  }
  capture.write_queue_frames = request.write_queue_frames;
  capture.callback_holds_frames = recorded ? request.recorded_holds_frames : 0;
  std::optional<RecordingWriter> writer;
  if (request.record) {
    writer.emplace(request.resume
                       ? resume_writer(folder, *projector, *camera, turntable, patterns, &capture)
                       : RecordingWriter::create(folder,
                                                 make_recording_info(*projector, *camera, patterns, request.exposures),
                                                 calibration));
    // A resumed recording keeps the calibration it was captured with.
    if (request.resume && std::filesystem::exists(folder + "/calibration.yml")) {
      calibration = RecordingReader::open(folder).calibration();
    }
  }
  const RecordingInfo info =
      writer ? writer->info() : make_recording_info(*projector, *camera, patterns, request.exposures);
  if (request.described) request.described(info, calibration);
  CaptureSequencer sequencer(*projector, {camera}, turntable, patterns, capture);

  DeviceCapture result;
  result.recording_folder = folder;
  result.images_per_frame = patterns.size();
  result.resumed_from = capture.first_frame;
  FrameCallback on_frame;
  if (recorded) {
    // The frame as a replay of the recording would read it back (read_recording_frame).
    on_frame = [&recorded, &info](CapturedFrame& captured) {
      ScanFrame frame;
      frame.index = captured.recording_indices.empty() ? captured.index : captured.recording_indices.front();
      frame.timestamp_ns = captured.timestamp_ns();
      frame.turntable_angle_deg = captured.turntable_angle_deg;
      if (!captured.complete) {
        frame.problem = "incomplete pattern stack" + (captured.note.empty() ? std::string() : ": " + captured.note);
      } else {
        CameraStack& stack = captured.cameras.front();
        frame.images = std::move(stack.images);
        frame.shared_images = std::move(stack.shared_images);  // being written: shared, not copied
        try {
          fuse_hdr_frame(info, hdr_decode_options(info), &frame);
        } catch (const Error& error) {
          if (!is_frame_problem(error)) throw;
          frame.images.clear();
          frame.shared_images.reset();
          frame.problem = fmt::format("cannot read: {}", error.what());
        }
      }
      recorded(std::move(frame));
    };
  }
  try {
    result.statistics = sequencer.run(writer ? std::vector<RecordingWriter*>{&*writer} : std::vector<RecordingWriter*>{},
                                      on_frame, progress);
  } catch (...) {
    if (request.write_statistics != nullptr) *request.write_statistics = sequencer.statistics().writes;
    throw;
  }
  if (request.write_statistics != nullptr) *request.write_statistics = result.statistics.writes;
  result.calibrated = calibration.has_value();  // given now, or when first captured
  return result;
}

RecordingReader open_recording_for_scan(const std::string& folder, bool calibration_given) {
  // Its frames are not checked here: one bad image must not refuse the whole recording. Each
  // frame is read when it is scanned, and one that cannot be read is reported and skipped.
  RecordingReader recording = RecordingReader::open(folder);
  if (!calibration_given && !recording.has_calibration()) {
    throw_error(ErrorCode::kInvalidArgument, "{} has no calibration.yml: a scan needs a calibrated recording", folder);
  }
  return recording;
}

ScanSession make_recording_session(const RecordingReader& recording, ScanSessionOptions options,
                                   const ScannerCalibration* calibration) {
  const RecordingInfo& info = recording.info();
  if (calibration != nullptr &&
      (calibration->camera.width != info.camera.width || calibration->camera.height != info.camera.height)) {
    throw_error(ErrorCode::kInvalidArgument, "the calibration is of a {}x{} camera, {} was recorded at {}x{}",
                calibration->camera.width, calibration->camera.height, recording.folder(), info.camera.width,
                info.camera.height);
  }
  return make_capture_session(info, calibration != nullptr ? *calibration : recording.calibration(), std::move(options));
}

ScanSession make_capture_session(const RecordingInfo& info, const ScannerCalibration& calibration,
                                 ScanSessionOptions options) {
  options.decode.bit_depth = info.camera.bit_depth;
  std::optional<PatternSet> patterns;
  if (info.images_per_frame > 0) patterns = pattern_set_from_json(info.pattern_set_json);
  return ScanSession(calibration, patterns ? &*patterns : nullptr, options);
}

std::vector<StampedPose> groundtruth_poses(const RecordingReader& recording) {
  const std::string path = recording.groundtruth_folder() + "/trajectory.txt";
  if (!std::filesystem::exists(path)) {
    throw_error(ErrorCode::kInvalidArgument, "{} has no ground-truth trajectory (only simulated recordings do)",
                recording.folder());
  }
  std::vector<StampedPose> poses = read_tum_trajectory(path);
  // A capture killed between writing a frame's pose and listing the frame leaves the pose of
  // that unlisted frame last (drivers/sim/sim_recording.h): not one of the recording's.
  if (poses.size() == recording.frame_count() + 1) poses.pop_back();
  if (poses.size() != recording.frame_count()) {
    throw_error(ErrorCode::kFormat, "{}: {} poses for {} frames", path, poses.size(), recording.frame_count());
  }
  return poses;
}

fusion::VolumeGeometry groundtruth_volume(const RecordingReader& recording, double voxel_size_m, double max_voxels,
                                          const fusion::IntegrationOptions& integration) {
  const std::string reference_path = recording.groundtruth_folder() + "/reference.ply";
  if (!std::filesystem::exists(reference_path)) {
    throw_error(ErrorCode::kInvalidArgument, "{} has no ground-truth reference.ply to place the volume around",
                recording.folder());
  }
  const PointCloud reference = read_ply_cloud(reference_path);
  if (reference.empty()) throw_error(ErrorCode::kFormat, "{} holds no points", reference_path);
  Eigen::Vector3d lo = reference.positions[0].cast<double>(), hi = lo;
  for (const Eigen::Vector3f& p : reference.positions) {
    lo = lo.cwiseMin(p.cast<double>());
    hi = hi.cwiseMax(p.cast<double>());
  }
  const bool automatic = voxel_size_m <= 0.0;
  // Twice the pixel footprint at the working distance (the median depth is ~ the focus).
  double voxel = automatic ? 2.0 * 0.1 / recording.calibration().camera.fx : voxel_size_m;
  for (;;) {
    const double margin = (integration.eta_voxels + 2.0) * voxel;
    const Eigen::Vector3d size = (hi - lo).array() + 2.0 * margin;
    const Eigen::Vector3i counts = (size / voxel).array().ceil().cast<int>();
    const double total = static_cast<double>(counts.x()) * counts.y() * counts.z();
    if (total <= max_voxels || !automatic) {
      return fusion::VolumeGeometry::centred(0.5 * (lo + hi), counts.x(), counts.y(), counts.z(), voxel);
    }
    voxel *= std::cbrt(total / max_voxels) * 1.001;
  }
}

bool is_full_revolution(const RecordingReader& recording, std::string* why) {
  std::vector<std::optional<double>> angles;
  for (std::size_t i = 0; i < recording.frame_count(); ++i) angles.push_back(recording.frame(i).turntable_angle_deg);
  return is_full_revolution(angles, why);
}

bool is_full_revolution(const std::vector<std::optional<double>>& frame_angles, std::string* why) {
  std::vector<double> angles;
  for (const std::optional<double>& angle : frame_angles) {
    if (angle) angles.push_back(*angle);
  }
  const auto say = [why](std::string text) {
    if (why != nullptr) *why = std::move(text);
  };
  if (angles.size() < 3) {
    say("no turntable angles: not a turntable revolution");
    return false;
  }
  const double span = std::abs(angles.back() - angles.front());
  const double step = span / static_cast<double>(angles.size() - 1);
  if (span + 2.0 * step >= 360.0 - 1e-6) {
    say(fmt::format("a full turntable revolution ({:.1f}°)", span));
    return true;
  }
  say(fmt::format("the turntable turned {:.1f}°, not a full revolution", span));
  return false;
}

double automatic_max_voxels(const Device& device) { return (device.is_cuda() ? 256.0 : 48.0) * 1e6; }

}  // namespace sls::session
