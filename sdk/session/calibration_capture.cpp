#include "sdk/session/calibration_capture.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <utility>

#include <fmt/format.h>

#include "drivers/device_registry.h"
#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/session/scan_setup.h"
#include "sdk/session/sim_charuco_board.h"

namespace sls::session {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The turntable as the sequencer sees it during a turntable pose: already at the pose's angle
// (moved before the stack, so that a failed move names the pose and the angle asked for), so
// the sequencer's home and move do nothing and its reading is the table's own.
class PlacedTurntable final : public drivers::Turntable {
 public:
  explicit PlacedTurntable(drivers::Turntable& table) : table_(table) {}
  void home(std::chrono::milliseconds) override {}
  void move_to_deg(double, std::chrono::milliseconds) override {}
  double position_deg() const override { return table_.position_deg(); }
  int steps_per_revolution() const override { return table_.steps_per_revolution(); }

 private:
  drivers::Turntable& table_;
};

void add_statistics(CaptureStatistics& total, const CaptureStatistics& run) {
  total.frames += run.frames;
  total.incomplete_frames += run.incomplete_frames;
  total.retries += run.retries;
  total.images += run.images;
  total.incomplete_images += run.incomplete_images;
  total.lost_images += run.lost_images;
  total.timeouts += run.timeouts;
  total.stale_images += run.stale_images;
  if (run.transport) {
    FrameTransportCounters& sum = total.transport ? *total.transport : total.transport.emplace();
    sum.resent_packets += run.transport->resent_packets;
    sum.missing_packets += run.transport->missing_packets;
    sum.queue_depth = std::max(sum.queue_depth, run.transport->queue_depth);
  }
  total.seconds += run.seconds;
  total.capture_seconds += run.capture_seconds;
  total.projector_seconds += run.projector_seconds;
  total.camera_seconds += run.camera_seconds;
}

// Whether a table reading and a commanded angle are the same table position (half a step).
bool same_angle(double reported_deg, double commanded_deg, int steps_per_revolution) {
  const double half_step = steps_per_revolution > 0 ? 180.0 / steps_per_revolution : 1e-6;
  return std::fabs(std::remainder(reported_deg - commanded_deg, 360.0)) <= half_step;
}

// What a failed capture kept, for its message: every camera's recording holds the same frames.
std::string frames_kept(const std::vector<RecordingWriter>& writers, const std::string& folder) {
  if (writers.size() == 1) return fmt::format("{} frame(s) are in {}", writers.front().frame_count(), folder);
  return fmt::format("{} frame(s) are in each of the {} cameras' recordings in {}", writers.front().frame_count(),
                     writers.size(), folder);
}

// The recordings of a head to continue (`folder`/camera0 .. camera{K−1}): each camera's own,
// checked as one camera's is, and all of them the same poses so far — a kill between two
// cameras' writes of one stack leaves them disagreeing, and calibrating such a head would pair
// the wrong views. Refused naming the folder that disagrees.
std::vector<RecordingWriter> continue_head(const std::string& folder, const std::vector<drivers::Camera*>& cameras,
                                           const drivers::Projector& projector, const PatternSet& patterns) {
  std::error_code error;
  const std::string extra = head_camera_folder(folder, cameras.size());
  if (std::filesystem::exists(extra, error)) {
    throw_error(ErrorCode::kInvalidArgument, "resume: {} holds {}: a head of more than the {} cameras given", folder,
                extra, cameras.size());
  }
  // The layout first: a head of another camera count is named as such, not by the first
  // difference one camera's recording shows.
  for (std::size_t k = 0; k < cameras.size(); ++k) {
    const std::string camera_folder = head_camera_folder(folder, k);
    if (!std::filesystem::exists(std::filesystem::path(camera_folder) / "manifest.json", error)) {
      throw_error(ErrorCode::kInvalidArgument,
                  "resume: {} holds no recording for camera {} ({}): not a head of {} cameras to continue", folder, k,
                  camera_folder, cameras.size());
    }
  }
  std::vector<RecordingWriter> writers;
  for (std::size_t k = 0; k < cameras.size(); ++k) {
    const std::string camera_folder = head_camera_folder(folder, k);
    try {
      writers.push_back(append_to_recording_of(camera_folder, projector, *cameras[k], patterns));
    } catch (const Error& failure) {
      throw Error(failure.code(), fmt::format("camera {} ({}): {}", k, cameras[k]->info().uri, failure.what()));
    }
  }
  const RecordingWriter& first = writers.front();
  for (std::size_t k = 1; k < writers.size(); ++k) {
    const RecordingWriter& writer = writers[k];
    if (writer.frame_count() != first.frame_count()) {
      throw_error(ErrorCode::kInvalidArgument,
                  "resume: {} holds {} pose(s), {} holds {}: the head's recordings disagree (one was cut off between "
                  "two cameras' writes); calibrate the poses all hold, or capture the head again",
                  writer.folder(), writer.frame_count(), first.folder(), first.frame_count());
    }
    for (std::size_t i = 0; i < writer.frame_count(); ++i) {
      if (writer.frame(i).turntable_angle_deg.has_value() != first.frame(i).turntable_angle_deg.has_value()) {
        throw_error(ErrorCode::kInvalidArgument,
                    "resume: frame {} of {} is a {} pose, of {} a {} pose: the head's recordings disagree", i,
                    writer.folder(), writer.frame(i).turntable_angle_deg ? "turntable" : "hand", first.folder(),
                    first.frame(i).turntable_angle_deg ? "turntable" : "hand");
      }
    }
  }
  return writers;
}

// The exact calibration of a head whose every camera is simulated (Camera::exact_calibration),
// as the simulator's own capture writes it: camera 0's (with the projector and the turntable
// axis), the others as additional cameras (T_camera0_cameraK = T_camera0_projector ·
// T_cameraK_projector⁻¹). nullopt when some camera has none (a real head).
std::optional<ScannerCalibration> exact_head_calibration(const std::vector<drivers::Camera*>& cameras) {
  std::vector<ScannerCalibration> exact;
  for (const drivers::Camera* camera : cameras) {
    std::optional<ScannerCalibration> each = camera->exact_calibration();
    if (!each) return std::nullopt;
    exact.push_back(std::move(*each));
  }
  ScannerCalibration head = exact.front();
  for (std::size_t k = 1; k < exact.size(); ++k) {
    head.additional_cameras.push_back(
        {exact[k].camera, exact.front().T_camera_projector * exact[k].T_camera_projector.inverse(), 0.0});
  }
  if (exact.size() > 1) {
    head.description = fmt::format("exact calibration of a simulated head of {} cameras (captured through its devices)",
                                   exact.size());
  }
  return head;
}

// A new recording for `camera`; a simulated camera's carries its exact calibration in
// groundtruth/calibration.yml (as `sls sim --calibration` writes it), so calibrating it
// reports the truth.
RecordingWriter create_recording(const std::string& folder, const drivers::Camera& camera,
                                 const drivers::Projector& projector, const PatternSet& patterns) {
  RecordingInfo info = make_recording_info(projector, camera, patterns);
  const std::optional<ScannerCalibration> exact = camera.exact_calibration();
  info.has_groundtruth = exact.has_value();
  RecordingWriter writer = RecordingWriter::create(folder, info, std::nullopt);  // made uncalibrated
  if (exact) write_calibration(writer.groundtruth_folder() + "/calibration.yml", *exact);
  return writer;
}

// New recordings for the capture: the one at `folder`, or one per camera of a head in it (a
// simulated head's exact calibration beside them, in `folder`/groundtruth/calibration.yml).
std::vector<RecordingWriter> create_recordings(const std::string& folder, const std::vector<drivers::Camera*>& cameras,
                                               const drivers::Projector& projector, const PatternSet& patterns) {
  std::vector<RecordingWriter> writers;
  if (cameras.size() == 1) {
    writers.push_back(create_recording(folder, *cameras.front(), projector, patterns));
    return writers;
  }
  std::error_code error;
  if (std::filesystem::exists(folder, error) && !std::filesystem::is_empty(folder, error)) {
    throw_error(ErrorCode::kInvalidArgument, "{}: the folder exists and is not empty; refusing to capture a head into it",
                folder);
  }
  for (std::size_t k = 0; k < cameras.size(); ++k) {
    writers.push_back(create_recording(head_camera_folder(folder, k), *cameras[k], projector, patterns));
  }
  if (const std::optional<ScannerCalibration> head = exact_head_calibration(cameras)) {
    std::filesystem::create_directories(std::filesystem::path(folder) / "groundtruth", error);
    write_calibration(folder + "/groundtruth/calibration.yml", *head);
  }
  return writers;
}

}  // namespace

