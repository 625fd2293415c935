#include "sdk/session/capture_sequencer.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

#include <fmt/format.h>

#include "sdk/core/error.h"
#include "sdk/decode/hdr_fusion.h"
#include "sdk/core/host_memory.h"

namespace sls::session {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

// One try at a frame's stack: what arrived whole, and why it stopped short.
struct CaptureSequencer::Attempt {
  std::vector<CameraStack> cameras;
  std::string problem;  // empty: every camera has every pattern
  // Set when the attempt ended because a camera sent nothing in time: that camera and the
  // driver's error, for the error thrown when no attempt got an answer from it.
  std::optional<std::size_t> silent_camera;
  std::optional<Error> timeout_error;

  std::size_t whole_images() const {
    std::size_t fewest = cameras.empty() ? 0 : cameras.front().images.size();
    for (const CameraStack& stack : cameras) fewest = std::min(fewest, stack.images.size());
    return fewest;
  }
};

void CaptureOptions::validate() const {
  if (frames < 0) throw_error(ErrorCode::kInvalidArgument, "capture: frames = {} must be >= 0", frames);
  if (frames_per_revolution <= 0) {
    throw_error(ErrorCode::kInvalidArgument, "capture: frames_per_revolution = {} must be > 0", frames_per_revolution);
  }
  if (!std::isfinite(start_angle_deg) || start_angle_deg < 0.0) {
    throw_error(ErrorCode::kInvalidArgument, "capture: start_angle_deg = {} must be finite and >= 0", start_angle_deg);
  }
  if (!std::isfinite(exposure_us) || exposure_us < 0.0) {
    throw_error(ErrorCode::kInvalidArgument, "capture: exposure_us = {} must be finite and >= 0 (0: leave as is)",
                exposure_us);
  }
  if (!exposures.empty()) HdrExposures{exposures}.validate();
  if (image_timeout.count() <= 0 || turntable_timeout.count() <= 0) {
    throw_error(ErrorCode::kInvalidArgument, "capture: image_timeout ({} ms) and turntable_timeout ({} ms) must be > 0",
                image_timeout.count(), turntable_timeout.count());
  }
  if (max_retries < 0) throw_error(ErrorCode::kInvalidArgument, "capture: max_retries = {} must be >= 0", max_retries);
  const int count = frames > 0 ? frames : frames_per_revolution;
  if (first_frame < 0 || first_frame > count) {
    throw_error(ErrorCode::kInvalidArgument, "capture: first_frame = {} must be in 0..{} (the frames to capture)",
                first_frame, count);
  }
}

std::int64_t CapturedFrame::timestamp_ns() const {
  if (cameras.empty() || cameras.front().metadata.empty()) return 0;
  return cameras.front().metadata.front().timestamp_ns;
}

RecordingInfo make_recording_info(const drivers::Projector& projector, const drivers::Camera& camera,
                                  const PatternSet& patterns, const std::vector<double>& exposures) {
  const drivers::ProjectorInfo projector_info = projector.info();
  const drivers::CameraInfo camera_info = camera.info();
  RecordingInfo info;
  info.device = {projector_info.uri, fmt::format("{} + {}", projector_info.model, camera_info.model),
                 camera_info.serial};
  info.camera = {camera_info.width, camera_info.height, camera_info.bit_depth};
  info.pattern_set_json = pattern_set_to_json(patterns);
  if (!exposures.empty()) HdrExposures{exposures}.validate();
  if (exposures.size() > 1) info.exposures = exposures;
  info.images_per_frame = static_cast<int>(patterns.size() * std::max<std::size_t>(1, exposures.size()));
  return info;
}

CaptureSequencer::CaptureSequencer(drivers::Projector& projector, std::vector<drivers::Camera*> cameras,
                                   drivers::Turntable* turntable, PatternSet patterns, CaptureOptions options)
    : projector_(projector),
      cameras_(std::move(cameras)),
      turntable_(turntable),
      patterns_(std::move(patterns)),
      options_(std::move(options)) {
  options_.validate();
  validate_pattern_set(patterns_);
  if (cameras_.empty()) throw_error(ErrorCode::kInvalidArgument, "capture: no camera");
  if (std::find(cameras_.begin(), cameras_.end(), nullptr) != cameras_.end()) {
    throw_error(ErrorCode::kInvalidArgument, "capture: a camera is null");
  }
  // Names for messages, asked once: a device that has stopped answering may not tell its name.
  projector_name_ = "projector " + projector_.info().uri;
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    const drivers::CameraInfo info = cameras_[c]->info();
    camera_names_.push_back(cameras_.size() == 1 ? fmt::format("camera {}", info.uri)
                                                 : fmt::format("camera {} ({})", c, info.uri));
  }
}

