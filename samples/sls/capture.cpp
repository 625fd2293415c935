#include "samples/sls/capture.h"

#include <algorithm>
#include <atomic>
#include <csignal>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>

#include <fmt/format.h>

#include "drivers/device_registry.h"
#include "drivers/interfaces/device_uri.h"
#include "drivers/sim/sim_recording.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"

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
// A capture that failed part-way (a full disk, a device that stopped answering): its frames
// are kept, and the error says how many, where, and how to go on.
[[noreturn]] void rethrow_keeping(const Error& error, const std::string& folder) {
  std::size_t frames = 0;
  try {
    if (holds_recording(folder)) frames = RecordingReader::open(folder).frame_count();
  } catch (const Error&) {
  }
  if (frames == 0) throw error;
  throw Error(error.code(), fmt::format("{}; the {} frame(s) captured before are kept in {}: fix the cause (free "
                                        "space, reconnect the device) and continue the capture with --resume",
                                        error.what(), frames, folder));
}

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
                           const Device& device, const ProgressCallback& display, const StopOnSignal& stop,
                           const session::RecordedFrame& on_recorded, const LiveRecording& live) {
  if (live.record) check_folder(folder, resume);
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
  options.record = live.record;
  options.described = live.described;
  CaptureOutcome outcome;
  outcome.recording = live.record ? folder : std::string();
  options.write_statistics = &outcome.writes;
  options.image_memory = session::capture_memory_for(device);  // where the scan reads them
  int delivered = 0;  // frames captured this run (what a capture that records nothing has)
  std::size_t images_seen = 0;  // and their images each
  if (on_recorded) {
    options.on_recorded = [&on_recorded, &delivered, &images_seen](
                              int frame, const std::shared_ptr<const std::vector<Image16u>>& images,
                              const FrameMetadata& metadata, Image32f* depth_m) {
      session::ScanFrame scan_frame;
      scan_frame.index = frame;
      scan_frame.timestamp_ns = metadata.timestamp_ns;
      scan_frame.turntable_angle_deg = metadata.turntable_angle_deg;
      if (depth_m != nullptr) {
        scan_frame.depth_m = std::move(*depth_m);
      } else {
        scan_frame.shared_images = images;  // being written: shared with the writer, not copied
      }
      ++delivered;
      images_seen = std::max(images_seen, scan_frame.pattern_images().size());
      on_recorded(std::move(scan_frame));
    };
  }
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
    if (!stopped_by_signal(error, stop)) {
      if (!live.record) throw;
      rethrow_keeping(error, folder);
    }
  }
  outcome.interrupted = true;
  if (!live.record) {
    outcome.frames = delivered;
    outcome.planned = planned > 0 ? static_cast<int>(planned) : delivered;
    outcome.images_per_frame = static_cast<int>(images_seen);
    return outcome;
  }
  const RecordingReader recorded = RecordingReader::open(folder);
  outcome.source = recorded.info().device.uri;
  outcome.frames = static_cast<int>(recorded.frame_count());
  // Stopped before the first frame was reported: the count its URI was made with.
  outcome.planned = planned > 0 ? static_cast<int>(planned)
                                : drivers::parse_device_uri(outcome.source).get_int("frames", outcome.frames);
  outcome.images_per_frame = recorded.info().images_per_frame;
  return outcome;
}

CaptureOutcome capture_devices(const std::string& folder, const session::DeviceCaptureRequest& request, bool resume,
                               const ProgressCallback& display, const StopOnSignal& stop,
                               const session::RecordedFrame& on_recorded, const LiveRecording& live) {
  if (live.record) check_folder(folder, resume);
  CaptureOutcome outcome;
  outcome.recording = live.record ? folder : std::string();
  outcome.source = request.camera_uri;
  const ProgressCallback progress = stop.wrap(display);
  int delivered = 0;             // frames captured this run (what a capture that records nothing has)
  std::size_t images_seen = 0;  // and their images each
  const session::RecordedFrame counted = [&on_recorded, &delivered, &images_seen](session::ScanFrame&& frame) {
    ++delivered;
    images_seen = std::max(images_seen, frame.pattern_images().size());
    on_recorded(std::move(frame));
  };
  try {
    session::DeviceCaptureRequest resumable = request;
    resumable.resume = resume;
    resumable.record = live.record;
    resumable.described = live.described;
    resumable.write_statistics = &outcome.writes;
    const session::DeviceCapture captured =
        session::capture_from_devices(folder, resumable, progress, on_recorded ? counted : session::RecordedFrame{});
    outcome.statistics = captured.statistics;
    outcome.resumed_from = captured.resumed_from;
    outcome.calibrated = captured.calibrated;
  } catch (const Error& error) {
    if (!stopped_by_signal(error, stop)) {
      if (!live.record) throw;
      rethrow_keeping(error, folder);
    }
    outcome.interrupted = true;
  }
  outcome.planned = request.frames > 0 ? request.frames : (request.turntable_uri.empty() ? 1 : 36);
  if (!live.record) {
    outcome.frames = delivered;
    outcome.images_per_frame = static_cast<int>(images_seen);
    return outcome;
  }
  const RecordingReader recorded = RecordingReader::open(folder);
  outcome.frames = static_cast<int>(recorded.frame_count());
  outcome.planned = request.frames > 0 ? request.frames : (request.turntable_uri.empty() ? 1 : 36);
  outcome.images_per_frame = recorded.info().images_per_frame;
  outcome.calibrated = recorded.has_calibration();
  return outcome;
}

}  // namespace sls::cli
