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
#include <string>

#include "drivers/sim/rig.h"
#include "sdk/core/device.h"
#include "sdk/core/progress.h"

namespace sls::sim {

struct SimRecordingOptions {
  std::string object = "knurled-screw";
  RigOptions rig;                     // preset, frames, projector, sensor, turntable, seed, noise
  bool depth_mode = false;            // depth maps instead of pattern images
  double reference_spacing_m = 0.0;   // 0: per preset (ci 100 µm, demo 30 µm, paper 10 µm)
};

struct SimRecordingSummary {
  std::string uri;
  int frames = 0;
  int images_per_frame = 0;
  int width = 0;
  int height = 0;
  std::string groundtruth_folder;
};

// Writes the recording to `folder` (created; must not exist or be empty). Every frame is
// flushed as it is captured, so an interrupted run (an error, or the progress callback
// asking to stop) leaves a valid recording of the frames done. Throws sls::Error.
SimRecordingSummary write_sim_recording(const std::string& folder, const SimRecordingOptions& options,
                                        const Device& device, const ProgressCallback& progress);

}  // namespace sls::sim