int CaptureSequencer::frame_count() const {
  return options_.frames > 0 ? options_.frames : options_.frames_per_revolution;
}

double CaptureSequencer::commanded_angle_deg(int frame) const {
  return options_.start_angle_deg + 360.0 * frame / options_.frames_per_revolution;
}

std::string CaptureSequencer::camera_name(std::size_t camera) const { return camera_names_[camera]; }

std::string CaptureSequencer::where(int frame, int pattern) const {
  std::string text = fmt::format("frame {} of {}", frame, frame_count());
  if (angle_deg_) text += fmt::format(" (turntable at {:.3f} deg)", *angle_deg_);
  if (pattern >= 0) text += fmt::format(", pattern {} of {}", pattern, patterns_.size());
  return text;
}

void CaptureSequencer::fail(const std::string& device, const std::string& context, const Error& error) {
  failed_device_ = device;
  throw Error(error.code(), fmt::format("capture {}: {}: {}", context, device, error.what()));
}

CaptureStatistics CaptureSequencer::run(const std::vector<RecordingWriter*>& recordings, const FrameCallback& on_frame,
                                        const ProgressCallback& progress) {
  if (!recordings.empty() && recordings.size() != cameras_.size()) {
    throw_error(ErrorCode::kInvalidArgument, "capture: {} recordings for {} cameras (give one per camera, or none)",
                recordings.size(), cameras_.size());
  }
  for (std::size_t c = 0; c < recordings.size(); ++c) {
    const RecordingWriter* writer = recordings[c];
    if (writer == nullptr) throw_error(ErrorCode::kInvalidArgument, "capture: the recording of camera {} is null", c);
    const drivers::CameraInfo info = cameras_[c]->info();
    const RecordingInfo& recording = writer->info();
    const std::vector<double> hdr = options_.exposures.size() > 1 ? options_.exposures : std::vector<double>{};
    if (writer->is_closed() ||
        recording.images_per_frame != static_cast<int>(patterns_.size() * exposure_count()) ||
        recording.exposures != hdr || recording.camera.width != info.width || recording.camera.height != info.height) {
      throw_error(ErrorCode::kInvalidArgument,
                  "capture: recording {} ({}x{}, {} images per frame at {} exposure(s){}) does not fit {} ({}x{}) with "
                  "{} patterns at {} exposure(s)",
                  writer->folder(), recording.camera.width, recording.camera.height, recording.images_per_frame,
                  std::max<std::size_t>(1, recording.exposures.size()), writer->is_closed() ? ", closed" : "",
                  camera_name(c), info.width, info.height, patterns_.size(), exposure_count());
    }
    if (writer->frame_count() != static_cast<std::size_t>(options_.first_frame)) {
      throw_error(ErrorCode::kInvalidArgument,
                  "capture: recording {} holds {} frame(s); the capture {} at frame {}", writer->folder(),
                  writer->frame_count(), options_.first_frame > 0 ? "resumes" : "starts", options_.first_frame);
    }
  }

  // Each camera's stack is held until it is recorded and the callback is done with it (~0.5 GB
  // at 12 MP): every stack that can be held at once is admitted before anything moves, as a
  // volume is (Linux overcommits; stacks that do not fit would end in the OOM killer part-way
  // through a scan). The one being captured, and the most recent ones the writer thread or the
  // callback still holds (CaptureOptions::callback_holds_frames).
  std::uint64_t stack_bytes = 0;
  for (drivers::Camera* camera : cameras_) {
    const drivers::CameraInfo info = camera->info();
    stack_bytes += static_cast<std::uint64_t>(patterns_.size() * exposure_count()) * static_cast<std::uint64_t>(info.width) *
                   static_cast<std::uint64_t>(info.height) * sizeof(std::uint16_t);
  }
  const std::size_t writer_holds =
      recordings.empty() || options_.write_queue_frames == 0 ? 0 : options_.write_queue_frames + 1;
  // No more than the run captures (a calibration pose's run takes one stack).
  const auto remaining = static_cast<std::size_t>(std::max(1, frame_count() - options_.first_frame));
  const std::size_t stacks_held = std::min(remaining, 1 + std::max(writer_holds, options_.callback_holds_frames));
  const std::string what =
      stacks_held == 1
          ? fmt::format("capturing a pattern stack ({} images from {} camera(s))", patterns_.size(), cameras_.size())
          : fmt::format("capturing pattern stacks ({} images from {} camera(s), up to {} at once: the one being "
                        "captured and {} still being written or fused)",
                        patterns_.size(), cameras_.size(), stacks_held, stacks_held - 1);
  admit_host_allocation(stack_bytes * stacks_held, what,
                        "free memory for them (other programs), capture with fewer cameras, or hold fewer stacks "
                        "(CaptureOptions::write_queue_frames)");

  const Clock::time_point start = Clock::now();
  statistics_ = CaptureStatistics{};
  failed_device_.clear();
  angle_deg_.reset();
  const int frames = frame_count();
  if (options_.first_frame >= frames) return statistics_;  // all captured already
  // The recordings' writes, beside the capture (capture_sequencer.h, step 4). Declared after
  // what the writes read (the writers) and destroyed first: unwinding writes what is queued.
  std::optional<RecordingWriterThread> writes;
  if (!recordings.empty()) {
    std::string folders = recordings.front()->folder();
    for (std::size_t c = 1; c < recordings.size(); ++c) folders += ", " + recordings[c]->folder();
    writes.emplace(folders, options_.write_queue_frames);
  }
  const auto keep_write_statistics = [&] {
    if (writes) statistics_.writes = writes->statistics();
  };
  try {
    prepare();
    for (int frame = options_.first_frame; frame < frames; ++frame) {
      const CaptureStatistics before = statistics_;
      queue_depth_ = 0;
      CapturedFrame captured = capture_frame(frame);
      captured.counters = frame_counters(before, captured.attempts);
      if (writes) {
        std::vector<FrameMetadata> metadata(recordings.size());
        for (std::size_t c = 0; c < recordings.size(); ++c) {
          CameraStack& stack = captured.cameras[c];
          metadata[c].timestamp_ns = stack.metadata.empty() ? 0 : stack.metadata.front().timestamp_ns;
          metadata[c].turntable_angle_deg = captured.turntable_angle_deg;
          metadata[c].complete = captured.complete;
          metadata[c].note = captured.note;
          metadata[c].capture = captured.counters;
          stack.shared_images = std::make_shared<const std::vector<Image16u>>(std::move(stack.images));
          stack.images.clear();
          // Each recording lists frames 0..n-1 in order (checked above): this one is next.
          captured.recording_indices.push_back(frame);
        }
        std::vector<std::shared_ptr<const std::vector<Image16u>>> stacks;
        for (const CameraStack& stack : captured.cameras) stacks.push_back(stack.shared_images);
        writes->push(frame, [recordings, stacks = std::move(stacks), metadata = std::move(metadata)] {
          for (std::size_t c = 0; c < recordings.size(); ++c) recordings[c]->append_frame(*stacks[c], metadata[c]);
        });
      }
      ++statistics_.frames;
      if (!captured.complete) ++statistics_.incomplete_frames;
      if (on_frame) on_frame(captured);
      report_progress(progress, {"capture", static_cast<std::size_t>(frame + 1), static_cast<std::size_t>(frames),
                                 captured.complete ? std::string() : captured.note});
    }
    if (writes) writes->finish();
  } catch (...) {
    finish(true);
    // Every frame captured is written before this rethrows; a write error then is logged by
    // the writer thread (this exception is the scan's outcome).
    if (writes) writes->drain();
    keep_write_statistics();
    statistics_.seconds = seconds_since(start);
    throw;
  }
  keep_write_statistics();
  finish(false);
  statistics_.seconds = seconds_since(start);
  return statistics_;
}

