// Scans the simulated scanner through its devices into a recording with ground truth:
// the projector shows each pattern, the camera captures it, the turntable steps (the capture
// path the hardware will take, issue #7). Layout of groundtruth/:
//   scene.json         the object and every parameter (exact geometry)
//   rig.json           optics, placement, turntable (docs/simulator-optics.md)
//   trajectory.txt     T_object_camera per frame, TUM (the camera orbiting the object)
//   reference.ply      dense samples of the exact surface with normals
//   creases.ply        knurl ridge/groove polylines (property "polyline": the line index)
//   frames/NNNNNN/     depth.pfm (m, 0 = no surface), projector_u.pfm, projector_v.pfm (NaN:
//                      not lit), valid.png (255: visible and lit), depth_sigma.pfm (m)
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "drivers/sim/rig.h"
#include "sdk/core/device.h"
#include "sdk/core/image.h"
#include "sdk/core/memory_type.h"
#include "sdk/core/progress.h"
#include "sdk/core/recording.h"
#include "sdk/core/recording_writer_thread.h"

namespace sls::sim {

// The steps of writing one frame, in order (SimRecordingOptions::step_hook).
enum class SimFrameStep {
  kCaptured,            // images (or depth map) in memory, nothing of the frame on disk
  kImagesWritten,       // images on disk, not listed
  kGroundTruthWritten,  // and groundtruth/frames/NNNNNN/ on disk
  kTrajectoryWritten,   // and groundtruth/trajectory.txt holds its pose; next: the manifest
  kListed,              // the manifest lists the frame
};

struct SimRecordingOptions {
  std::string object = "knurled-screw";
  // A scene made by the caller, imaged instead of `object` (a ChArUco board: its markers come
  // from calib, make_chessboard_scene with a CharucoPattern; `sls sim --object charuco`).
  std::optional<Scene> scene;
  RigOptions rig;                     // preset, frames, projector, sensor, turntable, seed, noise
  bool depth_mode = false;            // depth maps instead of pattern images
  double reference_spacing_m = 0.0;   // 0: per preset (ci 100 µm, demo 30 µm, paper 10 µm)
  // HDR capture (sdk/decode/hdr_fusion.h): the whole stack at each of these exposure times
  // relative to the rig's (2..4 of them; the camera's exposure set to kSimNominalExposureUs x
  // each), stored exposure-major with RecordingInfo::exposures. Empty: one exposure.
  std::vector<double> exposures;
  // Continue a recording of these same options that was cut off (see write_sim_recording).
  bool resume = false;
  // Tests: called at each step of each frame; one that throws there stops the writer as a
  // crash or a full disk would at that point.
  std::function<void(SimFrameStep step, int frame)> step_hook;
  // Called with each frame once it is handed to the recording's writer thread (fusing while
  // capturing: a scan session takes it): its position in the recording, its images shared
  // read-only with the writer (empty in depth mode) and metadata, and in depth mode its depth map
  // as the recording stores it (recorded_depth_m), which it may take (move out). An exception
  // from it ends the capture after that frame, which is still written, and propagates unchanged.
  std::function<void(int frame, const std::shared_ptr<const std::vector<Image16u>>& images,
                     const FrameMetadata& metadata, Image32f* depth_m)>
      on_recorded;
  // false (`sls scan --sim --no-record`): nothing touches the disk — no folder, no recording, no
  // ground truth —; the frames go to on_recorded only. Refused with resume.
  bool record = true;
  // Where the simulated camera delivers its images (drivers::Camera::set_image_memory):
  // kPinned for a scan fused on a GPU, which then uploads each stack without staging it.
  MemoryType image_memory = MemoryType::kHost;
  // Frames waiting for the writer thread, at most (sdk/core/recording_writer_thread.h; 0: each
  // frame written on the capturing thread before on_recorded sees it).
  std::size_t write_queue_frames = 2;
  // Called before the first frame, on the capturing thread: what the recording holds (or would
  // hold, without `record`) and the calibration it is simulated with: what a scan session is
  // made from when there is no recording to open.
  std::function<void(const RecordingInfo& info, const std::optional<ScannerCalibration>& calibration)> described;
  // When given: the writer thread's figures, filled when the capture ends, also when it throws.
  RecordingWriteStatistics* write_statistics = nullptr;
};

struct SimRecordingSummary {
  std::string uri;
  int frames = 0;          // in the recording
  int resumed_from = 0;    // frames it held already when resumed (0: a new recording)
  int images_per_frame = 0;
  int width = 0;
  int height = 0;
  std::string groundtruth_folder;
};

// Writes the recording to `folder` (created; must not exist or be empty) on a writer thread
// beside the capture (options.write_queue_frames); it returns once every frame is written, and
// an error or a cancel writes every frame captured before it propagates. Every frame is
// flushed as it is written, so an interrupted run (an error, or the progress callback
// asking to stop: kCancelled after the current frame) leaves a valid recording of the frames
// done. Crash consistency: a frame's images, its groundtruth/frames/NNNNNN/ files and its
// pose in trajectory.txt are all on disk (fsynced, renamed into place) before the manifest
// lists it, so a kill or a full disk at any moment leaves every listed frame with its ground
// truth. trajectory.txt may then hold one pose more than the manifest lists (a kill between
// its write and the manifest's): the pose of a frame not listed, which readers ignore; a
// failure the writer sees trims it.
//
// options.resume: `folder` holds such a cut-off recording, made with the same options; the
// capture goes on from the first frame not listed. Frames are a pure function of the options
// and the frame index (noise keyed by seed, frame, pattern; turntable jitter by seed, step),
// so the result equals an uninterrupted run's file for file. Ground truth the listed frames
// lack (a recording of an older writer) is written again, trajectory.txt rewritten for the
// listed frames. Throws kNotFound without a recording there, kInvalidArgument when the
// options differ from the recording's (the message names what differs).
SimRecordingSummary write_sim_recording(const std::string& folder, const SimRecordingOptions& options,
                                        const Device& device, const ProgressCallback& progress);

}  // namespace sls::sim
