// Setting a scan up, the same way for every front end (`sls scan`, the C API's sls_scan_run_*):
// devices given by URI captured into a recording through the capture sequencer, a recording
// opened and checked for a scan, and a scan session made for a recording.
//
//   DeviceCapture captured = capture_from_devices(folder, request, progress);
//   RecordingReader recording = open_recording_for_scan(folder);
//   ScanSession session = make_recording_session(recording, options);
//   ReplayOutcome outcome = run_recording(session, recording, ...);   // frame_pipeline.h
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/projector.h"
#include "fusion/volume.h"
#include "sdk/core/device.h"
#include "sdk/core/memory_type.h"
#include "sdk/core/progress.h"
#include "sdk/core/recording.h"
#include "sdk/core/recording_writer_thread.h"
#include "sdk/core/trajectory.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/session/capture_sequencer.h"
#include "sdk/session/frame_pipeline.h"
#include "sdk/session/scan_session.h"

namespace sls::session {

// Devices by URI (drivers/device_registry.h: hardware or sim://) and what to capture.
struct DeviceCaptureRequest {
  std::string camera_uri;
  std::string projector_uri;
  std::string turntable_uri;     // empty: no turntable, every stack at one position
  // calibration.yml of these devices, stored in the recording; empty: none, or with a replay://
  // camera the replayed recording's
  std::string calibration_path;
  // Frames per revolution; one revolution is captured. 0: 36 with a turntable, else 1; with a
  // replay:// camera the replayed recording's frames (at its turntable's recorded steps).
  int frames = 0;
  Device sim_device = Device::cpu();  // where sim:// devices render (unless their URI says device=)
  // Continue the recording at the folder, cut off by a signal, a kill or a device error, from
  // its first missing frame with the same devices (the turntable from that frame's angle). It
  // keeps the calibration it was captured with (calibration_path must be empty) and is refused,
  // naming the difference, when the devices or the frame count contradict it.
  bool resume = false;
  // HDR: the stack at each of these exposures relative to the camera's (CaptureOptions::exposures);
  // empty: one exposure.
  std::vector<double> exposures;
  // Where the camera delivers its images (drivers::Camera::set_image_memory): kPinned for a scan
  // fused on a GPU (capture_memory_for), which then uploads each stack without staging it.
  MemoryType image_memory = MemoryType::kHost;
  // false (`sls scan --no-record`, sls_scan_config.no_record): nothing of the capture touches
  // the disk — no folder, no recording —; the frames go to `recorded` only, so the capture can
  // be neither resumed nor scanned again. Refused with resume.
  bool record = true;
  // Stacks waiting for the recording's writer thread, at most (CaptureOptions::write_queue_frames).
  std::size_t write_queue_frames = CaptureOptions{}.write_queue_frames;
  // Stacks `recorded` (capture_from_devices) may keep after it returns, at most: a live scan's
  // frames waiting to be fused and the one being fused (frame_pipeline.h). Counted in the memory
  // the capture admits before anything moves (CaptureOptions::callback_holds_frames).
  std::size_t recorded_holds_frames = PipelineOptions{}.queue_frames + 1;
  // Called once the devices are open, before the first frame, on the capturing thread: what the
  // recording holds (or, without `record`, would hold) and the calibration it is captured with
  // (none: uncalibrated). What a scan session is made from when there is no recording to open.
  std::function<void(const RecordingInfo& info, const std::optional<ScannerCalibration>& calibration)> described;
  // When given: the recording's writer thread's figures, filled when the capture ends, also when
  // it throws.
  RecordingWriteStatistics* write_statistics = nullptr;
};

// Where a capture for a scan fused on `device` puts its images: page-locked for a GPU.
inline MemoryType capture_memory_for(const Device& device) {
  return device.is_cuda() ? MemoryType::kPinned : MemoryType::kHost;
}

struct DeviceCapture {
  std::string recording_folder;
  CaptureStatistics statistics;
  std::size_t images_per_frame = 0;
  bool calibrated = false;  // the recording holds a calibration (a scan can decode it)
  int resumed_from = 0;     // with resume: the frames the recording held before
};

// The pattern set a scan projects with `projector`: the Gray code + phase-shift set at the
// projector's size.
PatternSet scan_pattern_set(const drivers::Projector& projector);

// Opens the devices, loads scan_pattern_set() and captures one revolution through the capture
// sequencer into a new recording at `folder` (RecordingWriter::create: it must not exist or be
// empty), with the calibration when the request names one, or with request.resume the rest of
// the recording there (RecordingWriter::append_to). Every stack is appended as it
// arrives, so an error or a cancel keeps a valid recording of the stacks captured. Throws
// sls::Error: the device registry's codes for a URI that opens nothing (the message names it),
// kInvalidArgument without a camera or projector URI, the sequencer's codes for a device that
// stops answering, kCancelled when `progress` asks to stop.
// `recorded`, when given, is called on the capturing thread with each frame once it is handed to
// the recording's writer thread, as a scan session takes it (ScanFrame::index its position in
// the recording; HDR stacks fused; an incomplete frame with ScanFrame::problem), the stack shared
// with the writer (ScanFrame::shared_images), not copied: fusing while capturing
// (frame_pipeline.h's captured_frames). An exception from it ends the capture after that frame,
// which is still written, and propagates unchanged. A write that fails ends the capture with
// sls::Error naming the folder and the frame (the frames before it stay in the recording).
DeviceCapture capture_from_devices(const std::string& folder, const DeviceCaptureRequest& request,
                                   const ProgressCallback& progress = {},
                                   const std::function<void(ScanFrame&& frame)>& recorded = {});

// Continues the recording at `folder` (RecordingWriter::append_to) for a capture with these
// devices and pattern set: throws sls::Error(kInvalidArgument) naming the difference when it
// was captured with another projector, camera size or bit depth, pattern set, or exposures (HDR).
RecordingWriter append_to_recording_of(const std::string& folder, const drivers::Projector& projector,
                                       const drivers::Camera& camera, const PatternSet& patterns,
                                       const std::vector<double>& exposures = {});

// Opens a recording for a scan: reads and checks its manifest and, unless the caller brings its
// own (`calibration_given`), requires a calibration. The frames' images are read (and a bad one
// reported and skipped) as the scan reaches them. Throws sls::Error: kNotFound for a missing folder or manifest, kFormat for a
// corrupt one, kInvalidArgument without calibration.yml.
RecordingReader open_recording_for_scan(const std::string& folder, bool calibration_given = false);

// A scan session for the frames of `recording`: its calibration (or `calibration`, e.g. a
// new calibration of the head, when given: its camera must have the recording's size), its
// pattern set (none for a depth-map recording) and its camera's bit depth for the decoder;
// the rest from `options`. Throws sls::Error(kInvalidArgument) for a calibration of another
// camera size.
ScanSession make_recording_session(const RecordingReader& recording, ScanSessionOptions options,
                                   const ScannerCalibration* calibration = nullptr);
// The same from what a recording holds (its info and the calibration to decode with): for a
// capture that records nothing (DeviceCaptureRequest::described).
ScanSession make_capture_session(const RecordingInfo& info, const ScannerCalibration& calibration,
                                 ScanSessionOptions options);

// Known poses (`sls scan --poses groundtruth`, sls_scan_config.poses) for a simulated recording:
// its ground-truth trajectory, one pose per frame (a pose written for a frame the manifest does
// not list yet, by a capture killed between the two, is dropped). Throws sls::Error:
// kInvalidArgument when the recording has none (only simulated recordings do), kFormat when it
// does not hold one pose per frame.
std::vector<StampedPose> groundtruth_poses(const RecordingReader& recording);

// The fixed volume for known poses: the bounding box of the recording's ground-truth reference
// surface plus the integration band, at `voxel_size_m` (0: two pixel footprints at 0.1 m, grown
// until it holds at most `max_voxels`). Throws kInvalidArgument without a reference.ply, kFormat
// for an empty one.
fusion::VolumeGeometry groundtruth_volume(const RecordingReader& recording, double voxel_size_m, double max_voxels,
                                          const fusion::IntegrationOptions& integration);

// Whether a recording is a full turntable revolution (its angles span 360 degrees less at most
// two steps), as `sls scan` decides to close the loop by default; `why` says so in words.
bool is_full_revolution(const RecordingReader& recording, std::string* why = nullptr);
// The same from the frames' turntable angles (none: a frame without one), in frame order.
bool is_full_revolution(const std::vector<std::optional<double>>& angles, std::string* why = nullptr);

// The largest volume (one buffer of a moving volume) an automatic voxel size is grown to fit:
// 256 million voxels on a GPU, 48 million on the CPU.
double automatic_max_voxels(const Device& device);

}  // namespace sls::session