std::optional<drivers::TransportStatistics> CaptureSequencer::transport_sample() const {
  std::optional<drivers::TransportStatistics> total;
  for (const drivers::Camera* camera : cameras_) {
    const std::optional<drivers::TransportStatistics> one = camera->transport_statistics();
    if (!one) continue;
    if (!total) total.emplace();
    total->resent_packets += one->resent_packets;
    total->missing_packets += one->missing_packets;
    total->output_queue_depth = std::max(total->output_queue_depth, one->output_queue_depth);
  }
  return total;
}

FrameCaptureCounters CaptureSequencer::frame_counters(const CaptureStatistics& before, int attempts) {
  FrameCaptureCounters counters;
  counters.attempts = attempts;
  counters.incomplete_images = statistics_.incomplete_images - before.incomplete_images;
  counters.lost_images = statistics_.lost_images - before.lost_images;
  counters.stale_images = statistics_.stale_images - before.stale_images;
  const std::optional<drivers::TransportStatistics> now = transport_sample();
  if (now) {
    const drivers::TransportStatistics mark = transport_mark_.value_or(drivers::TransportStatistics{});
    // Counters only grow; a driver that restarted its own counts starts a new span.
    const auto since = [](std::uint64_t value, std::uint64_t previous) {
      return value >= previous ? value - previous : value;
    };
    FrameTransportCounters transport;
    transport.resent_packets = since(now->resent_packets, mark.resent_packets);
    transport.missing_packets = since(now->missing_packets, mark.missing_packets);
    transport.queue_depth = queue_depth_;
    counters.transport = transport;
    FrameTransportCounters& total = statistics_.transport ? *statistics_.transport : statistics_.transport.emplace();
    total.resent_packets += transport.resent_packets;
    total.missing_packets += transport.missing_packets;
    total.queue_depth = std::max(total.queue_depth, transport.queue_depth);
  }
  transport_mark_ = now;
  return counters;
}

