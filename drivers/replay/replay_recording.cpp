#include "drivers/replay/replay_recording.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <set>
#include <thread>
#include <utility>

#include "drivers/interfaces/device_uri.h"
#include "sdk/core/error.h"

namespace sls::replay {

void ReplayClock::sleep_until(TimePoint when) { std::this_thread::sleep_until(when); }

namespace {

constexpr const char* kModelJoin = " + ";  // session::make_recording_info's "projector + camera"

// The reader's error with the URI in front: the file it names alone does not say which device.
[[noreturn]] void rethrow_for(const std::string& uri, const Error& error) {
  throw Error(error.code(), fmt::format("{}: {}", uri, error.what()));
}

}  // namespace

// One trigger's image, fixed when the trigger came: the frame played then and the pattern shown.
struct ReplayTrigger {
  std::size_t frame = 0;
  int pattern = 0;
  std::optional<Error> error;  // a pulse that found no image (end of the recording): thrown by wait_image
};

class ReplayCamera final : public drivers::Camera {
 public:
  explicit ReplayCamera(std::shared_ptr<ReplayRecording> replay) : replay_(std::move(replay)) {}
  ~ReplayCamera() override { stop(); }

  drivers::CameraInfo info() const override {
    const RecordingInfo& info = replay_->reader_.info();
    return {replay_->uri_, replay_->camera_model(), info.device.serial, info.camera.width, info.camera.height,
            info.camera.bit_depth};
  }
  void set_exposure_us(double exposure_us) override {
    if (!(exposure_us > 0.0)) throw_error(ErrorCode::kInvalidArgument, "exposure {} us must be positive", exposure_us);
    exposure_us_ = exposure_us;  // the recorded images keep the exposure they were taken with
  }
  double exposure_us() const override { return exposure_us_; }
  void set_trigger_source(drivers::TriggerSource source) override {
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    source_ = source;
  }
  void start() override {
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    started_ = true;
    pending_.clear();
    if (source_ == drivers::TriggerSource::kHardwareLine) listeners().insert(this);
  }
  void stop() override {
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    started_ = false;
    pending_.clear();
    listeners().erase(this);
  }
  void software_trigger() override {
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    if (!started_) throw_error(ErrorCode::kInvalidArgument, "{}: software trigger before start()", replay_->uri_);
    pending_.push_back(trigger_locked());
  }
  drivers::CapturedImage wait_image(std::chrono::milliseconds timeout) override {
    std::unique_lock<std::mutex> lock(replay_->mutex_);
    if (!started_ || pending_.empty()) {
      throw_error(ErrorCode::kTimeout, "{}: no image within {} ms (camera not started or not triggered)",
                  replay_->uri_, timeout.count());
    }
    ReplayTrigger trigger = std::move(pending_.front());
    pending_.pop_front();
    if (trigger.error) throw *trigger.error;
    replay_->pace_locked(trigger.frame, lock);
    const std::uint64_t frame_id = frame_id_++;
    lock.unlock();

    const RecordingReader& reader = replay_->reader_;
    const FrameInfo& frame = reader.frame(trigger.frame);
    drivers::CapturedImage captured;
    captured.timestamp_ns = frame.timestamp_ns;
    captured.frame_id = frame_id;
    const auto pattern = static_cast<std::size_t>(trigger.pattern);
    if (pattern < frame.image_files.size()) {
      try {
        captured.image = reader.load_image(trigger.frame, pattern);
      } catch (const Error& error) {
        rethrow_for(replay_->uri_, error);
      }
    } else {
      // What the transport lost live: the sequencer re-captures, then records the frame
      // incomplete with the images it has, as the recording did.
      captured.complete = false;
      captured.problem = fmt::format("{}: frame {} was recorded incomplete ({} of {} images{}{})", replay_->uri_,
                                     frame.index, frame.image_files.size(), reader.info().images_per_frame,
                                     frame.note.empty() ? "" : ": ", frame.note);
    }
    return captured;
  }

