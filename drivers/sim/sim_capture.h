// What the simulator's recordings share (sim_recording.cpp, sim_calibration_capture.cpp):
// the devices set up for a capture, a pattern stack captured through them, and the
// ground-truth files both write (rig.json, frames/NNNNNN/ maps).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/projector.h"
#include "drivers/interfaces/turntable.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/sim_recording.h"
#include "drivers/sim/sim_scanner.h"

namespace sls::sim {

constexpr std::chrono::milliseconds kSimDeviceTimeout{5000};

struct SimDevices {
  std::unique_ptr<drivers::Camera> camera;
  std::unique_ptr<drivers::Projector> projector;
  std::unique_ptr<drivers::Turntable> turntable;
};

// The scanner's devices ready to capture: the projector holds the rig's pattern set, the
// turntable is homed (0°), the camera started on software triggers.
SimDevices start_sim_devices(SimScanner& scanner);
// Stops the camera and darkens the projector.
void stop_sim_devices(SimDevices& devices);

// What a finished recording of `frames` frames from `scanner` tells its caller.
SimRecordingSummary recording_summary(const SimScanner& scanner, int frames, int images_per_frame,
                                      const std::string& groundtruth_folder);

// One camera image per pattern (0 .. count − 1) as the projector shows it; the first image's
// timestamp in *first_timestamp_ns.
std::vector<Image16u> capture_pattern_stack(SimDevices& devices, int count, std::int64_t* first_timestamp_ns);

// groundtruth/rig.json: optics, placement, turntable (docs/simulator-optics.md).
std::string rig_json(const SimRig& rig);

// groundtruth/frames/NNNNNN/: depth.pfm (m, 0 = no surface), projector_u.pfm,
// projector_v.pfm (NaN: not lit), valid.png (255: visible and lit), depth_sigma.pfm (m).
// Returns that folder.
std::string write_frame_ground_truth(const GroundTruthFrame& truth, const std::string& groundtruth_folder);

}  // namespace sls::sim