void CaptureSequencer::prepare() {
  try {
    projector_.load_patterns(patterns_);
  } catch (const Error& error) {
    fail(projector_name_, "setup, loading the pattern set", error);
  }
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    try {
      cameras_[c]->set_trigger_source(options_.trigger);
      if (options_.exposure_us > 0.0) cameras_[c]->set_exposure_us(options_.exposure_us);
    } catch (const Error& error) {
      fail(camera_name(c), "setup", error);
    }
  }
  exposure_us_.clear();
  base_exposure_us_.clear();
  if (!options_.exposures.empty()) {
    for (std::size_t c = 0; c < cameras_.size(); ++c) {
      double base = options_.exposure_us;
      if (!(base > 0.0)) {
        try {
          base = cameras_[c]->exposure_us();
        } catch (const Error& error) {
          fail(camera_name(c), "setup, reading the exposure for HDR", error);
        }
      }
      base_exposure_us_.push_back(base);
      std::vector<double> passes;
      for (const double scale : options_.exposures) passes.push_back(base * scale);
      exposure_us_.push_back(std::move(passes));
    }
  }
  if (turntable_ != nullptr && options_.home_turntable) {
    try {
      turntable_->home(options_.turntable_timeout);
    } catch (const Error& error) {
      fail("turntable", "setup, homing", error);
    }
  }
  tracks_.assign(cameras_.size(), CameraTrack{});
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    try {
      cameras_[c]->start();
    } catch (const Error& error) {
      fail(camera_name(c), "setup, starting the acquisition", error);
    }
  }
  transport_mark_ = transport_sample();
}

