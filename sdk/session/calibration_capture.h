// A calibration capture through the devices (issue 17): the board views `sls calibrate`
// calibrates from, captured through the capture sequencer into an ordinary recording, made
// uncalibrated, that `sls calibrate --input` (calib::calibrate_capture) reads as it reads the
// simulator's own calibration capture (sim::write_sim_calibration_recording).
//
//   CalibrationCapture captured = capture_calibration(folder, devices, calibration_pattern_set(projector),
//                                                     options, confirm, progress);
//
// What it does:
//  1. hand poses (options.hand_poses): per pose k, confirm({kHand, k, N}) — the operator places
//     the board and confirms (kCapture), or skips the pose (kSkip), or ends the capture
//     (kStop) — then one pattern stack (white and black included, as the set has them)
//     through a CaptureSequencer run without the turntable: the frame's turntable angle in the
//     manifest is null;
//  2. turntable poses (options.turntable_angles_deg, in that order): confirm({kTurntable, j, M,
//     angle}) (a front end asks nothing per angle; the board is fixed on the table), then the
//     table is homed before the first one (options.home_turntable) and moved to the angle,
//     and one stack is captured; the frame carries the angle the table reports.
// Every stack is appended to the recording as it arrives (RecordingWriter: flushed per frame),
// with the capture sequencer's checks, re-captures and per-frame counters.
// Simulated cameras (drivers::Camera::exact_calibration) make a recording with ground truth:
// groundtruth/calibration.yml holds that camera's exact calibration (with the projector), and
// a head's folder its exact calibration (groundtruth/calibration.yml, camera 0 with the others
// as additional cameras), as `sls sim --calibration` writes them, so calibrating the capture
// reports the truth per camera and camera to camera. Real cameras: no ground truth.
//
// A head of several cameras (devices.more_cameras): each pose is one pattern stack that every
// camera takes together — the projector shows each pattern once and the cameras are
// triggered on it together (the software trigger of each in turn, or the projector's trigger
// line wired to all of them), as a real head does: one projection per pattern for all
// cameras, and every camera sees the board at the same instant, which a board held by hand
// needs (the pose a camera-camera calibration relates must be one pose). The capture is then
// the head layout (head_camera_folder, sdk/core/recording.h): `folder`/camera0, camera1, ...,
// one recording per camera, frame k of each the same pose — what `sls calibrate --input
// folder` calibrates as a head. A resume continues every camera's recording; their frames must
// agree (the same count, the same hand or turntable kind per frame), else it is refused
// naming the folder that disagrees. Errors name the camera by index and URI ("camera 1
// (sim://...)").
//
// Progress (sdk/core/progress.h): stage "calibration capture", one unit per pose (captured or
// skipped), the pose as detail ("hand pose 3 of 12", "turntable at 40.000 deg"), reported
// after each pose. The callback returning false ends the capture with kCancelled after the
// current pose; the recording keeps the poses captured and reads back as a valid recording.
//
// Resume (options.resume): the recording at `folder`, cut off by a cancel, a signal, a kill or
// a device error, is continued with the same devices and pattern set (refused, naming the
// difference, otherwise). Its frames say what was done: when it holds no turntable frame, the
// hand poses go on at pose h + 1 of N (h = its hand frames; a pose skipped before the cut is
// asked again), else the hand poses are over; the turntable angles it holds (to half a step)
// are not captured again. Poses skipped or a stop before the cut are not remembered.
//
// Errors (sls::Error) name the pose and the device: a camera, projector or turntable that stops
// answering ends the capture with the driver's code (kTimeout, kDevice, ...), e.g. "calibration
// hand pose 3 of 12: capture frame 2 of 3, pattern 5 of 42: camera sim://...: no image ...";
// the frames appended before it stay in the recording. kInvalidArgument for bad options or a
// turntable angle without a turntable. An sls::Error from `confirm` ends the capture with its
// code and message, plus the frames kept; another exception propagates unchanged (the
// recording stays valid either way).
//
// Not thread-safe: it drives the devices from the calling thread, which also calls the
// callbacks. The devices are not owned and must outlive the call.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/projector.h"
#include "drivers/interfaces/turntable.h"
#include "sdk/core/device.h"
#include "sdk/core/progress.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/session/capture_sequencer.h"

namespace sls::session {

enum class CalibrationPoseKind { kHand, kTurntable };
const char* calibration_pose_kind_name(CalibrationPoseKind kind);  // "hand", "turntable"

struct CalibrationPose {
  CalibrationPoseKind kind = CalibrationPoseKind::kHand;
  int index = 0;  // among the poses of its kind, from 0
  int count = 0;  // poses of its kind in the capture
  std::optional<double> turntable_angle_deg;  // turntable poses: the angle commanded