  // The projector fired its trigger output (under the lock).
  void pulse_locked() {
    try {
      pending_.push_back(trigger_locked());
    } catch (const Error& error) {
      ReplayTrigger failed;
      failed.error = error;
      pending_.push_back(std::move(failed));
    }
  }

 private:
  std::set<ReplayCamera*>& listeners() { return replay_->hardware_cameras_; }

  // The image a trigger now gets (under the lock): see the header's "Playback".
  ReplayTrigger trigger_locked() {
    ReplayRecording& replay = *replay_;
    const int pattern = replay.pattern_;
    if (pattern < 0) {
      throw_error(ErrorCode::kInvalidArgument,
                  "{}: triggered while its projector is dark; the camera gives the recorded image of the pattern "
                  "that the replay projector opened with the same URI shows",
                  replay.uri_);
    }
    ReplayTrigger trigger;
    trigger.pattern = pattern;
    if (replay.table_driven_) {
      if (!replay.table_frame_) replay.table_frame_ = replay.frame_at_angle_locked(0.0);  // homed, not moved
      trigger.frame = *replay.table_frame_;
      return trigger;
    }
    const std::size_t frames = replay.reader_.frame_count();
    if (last_pattern_ >= 0 && pattern <= last_pattern_) {  // a stack starts again
      const FrameInfo& played = replay.reader_.frame(cursor_);
      if (!played.complete) {
        throw_error(ErrorCode::kUnsupported,
                    "{}: frame {} was recorded incomplete; without the replay turntable a re-capture of it cannot be "
                    "told from the next frame (open the turntable {} too)",
                    replay.uri_, played.index, replay.uri_);
      }
      ++cursor_;
    }
    if (cursor_ >= frames) {
      throw_error(ErrorCode::kNotFound, "{}: end of the recording: its {} frame(s) were played", replay.uri_, frames);
    }
    last_pattern_ = pattern;
    trigger.frame = cursor_;
    return trigger;
  }

  std::shared_ptr<ReplayRecording> replay_;
  double exposure_us_ = 10000.0;
  drivers::TriggerSource source_ = drivers::TriggerSource::kSoftware;
  bool started_ = false;
  std::deque<ReplayTrigger> pending_;
  std::uint64_t frame_id_ = 0;
  // Without a turntable: the frame played and the last pattern triggered in it.
  std::size_t cursor_ = 0;
  int last_pattern_ = -1;
};

class ReplayProjector final : public drivers::Projector {
 public:
  explicit ReplayProjector(std::shared_ptr<ReplayRecording> replay)
      : replay_(std::move(replay)), patterns_(replay_->patterns_) {}

  drivers::ProjectorInfo info() const override {
    const PatternSet& recorded = replay_->patterns_;
    return {replay_->uri_, replay_->projector_model(), "replay", recorded.projector_width, recorded.projector_height};
  }
  void load_patterns(const PatternSet& patterns) override {
    validate_pattern_set(patterns);
    const PatternSet& recorded = replay_->patterns_;
    if (patterns != recorded) {
      throw_error(ErrorCode::kInvalidArgument,
                  "{}: the recording was captured with pattern set '{}' ({} patterns for a {}x{} projector), not "
                  "with '{}' ({} patterns for {}x{}){}",
                  replay_->uri_, recorded.name, recorded.size(), recorded.projector_width, recorded.projector_height,
                  patterns.name, patterns.size(), patterns.projector_width, patterns.projector_height,
                  patterns.name == recorded.name ? ": same name, other patterns" : "");
    }
    patterns_ = patterns;
  }
  const PatternSet& patterns() const override { return patterns_; }
  void show_pattern(int index) override {
    if (index < 0 || static_cast<std::size_t>(index) >= patterns_.size()) {
      throw_error(ErrorCode::kInvalidArgument, "{}: pattern {} of a set of {}", replay_->uri_, index,
                  patterns_.size());
    }
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    replay_->pattern_ = index;
    for (ReplayCamera* camera : replay_->hardware_cameras_) camera->pulse_locked();
  }
  int current_pattern() const override {
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    return replay_->pattern_;
  }
  void go_dark() override {
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    replay_->pattern_ = -1;
  }