void CaptureSequencer::finish(bool after_error) {
  // After an error the scan's outcome is that error: cleanup failures would only hide it.
  const auto attempt = [&](const std::string& device, const std::string& what, auto&& call) {
    if (after_error && device == failed_device_) return;
    try {
      call();
    } catch (const Error& error) {
      if (!after_error) fail(device, what, error);
    } catch (const std::exception&) {
      if (!after_error) throw;
    }
  };
  for (std::size_t c = 0; c < cameras_.size(); ++c) {
    attempt(camera_name(c), "end, stopping the acquisition", [&] { cameras_[c]->stop(); });
    if (c < base_exposure_us_.size()) {
      attempt(camera_name(c), "end, restoring the exposure", [&] { cameras_[c]->set_exposure_us(base_exposure_us_[c]); });
    }
  }
  attempt(projector_name_, "end, going dark", [&] { projector_.go_dark(); });
}

CapturedFrame CaptureSequencer::capture_frame(int frame) {
  CapturedFrame captured;
  captured.index = frame;
  if (turntable_ != nullptr) {
    try {
      turntable_->move_to_deg(commanded_angle_deg(frame), options_.turntable_timeout);
      angle_deg_ = turntable_->position_deg();
    } catch (const Error& error) {
      fail("turntable", where(frame, -1) + fmt::format(", moving to {:.3f} deg", commanded_angle_deg(frame)), error);
    }
    captured.turntable_angle_deg = angle_deg_;
  }

  const Clock::time_point start = Clock::now();
  std::optional<Attempt> best;  // the attempt with the most whole images, kept when all fail
  std::string first_problem;
  bool every_attempt_silent = true;
  for (int attempt = 0; attempt <= options_.max_retries; ++attempt) {
    if (attempt > 0) ++statistics_.retries;
    Attempt result = capture_attempt(frame);
    captured.attempts = attempt + 1;
    if (result.problem.empty()) {
      captured.cameras = std::move(result.cameras);
      if (attempt > 0) captured.note = fmt::format("re-captured {} time(s); first problem: {}", attempt, first_problem);
      statistics_.capture_seconds += seconds_since(start);
      return captured;
    }
    if (first_problem.empty()) first_problem = result.problem;
    if (!result.silent_camera) every_attempt_silent = false;
    if (!best || result.whole_images() > best->whole_images()) best = std::move(result);
  }
  statistics_.capture_seconds += seconds_since(start);
  // No attempt got anything from a camera in time: it has stopped answering.
  if (every_attempt_silent && best->silent_camera && best->timeout_error) {
    fail(camera_name(*best->silent_camera),
         where(frame, static_cast<int>(best->whole_images())) +
             fmt::format(", no image in any of {} attempt(s)", captured.attempts),
         *best->timeout_error);
  }
  // Keep what every camera has whole: the first images of the sequence.
  const std::size_t whole = best->whole_images();
  captured.cameras = std::move(best->cameras);
  for (CameraStack& stack : captured.cameras) {
    stack.images.resize(whole);
    stack.metadata.resize(whole);
  }
  captured.complete = false;
  captured.note = fmt::format("incomplete after {} attempt(s): {} of {} {} whole; first problem: {}; last: {}",
                              captured.attempts, whole, patterns_.size() * exposure_count(),
                              exposure_count() > 1 ? "images (patterns x exposures)" : "patterns", first_problem,
                              best->problem);
  return captured;
}