std::vector<drivers::Camera*> CalibrationDevices::cameras() const {
  std::vector<drivers::Camera*> all = {camera};
  all.insert(all.end(), more_cameras.begin(), more_cameras.end());
  return all;
}

const char* calibration_pose_kind_name(CalibrationPoseKind kind) {
  return kind == CalibrationPoseKind::kHand ? "hand" : "turntable";
}

std::string CalibrationPose::describe() const {
  std::string text = fmt::format("{} pose {} of {}", calibration_pose_kind_name(kind), index + 1, count);
  if (turntable_angle_deg) text += fmt::format(" ({:.3f} deg)", *turntable_angle_deg);
  return text;
}

void CalibrationCaptureOptions::validate() const {
  if (hand_poses < 0 || hand_poses > 1000) {
    throw_error(ErrorCode::kInvalidArgument, "calibration capture: {} hand poses (0 .. 1000)", hand_poses);
  }
  if (turntable_angles_deg.size() > 1000) {
    throw_error(ErrorCode::kInvalidArgument, "calibration capture: {} turntable angles (at most 1000)",
                turntable_angles_deg.size());
  }
  for (const double angle : turntable_angles_deg) {
    if (!std::isfinite(angle) || angle < 0.0 || angle >= 360.0) {
      throw_error(ErrorCode::kInvalidArgument, "calibration capture: turntable angle {} deg (0 <= angle < 360)",
                  angle);
    }
  }
  if (hand_poses == 0 && turntable_angles_deg.empty()) {
    throw_error(ErrorCode::kInvalidArgument, "calibration capture: nothing to capture (no hand poses, no turntable angles)");
  }
  // The rest as the sequencer checks it.
  CaptureOptions capture;
  capture.exposure_us = exposure_us;
  capture.image_timeout = image_timeout;
  capture.turntable_timeout = turntable_timeout;
  capture.max_retries = max_retries;
  capture.validate();
}