  // "hand pose 3 of 12", "turntable pose 2 of 3 (40.000 deg)".
  std::string describe() const;
};

enum class PoseDecision {
  kCapture,  // the board is in place: capture this pose
  kSkip,     // do not capture this pose; go on with the next
  kStop,     // capture nothing more (the poses captured are kept)
};

// Asked before every pose, on the capturing thread; for a hand pose it returns once the
// operator has placed the board and answered. May throw (see the file comment).
using PoseConfirmation = std::function<PoseDecision(const CalibrationPose& pose)>;

struct CalibrationCaptureOptions {
  int hand_poses = 12;                       // 0 .. 1000
  std::vector<double> turntable_angles_deg;  // each in [0, 360); at most 1000; empty: none
  // As CaptureOptions: exposure (0 leaves it), trigger, image and turntable timeouts, retries.
  double exposure_us = 0.0;
  drivers::TriggerSource trigger = drivers::TriggerSource::kSoftware;
  std::chrono::milliseconds image_timeout{2000};
  std::chrono::milliseconds turntable_timeout{10000};
  int max_retries = 2;
  bool home_turntable = true;  // before the first turntable pose
  bool resume = false;         // continue the recording at the folder (see the file comment)

  // Throws sls::Error(kInvalidArgument) naming the first bad value.
  void validate() const;
};

struct CalibrationDevices {
  drivers::Projector* projector = nullptr;
  drivers::Camera* camera = nullptr;
  drivers::Turntable* turntable = nullptr;  // null: no turntable poses
  std::string turntable_name = "turntable";  // in messages, e.g. its URI
  // A head of several cameras: cameras 1 .. K−1 (`camera` is camera 0); empty for one camera.
  std::vector<drivers::Camera*> more_cameras = {};

  // Every camera, camera 0 first.
  std::vector<drivers::Camera*> cameras() const;
};

// What happened to one pose that was asked for.
struct CalibrationPoseResult {
  CalibrationPose pose;
  bool captured = false;  // false: skipped
  int frame = -1;         // its frame in the recording
  std::optional<double> turntable_angle_deg;  // as the table reported it (the manifest's)
  bool complete = true;   // false: written incomplete after the re-captures ran out
  std::string note;       // the sequencer's note on re-captures or the incomplete stack
  double seconds = 0.0;   // capturing it: turntable move, stack and recording (the wait for the
                          // operator excluded)
};

struct CalibrationCapture {
  std::string folder;
  int cameras = 1;  // the head's: 1, or K recordings in folder/camera0 .. camera{K−1}
  std::size_t images_per_frame = 0;
  std::vector<CalibrationPoseResult> poses;  // every pose asked for, in order (skipped too)
  int frames = 0;             // in the recording now
  int hand_frames = 0;        // of those, by hand (manifest angle null)
  int turntable_frames = 0;   // on the turntable
  int resumed_from = 0;       // with resume: the frames it held before
  bool stopped = false;       // a confirmation said kStop
  CaptureStatistics statistics;  // the poses' sequencer runs summed (frames, retries, images...)
  double seconds = 0.0;          // the whole call, the operator's time included
  double capture_seconds = 0.0;  // capturing only: the poses' `seconds` summed

  int captured_poses() const;  // poses captured by this call
  int skipped_poses() const;
};

// The pattern set a calibration captures with `projector`: the scan's Gray code + phase shift
// (scan_pattern_set) over projector columns and rows — the calibration needs both projector
// coordinates of every corner — with the rows' phase period in row pixels that gives the
// columns' fringe pitch on the board: twice the columns' on a 912 x 1140 DMD (the DLP4500 the
// DLPC350 drives, a diamond array whose rows are half a column apart), the same elsewhere
// (square pixels). The simulator's calibration rig projects this set.
PatternSet calibration_pattern_set(const drivers::Projector& projector);

// Captures the calibration into a new recording at `folder` (RecordingWriter::create: it must
// not exist or be empty), or with options.resume the rest of the one there. Returns what was
// captured (also when a confirmation stopped it); throws as the file comment says.
CalibrationCapture capture_calibration(const std::string& folder, const CalibrationDevices& devices,
                                       const PatternSet& patterns, const CalibrationCaptureOptions& options,
                                       const PoseConfirmation& confirm, const ProgressCallback& progress = {});

// Devices by URI (drivers/device_registry.h: hardware or sim://).
struct CalibrationDeviceRequest {
  std::string camera_uri;
  std::vector<std::string> more_camera_uris;  // a head: cameras 1 .. K−1 (each URI once)
  std::string projector_uri;
  std::string turntable_uri;              // empty: none (then no turntable angles)
  std::optional<PatternSet> patterns;     // none: calibration_pattern_set(projector)
  Device sim_device = Device::cpu();      // where sim:// devices render (unless their URI says device=)
};

// Opens the devices by URI and runs capture_calibration. Throws the device registry's errors
// for a URI that opens nothing (naming it, and the camera's index in a head), kInvalidArgument
// without a camera or projector URI, with a camera URI given twice, or with turntable angles
// but no turntable, then capture_calibration's.
CalibrationCapture capture_calibration_from_devices(const std::string& folder, const CalibrationDeviceRequest& request,
                                                    const CalibrationCaptureOptions& options,
                                                    const PoseConfirmation& confirm,
                                                    const ProgressCallback& progress = {});

}  // namespace sls::session
