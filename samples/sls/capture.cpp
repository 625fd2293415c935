#include "samples/sls/capture.h"

#include <atomic>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/device_registry.h"
#include "drivers/interfaces/device_uri.h"
#include "drivers/sim/sim_recording.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/session/capture_sequencer.h"

namespace sls::cli {
namespace {

namespace fs = std::filesystem;

std::atomic<int> g_signal{0};
using Handler = void (*)(int);
Handler g_previous_int = SIG_DFL;
Handler g_previous_term = SIG_DFL;

extern "C" void stop_on_signal(int signal_number) {
  if (g_signal.exchange(signal_number) != 0) {
    // A second signal: the user insists. End as without a handler (the recording is valid).
    std::signal(signal_number, SIG_DFL);
    std::raise(signal_number);
  }
}

bool holds_recording(const std::string& folder) {
  std::error_code error;
  return fs::exists(fs::path(folder) / "manifest.json", error);
}

// A new capture must not write over a recording; a resumed one needs one.
void check_folder(const std::string& folder, bool resume) {
  std::error_code error;
  if (resume && !holds_recording(folder)) {
    throw_error(ErrorCode::kInvalidArgument,
                "--resume: {} holds no recording to resume (no manifest.json); run without --resume to start a capture",
                folder);
  }
  if (!resume && fs::exists(folder, error) && !fs::is_empty(folder, error)) {
    throw_error(ErrorCode::kInvalidArgument,
                "{} is not empty{}; add --resume to continue it, or choose another --out", folder,
                holds_recording(folder) ? " (it holds a recording, maybe one cut off)" : "");
  }
}

// kCancelled after a signal: the capture stopped where it was asked to.
bool stopped_by_signal(const Error& error, const StopOnSignal& stop) {
  return error.code() == ErrorCode::kCancelled && stop.requested();
}

}  // namespace

StopOnSignal::StopOnSignal() {
  g_signal.store(0);
  g_previous_int = std::signal(SIGINT, stop_on_signal);
  g_previous_term = std::signal(SIGTERM, stop_on_signal);
}

StopOnSignal::~StopOnSignal() {
  std::signal(SIGINT, g_previous_int == SIG_ERR ? SIG_DFL : g_previous_int);
  std::signal(SIGTERM, g_previous_term == SIG_ERR ? SIG_DFL : g_previous_term);
}

bool StopOnSignal::requested() const { return g_signal.load() != 0; }

std::string StopOnSignal::signal_name() const {
  const int signal_number = g_signal.load();
  return signal_number == SIGINT ? "SIGINT" : signal_number == SIGTERM ? "SIGTERM" : "";
}

ProgressCallback StopOnSignal::wrap(const ProgressCallback& display) const {
  return [display](const ProgressUpdate& update) {
    if (g_signal.load() != 0) return false;
    return !display || display(update);
  };
}

CaptureOutcome capture_sim(const std::string& folder, const SimCaptureRequest& request, bool resume,
                           const Device& device, const ProgressCallback& display, const StopOnSignal& stop) {
  check_folder(folder, resume);
  sim::SimRecordingOptions options;
  options.resume = resume;
  options.rig.preset = request.preset;
  options.object = request.object.empty() ? options.object : request.object;
  options.rig.frames = request.frames;
  if (resume) {
    // What the recording was simulated with (its URI), unless the command line says: a
    // contradiction is then refused by write_sim_recording, naming what differs.
    const RecordingReader recorded = RecordingReader::open(folder);
    const std::string& uri = recorded.info().device.uri;
    const drivers::DeviceUri parsed = drivers::parse_device_uri(uri);
    if (parsed.scheme != "sim" || !recorded.info().has_groundtruth) {
      throw_error(ErrorCode::kInvalidArgument,
                  "--resume --sim: {} was not made by the simulator (its device is {}); resume it with the --camera / "
                  "--projector / --turntable it was captured with",
                  folder, uri);
    }
    if (request.preset.empty()) options.rig.preset = parsed.get("preset", "ci");
    if (request.object.empty()) options.object = parsed.target;
    if (request.frames == 0) options.rig.frames = parsed.get_int("frames", 0);
    options.rig.seed = static_cast<std::uint64_t>(parsed.get_int("seed", static_cast<int>(options.rig.seed)));
    options.rig.noise = parsed.get_int("noise", 1) != 0;
    options.rig.projector = parsed.get("projector", options.rig.projector);
  }
  CaptureOutcome outcome;
  outcome.recording = folder;
  std::size_t planned = 0;
  const ProgressCallback wrapped = stop.wrap(display);
  const ProgressCallback progress = [&planned, &wrapped](const ProgressUpdate& update) {
    planned = update.total;
    return wrapped(update);
  };
  try {
    const sim::SimRecordingSummary summary = sim::write_sim_recording(folder, options, device, progress);
    outcome.source = summary.uri;
    outcome.frames = summary.frames;
    outcome.planned = summary.frames;
    outcome.resumed_from = summary.resumed_from;
    outcome.images_per_frame = summary.images_per_frame;
    return outcome;
  } catch (const Error& error) {
    if (!stopped_by_signal(error, stop)) throw;
  }
  const RecordingReader recorded = RecordingReader::open(folder);
  outcome.interrupted = true;
  outcome.source = recorded.info().device.uri;
  outcome.frames = static_cast<int>(recorded.frame_count());
  // Stopped before the first frame was reported: the count its URI was made with.
  outcome.planned = planned > 0 ? static_cast<int>(planned)
                                : drivers::parse_device_uri(outcome.source).get_int("frames", outcome.frames);
  outcome.images_per_frame = recorded.info().images_per_frame;
  return outcome;
}

namespace {

// The rest of a device capture cut off: the same devices, from the first missing frame.
session::CaptureStatistics resume_device_capture(const std::string& folder, const session::DeviceCaptureRequest& request,
                                                 const ProgressCallback& progress, int* resumed_from) {
  drivers::OpenOptions open_options;
  open_options.sim_device = request.sim_device;
  const std::unique_ptr<drivers::Projector> projector = drivers::open_projector(request.projector_uri, open_options);
  const std::unique_ptr<drivers::Camera> camera = drivers::open_camera(request.camera_uri, open_options);
  const std::unique_ptr<drivers::Turntable> turntable =
      request.turntable_uri.empty() ? nullptr : drivers::open_turntable(request.turntable_uri, open_options);
  const PatternSet patterns = session::scan_pattern_set(*projector);
  RecordingWriter writer = RecordingWriter::append_to(folder);
  const RecordingInfo& recorded = writer.info();
  const RecordingInfo now = session::make_recording_info(*projector, *camera, patterns);
  if (recorded.device.uri != now.device.uri) {
    throw_error(ErrorCode::kInvalidArgument, "--resume: {} was captured with projector {}, not {}", folder,
                recorded.device.uri, now.device.uri);
  }
  if (recorded.camera.width != now.camera.width || recorded.camera.height != now.camera.height ||
      recorded.camera.bit_depth != now.camera.bit_depth || recorded.images_per_frame != now.images_per_frame ||
      nlohmann::json::parse(recorded.pattern_set_json) != nlohmann::json::parse(now.pattern_set_json)) {
    throw_error(ErrorCode::kInvalidArgument,
                "--resume: {} holds {}x{} {}-bit frames of {} patterns; camera {} gives {}x{} {}-bit with {} patterns",
                folder, recorded.camera.width, recorded.camera.height, recorded.camera.bit_depth,
                recorded.images_per_frame, request.camera_uri, now.camera.width, now.camera.height,
                now.camera.bit_depth, now.images_per_frame);
  }
  session::CaptureOptions capture;
  capture.frames_per_revolution = request.frames > 0 ? request.frames : (turntable ? 36 : 1);
  capture.frames = capture.frames_per_revolution;
  const int listed = static_cast<int>(writer.frame_count());
  if (listed > capture.frames) {
    throw_error(ErrorCode::kInvalidArgument, "--resume: {} holds {} frames, more than the {} of --frames", folder,
                listed, capture.frames);
  }
  // Each recorded angle must be where this frame count puts that frame: another --frames or
  // another turntable would fill the revolution with frames at the wrong angles.
  const double step_deg = 360.0 / capture.frames_per_revolution;
  for (int i = 0; i < listed; ++i) {
    const std::optional<double>& angle = writer.frame(static_cast<std::size_t>(i)).turntable_angle_deg;
    if (angle.has_value() != (turntable != nullptr)) {
      throw_error(ErrorCode::kInvalidArgument, "--resume: {} was captured {} a turntable; give {} --turntable", folder,
                  angle ? "with" : "without", angle ? "the same" : "no");
    }
    if (angle && std::abs(*angle - step_deg * i) > 0.5 * step_deg) {
      throw_error(ErrorCode::kInvalidArgument,
                  "--resume: frame {} of {} is at {:.3f} deg; {} frames per revolution put it at {:.3f} deg (another "
                  "--frames?)",
                  i, folder, *angle, capture.frames_per_revolution, step_deg * i);
    }
  }
  capture.first_frame = listed;
  *resumed_from = listed;
  session::CaptureSequencer sequencer(*projector, {camera.get()}, turntable.get(), patterns, capture);
  return sequencer.run({&writer}, {}, progress);
}

}  // namespace

CaptureOutcome capture_devices(const std::string& folder, const session::DeviceCaptureRequest& request, bool resume,
                               const ProgressCallback& display, const StopOnSignal& stop) {
  check_folder(folder, resume);
  if (resume && !request.calibration_path.empty()) {
    throw_error(ErrorCode::kInvalidArgument,
                "--resume keeps the calibration {} was captured with; leave --calibration out", folder);
  }
  CaptureOutcome outcome;
  outcome.recording = folder;
  outcome.source = request.camera_uri;
  const ProgressCallback progress = stop.wrap(display);
  try {
    if (resume) {
      outcome.statistics = resume_device_capture(folder, request, progress, &outcome.resumed_from);
    } else {
      outcome.statistics = session::capture_from_devices(folder, request, progress).statistics;
    }
  } catch (const Error& error) {
    if (!stopped_by_signal(error, stop)) throw;
    outcome.interrupted = true;
  }
  const RecordingReader recorded = RecordingReader::open(folder);
  outcome.frames = static_cast<int>(recorded.frame_count());
  outcome.planned = request.frames > 0 ? request.frames : (request.turntable_uri.empty() ? 1 : 36);
  outcome.images_per_frame = recorded.info().images_per_frame;
  outcome.calibrated = recorded.has_calibration();
  return outcome;
}

}  // namespace sls::cli