int CalibrationCapture::captured_poses() const {
  return static_cast<int>(std::count_if(poses.begin(), poses.end(), [](const auto& p) { return p.captured; }));
}

int CalibrationCapture::skipped_poses() const { return static_cast<int>(poses.size()) - captured_poses(); }

PatternSet calibration_pattern_set(const drivers::Projector& projector) {
  const drivers::ProjectorInfo info = projector.info();
  GrayPhaseOptions options;
  options.projector_width = info.width;
  options.projector_height = info.height;
  options.rows = true;
  const bool diamond = info.width == 912 && info.height == 1140;  // the DLP4500
  options.row_phase_period_px = diamond ? 2 * options.phase_period_px : options.phase_period_px;
  return make_gray_phase_pattern_set(options);
}

CalibrationCapture capture_calibration(const std::string& folder, const CalibrationDevices& devices,
                                       const PatternSet& patterns, const CalibrationCaptureOptions& options,
                                       const PoseConfirmation& confirm, const ProgressCallback& progress) {
  const Clock::time_point start = Clock::now();
  options.validate();
  if (devices.projector == nullptr || devices.camera == nullptr) {
    throw_error(ErrorCode::kInvalidArgument, "calibration capture: no {}",
                devices.projector == nullptr ? "projector" : "camera");
  }
  const std::vector<drivers::Camera*> cameras = devices.cameras();
  for (std::size_t k = 1; k < cameras.size(); ++k) {
    if (cameras[k] == nullptr) throw_error(ErrorCode::kInvalidArgument, "calibration capture: camera {} is null", k);
    if (std::find(cameras.begin(), cameras.begin() + static_cast<std::ptrdiff_t>(k), cameras[k]) !=
        cameras.begin() + static_cast<std::ptrdiff_t>(k)) {
      throw_error(ErrorCode::kInvalidArgument, "calibration capture: camera {} is an earlier camera of the head again",
                  k);
    }
  }
  if (cameras.size() > static_cast<std::size_t>(ScannerCalibration::kMaxCameras)) {
    throw_error(ErrorCode::kInvalidArgument, "calibration capture: {} cameras (a head has at most {})", cameras.size(),
                ScannerCalibration::kMaxCameras);
  }
  if (!options.turntable_angles_deg.empty() && devices.turntable == nullptr) {
    throw_error(ErrorCode::kInvalidArgument, "calibration capture: {} turntable angle(s) but no turntable",
                options.turntable_angles_deg.size());
  }
  validate_pattern_set(patterns);
  std::vector<RecordingWriter> writers;
  if (!options.resume) {
    writers = create_recordings(folder, cameras, *devices.projector, patterns);
  } else if (cameras.size() == 1) {
    writers.push_back(append_to_recording_of(folder, *devices.projector, *devices.camera, patterns));
  } else {
    writers = continue_head(folder, cameras, *devices.projector, patterns);
  }
  // Camera 0's recording says what was done (the others hold the same poses: continue_head).
  RecordingWriter& writer = writers.front();
  std::vector<RecordingWriter*> recordings;
  for (RecordingWriter& each : writers) recordings.push_back(&each);

  CalibrationCapture result;
  result.folder = folder;
  result.cameras = static_cast<int>(cameras.size());
  result.images_per_frame = patterns.size();
  result.resumed_from = static_cast<int>(writer.frame_count());
  std::vector<double> angles_done;
  for (std::size_t i = 0; i < writer.frame_count(); ++i) {
    const std::optional<double>& angle = writer.frame(i).turntable_angle_deg;
    if (angle) angles_done.push_back(*angle);
  }
  const int hand_done = result.resumed_from - static_cast<int>(angles_done.size());

  // The poses still to capture: all of them in a new recording.
  std::vector<CalibrationPose> plan;
  const int first_hand = angles_done.empty() ? std::min(hand_done, options.hand_poses) : options.hand_poses;
  for (int k = first_hand; k < options.hand_poses; ++k) {
    plan.push_back({CalibrationPoseKind::kHand, k, options.hand_poses, std::nullopt});
  }
  const int table_count = static_cast<int>(options.turntable_angles_deg.size());
  const int steps = devices.turntable != nullptr ? devices.turntable->steps_per_revolution() : 0;
  for (int j = 0; j < table_count; ++j) {
    const double angle = options.turntable_angles_deg[static_cast<std::size_t>(j)];
    const bool done = std::any_of(angles_done.begin(), angles_done.end(),
                                  [&](double recorded) { return same_angle(recorded, angle, steps); });
    if (!done) plan.push_back({CalibrationPoseKind::kTurntable, j, table_count, angle});
  }

  bool homed = false;
  for (std::size_t p = 0; p < plan.size(); ++p) {
    const CalibrationPose& pose = plan[p];
    PoseDecision decision = PoseDecision::kCapture;
    try {
      if (confirm) decision = confirm(pose);
    } catch (const Error& error) {
      throw Error(error.code(), fmt::format("{}; {}", error.what(), frames_kept(writers, folder)));
    }
    if (decision == PoseDecision::kStop) {
      result.stopped = true;
      break;
    }
    CalibrationPoseResult record;
    record.pose = pose;
    ProgressUpdate update{"calibration capture", p + 1, plan.size(), pose.describe()};
    if (decision == PoseDecision::kSkip) {
      result.poses.push_back(record);
      update.detail += " skipped";
      try {
        report_progress(progress, update);
      } catch (const Error& error) {
        throw Error(error.code(), fmt::format("calibration capture cancelled after {}; {}", pose.describe(),
                                              frames_kept(writers, folder)));
      }
      continue;
    }

    const Clock::time_point pose_start = Clock::now();
    std::unique_ptr<PlacedTurntable> placed;
    if (pose.kind == CalibrationPoseKind::kTurntable) {
      const char* doing = "homing";
      try {
        if (!homed && options.home_turntable) devices.turntable->home(options.turntable_timeout);
        homed = true;
        doing = "moving";
        devices.turntable->move_to_deg(*pose.turntable_angle_deg, options.turntable_timeout);
      } catch (const Error& error) {
        throw Error(error.code(), fmt::format("calibration {}: {}, {} to {:.3f} deg: {}; {}", pose.describe(),
                                              devices.turntable_name, doing, *pose.turntable_angle_deg, error.what(),
                                              frames_kept(writers, folder)));
      }
      placed = std::make_unique<PlacedTurntable>(*devices.turntable);
    }
    // One stack: the recording's next frame, through the sequencer's checks and re-captures.
    CaptureOptions capture;
    capture.first_frame = static_cast<int>(writer.frame_count());
    capture.frames = capture.first_frame + 1;
    capture.home_turntable = false;
    capture.exposure_us = options.exposure_us;
    capture.trigger = options.trigger;
    capture.image_timeout = options.image_timeout;
    capture.turntable_timeout = options.turntable_timeout;
    capture.max_retries = options.max_retries;
    CaptureSequencer sequencer(*devices.projector, cameras, placed.get(), patterns, capture);
    const FrameCallback on_frame = [&record](const CapturedFrame& frame) {
      record.captured = true;
      record.frame = frame.recording_indices.empty() ? -1 : frame.recording_indices.front();
      record.turntable_angle_deg = frame.turntable_angle_deg;
      record.complete = frame.complete;
      record.note = frame.note;
    };
    // The sequencer reports once, after the frame is in the recording: the pose's progress.
    const ProgressCallback pose_progress = [&](const ProgressUpdate&) {
      record.seconds = seconds_since(pose_start);
      result.poses.push_back(record);
      return !progress || progress(update);
    };
    try {
      add_statistics(result.statistics, sequencer.run(recordings, on_frame, pose_progress));
    } catch (const Error& error) {
      if (error.code() == ErrorCode::kCancelled) {
        throw Error(error.code(), fmt::format("calibration capture cancelled after {}; {}", pose.describe(),
                                              frames_kept(writers, folder)));
      }
      throw Error(error.code(),
                  fmt::format("calibration {}: {}; {}", pose.describe(), error.what(), frames_kept(writers, folder)));
    }
  }
  for (RecordingWriter& each : writers) each.close();

  result.frames = static_cast<int>(writer.frame_count());
  for (std::size_t i = 0; i < writer.frame_count(); ++i) {
    ++(writer.frame(i).turntable_angle_deg ? result.turntable_frames : result.hand_frames);
  }
  for (const CalibrationPoseResult& pose : result.poses) result.capture_seconds += pose.seconds;
  result.seconds = seconds_since(start);
  return result;
}

