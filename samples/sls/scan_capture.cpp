#include "samples/sls/scan_capture.h"

#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "drivers/interfaces/device_uri.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/decode/hdr_fusion.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_setup.h"

namespace sls::cli {
namespace {

// What `sls scan --camera` asks of the devices (hardware or sim://).
session::DeviceCaptureRequest device_request(const ScanOptions& options, const Device& device) {
  if (options.projector_uri.empty()) {
    throw_error(ErrorCode::kInvalidArgument, "--camera needs --projector (the device that shows the patterns)");
  }
  session::DeviceCaptureRequest request;
  request.camera_uri = options.camera_uri;
  request.projector_uri = options.projector_uri;
  request.turntable_uri = options.turntable_uri;
  if (!options.exposures.empty()) request.exposures = parse_hdr_exposures(options.exposures).scales;
  request.calibration_path = options.calibration;
  request.frames = options.frames;
  request.sim_device = device;
  request.image_memory = session::capture_memory_for(device);
  return request;
}

// What `sls scan --sim` (or --resume of its capture) asks of the simulator.
SimCaptureRequest sim_request(const ScanOptions& options) {
  SimCaptureRequest request;
  request.preset = options.sim_preset;
  request.object = options.object_given || !options.resume ? options.object : std::string();
  request.frames = options.frames;
  return request;
}

// The command that continues a capture into OUT/recording that was cut off.
std::string resume_command(const ScanOptions& options) {
  std::string command = "sls scan --resume";
  if (!options.camera_uri.empty()) {
    command += " --camera " + options.camera_uri + " --projector " + options.projector_uri;
    if (!options.turntable_uri.empty()) command += " --turntable " + options.turntable_uri;
    if (!options.exposures.empty()) command += " --exposures " + options.exposures;
    if (options.frames > 0) command += fmt::format(" --frames {}", options.frames);
  }
  return command + " --out " + options.out;
}

}  // namespace

void print_capture(const Context& context, const ScanOptions& options, const CaptureOutcome& outcome,
                   const std::string& folder) {
  if (context.options.json) return;
  if (options.resume && outcome.resumed_from == outcome.frames) {
    std::cerr << fmt::format("{} is complete ({} frames): fusing it (fusion keeps no checkpoint; it runs from the "
                             "first frame)\n", folder, outcome.frames);
    return;
  }
  std::string how = outcome.resumed_from > 0 ? fmt::format(" (resumed at frame {})", outcome.resumed_from) : "";
  if (!options.camera_uri.empty()) {
    const session::CaptureStatistics& stats = outcome.statistics;
    how += fmt::format(" ({} incomplete, {} re-captured stacks this run)", stats.incomplete_frames, stats.retries);
  }
  std::cerr << fmt::format("\ncaptured {} frame(s){} x {} images from {} {}\n", outcome.frames, how,
                           outcome.images_per_frame, outcome.source,
                           outcome.recording.empty() ? std::string("(--no-record: not recorded)") : "into " + folder);
}

bool can_fuse_while_capturing(const ScanOptions& options) {
  if (options.poses != "track") return false;
  if (!options.camera_uri.empty()) {
    return !options.calibration.empty() || options.resume ||
           drivers::parse_device_uri(options.camera_uri).scheme == "replay";
  }
  return true;
}

void start_live_capture(const Context& context, const ScanOptions& options, const Device& device,
                        const std::string& folder, LiveCapture* live) {
  live->resume_command = resume_command(options);
  // A resumed capture holds its first frames already (all of them when it was complete).
  if (options.resume) {
    try {
      live->planned_frames.store(RecordingReader::open(folder).frame_count());
    } catch (const Error&) {
      // No recording there: the capture says so when it starts.
    }
  }
  const ProgressCallback display = [live, shown = context.progress_callback("capture")](const ProgressUpdate& update) {
    live->planned_frames.store(update.total);
    return !shown || shown(update);
  };
  live->record = !options.no_record;
  LiveRecording recording;
  recording.record = live->record;
  recording.described = [live](const RecordingInfo& info, const std::optional<ScannerCalibration>& calibration) {
    live->info = info;
    live->calibration = calibration;
  };
  // Each frame's turntable angle kept as it is captured (what --no-record has instead of a
  // recording's manifest), then the frame handed on.
  const auto keep_angle = [live](const session::RecordedFrame& recorded) {
    return [live, recorded](session::ScanFrame&& frame) {
      live->turntable_angles.push_back(frame.turntable_angle_deg);
      recorded(std::move(frame));
    };
  };
  // Without a recording nothing is read back (captured_frames with no folder).
  const std::string recorded_folder = live->record ? folder : std::string();
  if (!options.camera_uri.empty()) {
    const session::DeviceCaptureRequest request = device_request(options, device);
    live->frames = session::captured_frames(recorded_folder, [&options, live, request, display, folder, recording,
                                                              keep_angle](const session::RecordedFrame& recorded) {
      live->outcome = capture_devices(folder, request, options.resume, display, live->stop, keep_angle(recorded),
                                      recording);
    });
  } else {
    const SimCaptureRequest request = sim_request(options);
    live->frames = session::captured_frames(recorded_folder, [&options, live, request, device, display, folder,
                                                              recording, keep_angle](
                                                                 const session::RecordedFrame& recorded) {
      live->outcome =
          capture_sim(folder, request, options.resume, device, display, live->stop, keep_angle(recorded), recording);
    });
  }
}

// The simulator with --poses groundtruth, devices without a calibration.
bool capture_for_scan(const Context& context, const ScanOptions& options, const Device& device,
                      const std::string& folder) {
  const StopOnSignal stop;
  const CaptureOutcome outcome =
      !options.camera_uri.empty()
          ? capture_devices(folder, device_request(options, device), options.resume,
                            context.progress_callback("capture"), stop)
          : capture_sim(folder, sim_request(options), options.resume, device, context.progress_callback("capture"),
                        stop);
  if (outcome.interrupted || stop.requested()) {
    const std::string resume = resume_command(options);
    const nlohmann::json result = {{"ok", false},
                                   {"interrupted", true},
                                   {"stage", "capture"},
                                   {"signal", stop.signal_name()},
                                   {"recording", folder},
                                   {"frames_captured", outcome.frames},
                                   {"frames_planned", outcome.planned},
                                   {"resume", resume}};
    if (context.options.json) {
      std::cout << result.dump(2) << "\n";
    }
    std::cerr << fmt::format("\ninterrupted by {} during the capture: {} of {} frame(s) captured into {} (a valid "
                             "recording, nothing fused).\nResume the capture and fuse with the same options and "
                             "--resume: {}\n",
                             stop.signal_name(), outcome.frames, outcome.planned, folder, resume);
    return false;
  }
  print_capture(context, options, outcome, folder);
  if (!outcome.calibrated) {
    throw_error(ErrorCode::kInvalidArgument,
                "captured {} frame(s) into {}; without --calibration (or a replayed recording's) they cannot be "
                "decoded (the recording is kept)",
                outcome.frames, folder);
  }
  return true;
}

}  // namespace sls::cli
