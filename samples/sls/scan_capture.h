// `sls scan`'s options (cmd_scan.cpp) and the capture it makes before or while it fuses
// (--sim, --camera, --resume): fused while it records when it can be (frame_pipeline.h), else
// captured first.
#pragma once

#include <optional>
#include <string>

#include "samples/sls/capture.h"
#include "samples/sls/cli.h"
#include "sdk/core/device.h"
#include "sdk/session/scan_deformation.h"
#include "fusion/tracker.h"

namespace sls::cli {

struct ScanOptions {
  std::string input;
  std::string sim_preset;
  std::string camera_uri;      // devices by URI (sls devices lists them): capture through the sequencer
  std::string projector_uri;
  std::string turntable_uri;
  std::string exposures;       // HDR with those devices: relative exposure times, "4,1,0.25"
  std::string calibration;     // calibration.yml of those devices, stored in the recording
  std::string object = "knurled-screw";
  int frames = 0;
  std::string out;
  std::string device = "cuda";
  std::string fusion = "gtsdf";
  // --fusion gtsdf: the anisotropic term's parameters (unset: IntegrationOptions::gtsdf()'s)
  std::optional<double> gtsdf_lambda;
  std::optional<double> gtsdf_kappa;
  std::string gtsdf_penalty;
  std::optional<int> gtsdf_iterations;
  std::string poses = "track";
  double voxel_um = 0.0;          // 0: twice the camera's pixel footprint, grown to fit max_voxels
  double max_voxels_million = 0;  // 0: 256 on a GPU, 48 on the CPU
  double max_gpu_memory = 0;      // bytes of GPU memory the scan may allocate (0: no budget)
  bool turntable_prior = false;   // --poses track: the recording's turntable angles as the pose guess
  double photometric_weight = 0;  // --poses track: the tracker's photometric term (0: off)
  std::string icp_weights = "confidence";  // --poses track: ICP's per-pixel weights
  double icp_crease_deg = fusion::TrackingOptions{}.crease_angle_deg;  // --poses track: the crease test (0: off)
  std::string deformation = "on";   // --poses track: online deformation (the graph)
  std::string loop_closure;         // on | off; empty: on for a full turntable revolution
  std::string revisits = "auto";    // auto | keep | merge (session::RevisitPolicy)
  int loop_frames = session::DeformationOptions().loop_frames;  // last frames the loop closure registers
  bool resume = false;              // continue the capture in OUT/recording, then fuse it all
  bool no_record = false;           // --no-record: the capture fused while it runs, nothing of it written
  bool object_given = false;
  bool device_given = false;
};

// Whether the capture can be fused while it records: tracked poses (known poses come from
// the simulator's ground truth, read from the whole recording), and a calibration known before
// its first frame (the simulator's, one given, a replay:// camera's, or a resumed recording's).
// Otherwise it is captured first and fused after (capture_for_scan).
bool can_fuse_while_capturing(const ScanOptions& options);

// Sets `live` up to capture into `folder` (OUT/recording) as a frame source: the simulator
// (--sim), devices by URI (--camera), or with --resume the rest of the capture there, each frame
// handed to the scan as it is captured while a writer thread records it (session::captured_frames);
// with --no-record nothing is written (live->record false: no `folder` is made).
void start_live_capture(const Context& context, const ScanOptions& options, const Device& device,
                        const std::string& folder, LiveCapture* live);

// Captures into `folder` (OUT/recording) first, for a scan that cannot be fused while capturing.
// A SIGINT/SIGTERM stops it after the current frame: the recording is kept and said, with how to
// resume, and the scan stops there (false) instead of fusing a part of the object. A capture
// resumed when it was complete already captures nothing.
bool capture_for_scan(const Context& context, const ScanOptions& options, const Device& device,
                      const std::string& folder);

// The capture's summary line on stderr (nothing with --json).
void print_capture(const Context& context, const ScanOptions& options, const CaptureOutcome& outcome,
                   const std::string& folder);

}  // namespace sls::cli
