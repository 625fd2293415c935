#include "sdk/session/calibration_capture.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>

#include <fmt/format.h>

#include "drivers/device_registry.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/session/scan_setup.h"

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

std::string frames_kept(const RecordingWriter& writer) {
  return fmt::format("{} frame(s) are in {}", writer.frame_count(), writer.folder());
}

}  // namespace

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
  if (!options.turntable_angles_deg.empty() && devices.turntable == nullptr) {
    throw_error(ErrorCode::kInvalidArgument, "calibration capture: {} turntable angle(s) but no turntable",
                options.turntable_angles_deg.size());
  }
  validate_pattern_set(patterns);
  RecordingWriter writer =
      options.resume ? append_to_recording_of(folder, *devices.projector, *devices.camera, patterns)
                     : RecordingWriter::create(folder, make_recording_info(*devices.projector, *devices.camera, patterns),
                                               std::nullopt);  // made uncalibrated

  CalibrationCapture result;
  result.folder = folder;
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
      throw Error(error.code(), fmt::format("{}; {}", error.what(), frames_kept(writer)));
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
                                              frames_kept(writer)));
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
                                              frames_kept(writer)));
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
    CaptureSequencer sequencer(*devices.projector, {devices.camera}, placed.get(), patterns, capture);
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
      add_statistics(result.statistics, sequencer.run({&writer}, on_frame, pose_progress));
    } catch (const Error& error) {
      if (error.code() == ErrorCode::kCancelled) {
        throw Error(error.code(), fmt::format("calibration capture cancelled after {}; {}", pose.describe(),
                                              frames_kept(writer)));
      }
      throw Error(error.code(), fmt::format("calibration {}: {}; {}", pose.describe(), error.what(), frames_kept(writer)));
    }
  }
  writer.close();

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
  options.validate();  // before any device is opened
  drivers::OpenOptions open_options;
  open_options.sim_device = request.sim_device;
  const drivers::ScannerDevices opened =
      drivers::open_scanner_devices(request.projector_uri, request.camera_uri, request.turntable_uri, open_options);
  CalibrationDevices devices;
  devices.projector = opened.projector.get();
  devices.camera = opened.camera.get();
  devices.turntable = opened.turntable.get();
  devices.turntable_name = "turntable " + request.turntable_uri;
  const PatternSet patterns = request.patterns ? *request.patterns : calibration_pattern_set(*opened.projector);
  return capture_calibration(folder, devices, patterns, options, confirm, progress);
}

}  // namespace sls::session