 private:
  std::shared_ptr<ReplayRecording> replay_;
  PatternSet patterns_;
};

class ReplayTurntable final : public drivers::Turntable {
 public:
  explicit ReplayTurntable(std::shared_ptr<ReplayRecording> replay) : replay_(std::move(replay)) {}

  void home(std::chrono::milliseconds) override {
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    replay_->homed_ = true;
    replay_->table_driven_ = true;
    replay_->table_frame_.reset();
  }
  void move_to_deg(double angle_deg, std::chrono::milliseconds) override {
    if (!std::isfinite(angle_deg) || angle_deg < 0.0) {
      throw_error(ErrorCode::kInvalidArgument, "{}: turntable angle {} must be finite and >= 0", replay_->uri_,
                  angle_deg);
    }
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    if (!replay_->homed_) throw_error(ErrorCode::kInvalidArgument, "{}: turntable not homed", replay_->uri_);
    replay_->table_frame_ = replay_->frame_at_angle_locked(angle_deg);
  }
  double position_deg() const override {
    std::lock_guard<std::mutex> lock(replay_->mutex_);
    return replay_->table_frame_ ? replay_->angles_[*replay_->table_frame_] : 0.0;
  }
  int steps_per_revolution() const override { return replay_->steps_per_revolution_; }