CalibrationCapture capture_calibration_from_devices(const std::string& folder, const CalibrationDeviceRequest& request,
                                                    const CalibrationCaptureOptions& options,
                                                    const PoseConfirmation& confirm, const ProgressCallback& progress) {
  if (request.camera_uri.empty()) throw_error(ErrorCode::kInvalidArgument, "calibration capture: no camera URI");
  if (request.projector_uri.empty()) {
    throw_error(ErrorCode::kInvalidArgument,
                "calibration capture with {}: no projector URI (the device that shows the patterns)", request.camera_uri);
  }
  if (!options.turntable_angles_deg.empty() && request.turntable_uri.empty()) {
    throw_error(ErrorCode::kInvalidArgument, "calibration capture: {} turntable angle(s) but no turntable URI",
                options.turntable_angles_deg.size());
  }
  for (std::size_t k = 0; k < request.more_camera_uris.size(); ++k) {
    const std::string& uri = request.more_camera_uris[k];
    if (uri.empty()) throw_error(ErrorCode::kInvalidArgument, "calibration capture: camera {}'s URI is empty", k + 1);
    const auto earlier = std::find(request.more_camera_uris.begin(),
                                   request.more_camera_uris.begin() + static_cast<std::ptrdiff_t>(k), uri);
    if (uri == request.camera_uri || earlier != request.more_camera_uris.begin() + static_cast<std::ptrdiff_t>(k)) {
      throw_error(ErrorCode::kInvalidArgument, "calibration capture: camera {} ({}) is camera {} again", k + 1, uri,
                  uri == request.camera_uri ? 0 : earlier - request.more_camera_uris.begin() + 1);
    }
  }
  options.validate();  // before any device is opened
  const drivers::OpenOptions open_options = device_open_options(request.sim_device);
  const drivers::ScannerDevices opened =
      drivers::open_scanner_devices(request.projector_uri, request.camera_uri, request.turntable_uri, open_options);
  // The head's other cameras, closed before the projector (opened's) as open_scanner_devices does.
  std::vector<std::unique_ptr<drivers::Camera>> more_cameras;
  for (std::size_t k = 0; k < request.more_camera_uris.size(); ++k) {
    try {
      more_cameras.push_back(drivers::open_camera(request.more_camera_uris[k], open_options));
    } catch (const Error& error) {
      throw Error(error.code(), fmt::format("camera {}: {}", k + 1, error.what()));
    }
  }
  CalibrationDevices devices;
  devices.projector = opened.projector.get();
  devices.camera = opened.camera.get();
  for (const std::unique_ptr<drivers::Camera>& camera : more_cameras) devices.more_cameras.push_back(camera.get());
  devices.turntable = opened.turntable.get();
  devices.turntable_name = "turntable " + request.turntable_uri;
  const PatternSet patterns = request.patterns ? *request.patterns : calibration_pattern_set(*opened.projector);
  return capture_calibration(folder, devices, patterns, options, confirm, progress);
}

}  // namespace sls::session