CaptureSequencer::Attempt CaptureSequencer::capture_attempt(int frame) {
  Attempt attempt;
  attempt.cameras.resize(cameras_.size());
  const bool software = options_.trigger == drivers::TriggerSource::kSoftware;
  for (std::size_t exposure = 0; exposure < exposure_count(); ++exposure) {
    if (!exposure_us_.empty()) {
      for (std::size_t c = 0; c < cameras_.size(); ++c) {
        try {
          cameras_[c]->set_exposure_us(exposure_us_[c][exposure]);
        } catch (const Error& error) {
          fail(camera_name(c), where(frame, -1) + fmt::format(", setting exposure {} ({} us)", exposure,
                                                              exposure_us_[c][exposure]),
               error);
        }
      }
    }
    for (int pattern = 0; pattern < static_cast<int>(patterns_.size()); ++pattern) {
      const Clock::time_point show_start = Clock::now();
      try {
        projector_.show_pattern(pattern);
      } catch (const Error& error) {
        fail(projector_name_, where(frame, pattern), error);
      }
      const Clock::time_point shown = Clock::now();
      statistics_.projector_seconds += std::chrono::duration<double>(shown - show_start).count();
      // Counted when the scope ends, however the cameras' part ends.
      struct CameraTime {
        double& total;
        Clock::time_point since;
        ~CameraTime() { total += seconds_since(since); }
      } camera_time{statistics_.camera_seconds, shown};
      for (std::size_t c = 0; c < cameras_.size(); ++c) {
        if (software) {
          try {
            cameras_[c]->software_trigger();
          } catch (const Error& error) {
            fail(camera_name(c), where(frame, pattern), error);
          }
        }
        ++tracks_[c].triggers;  // software, or the one pulse show_pattern fired
      }
      for (std::size_t c = 0; c < cameras_.size(); ++c) {
        if (!collect_image(c, frame, pattern, attempt)) return attempt;
        attempt.cameras[c].metadata.back().exposure = static_cast<int>(exposure);
      }
    }
  }
  return attempt;
}

bool CaptureSequencer::collect_image(std::size_t camera, int frame, int pattern, Attempt& attempt) {
  drivers::Camera& device = *cameras_[camera];
  CameraTrack& track = tracks_[camera];
  const std::uint64_t expected = track.triggers - 1;
  const Clock::time_point deadline = Clock::now() + options_.image_timeout;
  bool dropped_stale = false;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    drivers::CapturedImage captured;
    try {
      captured = device.wait_image(std::max(left, std::chrono::milliseconds(1)));
    } catch (const Error& error) {
      if (error.code() != ErrorCode::kTimeout) fail(camera_name(camera), where(frame, pattern), error);
      ++statistics_.timeouts;
      ++statistics_.lost_images;
      // An image for an earlier trigger came, ours did not: the camera never acted on one
      // trigger, so its count is one behind ours. Follow the camera from here.
      if (dropped_stale && track.last_answer) track.triggers = *track.last_answer + 1;
      attempt.problem = fmt::format("{} sent no image for pattern {} within {} ms", camera_name(camera), pattern,
                                    options_.image_timeout.count());
      attempt.silent_camera = camera;
      attempt.timeout_error = error;
      return false;
    }
    ++statistics_.images;
    if (const std::optional<drivers::TransportStatistics> transport = device.transport_statistics()) {
      queue_depth_ = std::max(queue_depth_, transport->output_queue_depth);
    }
    // Frames the camera numbered but we never received still used up a trigger each.
    const std::uint64_t answers = track.last_answer ? *track.last_answer + 1 + captured.frames_missed : expected;
    track.last_answer = answers;
    if (answers < expected) {  // late, for a trigger whose wait already timed out
      ++statistics_.stale_images;
      dropped_stale = true;
      continue;
    }
    if (answers > expected) {
      // The camera numbered frames we never received after our trigger's: ours was lost (or the
      // camera saw triggers we did not send). Follow the camera's count from here.
      statistics_.lost_images += static_cast<int>(answers - expected);
      track.triggers = answers + 1;
      attempt.problem = fmt::format("{}: the image for pattern {} was lost (frame {} arrived {} frame(s) late)",
                                    camera_name(camera), pattern, captured.frame_id, answers - expected);
      return false;
    }
    if (!captured.complete) {
      ++statistics_.incomplete_images;
      attempt.problem = captured.problem.empty()
                            ? fmt::format("{}: frame {} for pattern {} is incomplete", camera_name(camera),
                                          captured.frame_id, pattern)
                            : captured.problem;
      return false;
    }
    CameraStack& stack = attempt.cameras[camera];
    stack.images.push_back(std::move(captured.image));
    stack.metadata.push_back({pattern, captured.timestamp_ns, captured.frame_id, 0});
    return true;
  }
}

}  // namespace sls::session