 private:
  std::shared_ptr<ReplayRecording> replay_;
};

std::shared_ptr<ReplayRecording> ReplayRecording::open(const std::string& text, std::shared_ptr<ReplayClock> clock) {
  const drivers::DeviceUri uri = drivers::parse_device_uri(text);
  if (uri.scheme != "replay") throw_error(ErrorCode::kInvalidArgument, "'{}' is not a replay:// URI", text);
  if (uri.target.empty()) {
    throw_error(ErrorCode::kInvalidArgument, "'{}': no recording folder (replay://PATH, e.g. replay://out/recording)",
                text);
  }
  for (const auto& [key, value] : uri.query) {
    if (key != "timing") throw_error(ErrorCode::kInvalidArgument, "{}: unknown option '{}' (known: timing)", text, key);
  }
  const std::string timing = uri.get("timing", "fast");
  if (timing != "fast" && timing != "recorded") {
    throw_error(ErrorCode::kInvalidArgument, "{}: timing={} (fast or recorded)", text, timing);
  }

  std::shared_ptr<ReplayRecording> replay;
  try {
    replay = std::shared_ptr<ReplayRecording>(new ReplayRecording(text, RecordingReader::open(uri.target)));
    const RecordingInfo& info = replay->reader_.info();
    if (info.images_per_frame == 0) {
      throw_error(ErrorCode::kUnsupported, "{} is a depth-map recording: it holds no pattern images to replay",
                  uri.target);
    }
    replay->patterns_ = pattern_set_from_json(info.pattern_set_json);
  } catch (const Error& error) {
    rethrow_for(text, error);
  }
  const RecordingReader& reader = replay->reader_;
  if (reader.frame_count() == 0) {
    throw_error(ErrorCode::kNotFound, "{}: the recording holds no frames: nothing to replay", text);
  }
  replay->timing_ = timing == "recorded" ? ReplayTiming::kRecorded : ReplayTiming::kFast;
  replay->clock_ = clock ? std::move(clock) : std::make_shared<ReplayClock>();

  // The turntable's angles, when every frame has one; the tolerance a commanded angle is
  // matched with: half the smallest step between recorded angles (never two frames), at most
  // 0.5° (another frame count must not match the nearest frame).
  std::vector<double> sorted;
  for (std::size_t i = 0; i < reader.frame_count(); ++i) {
    if (!reader.frame(i).turntable_angle_deg) {
      sorted.clear();
      break;
    }
    sorted.push_back(*reader.frame(i).turntable_angle_deg);
  }
  if (!sorted.empty()) {
    replay->angles_ = sorted;
    std::sort(sorted.begin(), sorted.end());
    double smallest = 0.0;
    for (std::size_t i = 1; i < sorted.size(); ++i) {
      const double gap = sorted[i] - sorted[i - 1];
      if (gap > 1e-9 && (smallest == 0.0 || gap < smallest)) smallest = gap;
    }
    if (smallest > 0.0) replay->angle_tolerance_deg_ = std::min(0.5, smallest / 2.0);
    replay->steps_per_revolution_ = smallest > 0.0 ? std::max(1, static_cast<int>(std::lround(360.0 / smallest))) : 1;
  }
  return replay;
}

std::unique_ptr<drivers::Camera> ReplayRecording::camera() {
  return std::make_unique<ReplayCamera>(shared_from_this());
}
std::unique_ptr<drivers::Projector> ReplayRecording::projector() {
  return std::make_unique<ReplayProjector>(shared_from_this());
}
std::unique_ptr<drivers::Turntable> ReplayRecording::turntable() {
  if (!has_angles()) {
    throw_error(ErrorCode::kUnsupported,
                "{}: the recording was made without a turntable (its frames have no angles); replay it without one",
                uri_);
  }
  return std::make_unique<ReplayTurntable>(shared_from_this());
}

std::string ReplayRecording::projector_model() const {
  const std::string& model = reader_.info().device.model;
  const std::size_t join = model.find(kModelJoin);
  return join == std::string::npos ? model : model.substr(0, join);
}

std::string ReplayRecording::camera_model() const {
  const std::string& model = reader_.info().device.model;
  const std::size_t join = model.find(kModelJoin);
  return join == std::string::npos ? model : model.substr(join + std::string(kModelJoin).size());
}

std::size_t ReplayRecording::frame_at_angle_locked(double angle_deg) const {
  std::optional<std::size_t> nearest;
  std::optional<std::size_t> next;  // the first match after the frame played
  for (std::size_t i = 0; i < angles_.size(); ++i) {
    const double distance = std::abs(angles_[i] - angle_deg);
    if (!nearest || distance < std::abs(angles_[*nearest] - angle_deg)) nearest = i;
    if (distance <= angle_tolerance_deg_ && !next && (!table_frame_ || i > *table_frame_)) next = i;
  }
  if (next) return *next;
  if (nearest && std::abs(angles_[*nearest] - angle_deg) <= angle_tolerance_deg_) return *nearest;
  const auto [low, high] = std::minmax_element(angles_.begin(), angles_.end());
  throw_error(ErrorCode::kNotFound,
              "{}: no recorded frame at {:.3f} deg{}; the recording's {} frames are at {:.3f} .. {:.3f} deg (nearest: "
              "frame {} at {:.3f} deg; another frame count?)",
              uri_, angle_deg, angle_deg > *high ? ": the recording ends before it" : "", angles_.size(), *low, *high,
              reader_.frame(*nearest).index, angles_[*nearest]);
}

void ReplayRecording::pace_locked(std::size_t frame, std::unique_lock<std::mutex>& lock) {
  if (timing_ != ReplayTiming::kRecorded || last_paced_ == frame) return;
  last_paced_ = frame;
  const std::int64_t timestamp = reader_.frame(frame).timestamp_ns;
  if (!pace_origin_) {
    pace_origin_ = std::make_pair(timestamp, clock_->now());
    return;
  }
  const ReplayClock::TimePoint due =
      pace_origin_->second + std::chrono::nanoseconds(std::max<std::int64_t>(0, timestamp - pace_origin_->first));
  // Other devices of the recording go on meanwhile (the projector shows, the table turns).
  lock.unlock();
  clock_->sleep_until(due);
  lock.lock();
}

}  // namespace sls::replay
