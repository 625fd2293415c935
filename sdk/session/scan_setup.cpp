#include "sdk/session/scan_setup.h"

#include <memory>
#include <optional>
#include <utility>

#include "drivers/device_registry.h"
#include "sdk/core/calibration.h"
#include "sdk/core/error.h"

namespace sls::session {

PatternSet scan_pattern_set(const drivers::Projector& projector) {
  const drivers::ProjectorInfo info = projector.info();
  GrayPhaseOptions options;
  options.projector_width = info.width;
  options.projector_height = info.height;
  return make_gray_phase_pattern_set(options);
}

DeviceCapture capture_from_devices(const std::string& folder, const DeviceCaptureRequest& request,
                                   const ProgressCallback& progress) {
  if (request.camera_uri.empty()) throw_error(ErrorCode::kInvalidArgument, "capture: no camera URI");
  if (request.projector_uri.empty()) {
    throw_error(ErrorCode::kInvalidArgument, "capture with {}: no projector URI (the device that shows the patterns)",
                request.camera_uri);
  }
  if (request.frames < 0) throw_error(ErrorCode::kInvalidArgument, "capture: {} frames (0 or more)", request.frames);
  // Read before any device is touched: a bad calibration file fails at once.
  std::optional<ScannerCalibration> calibration;
  if (!request.calibration_path.empty()) calibration = read_calibration(request.calibration_path);

  drivers::OpenOptions open_options;
  open_options.sim_device = request.sim_device;
  const std::unique_ptr<drivers::Projector> projector = drivers::open_projector(request.projector_uri, open_options);
  const std::unique_ptr<drivers::Camera> camera = drivers::open_camera(request.camera_uri, open_options);
  const std::unique_ptr<drivers::Turntable> turntable =
      request.turntable_uri.empty() ? nullptr : drivers::open_turntable(request.turntable_uri, open_options);
  const PatternSet patterns = scan_pattern_set(*projector);
  CaptureOptions capture;
  capture.frames_per_revolution = request.frames > 0 ? request.frames : (turntable ? 36 : 1);
  capture.frames = capture.frames_per_revolution;
  CaptureSequencer sequencer(*projector, {camera.get()}, turntable.get(), patterns, capture);
  RecordingWriter writer = RecordingWriter::create(folder, make_recording_info(*projector, *camera, patterns), calibration);

  DeviceCapture result;
  result.recording_folder = folder;
  result.images_per_frame = patterns.size();
  result.calibrated = calibration.has_value();
  result.statistics = sequencer.run({&writer}, {}, progress);
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
  options.decode.bit_depth = info.camera.bit_depth;
  std::optional<PatternSet> patterns;
  if (info.images_per_frame > 0) patterns = pattern_set_from_json(info.pattern_set_json);
  return ScanSession(calibration != nullptr ? *calibration : recording.calibration(), patterns ? &*patterns : nullptr,
                     options);
}

double automatic_max_voxels(const Device& device) { return (device.is_cuda() ? 256.0 : 48.0) * 1e6; }

}  // namespace sls::session
