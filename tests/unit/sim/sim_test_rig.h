// Small rigs for the simulator's tests: the ci preset at a given camera width, 8 frames; and a
// scanner set up for a calibration capture (also used by tests/unit/calib).
#pragma once

#include <memory>
#include <string>

#include "drivers/sim/rig.h"
#include "drivers/sim/sim_calibration_capture.h"
#include "drivers/sim/sim_scanner.h"

namespace sls::sim {

inline SimRig small_rig(const Scene& scene, int width = 160) {
  RigOptions options;
  options.preset = "ci";
  options.camera_width = width;
  options.frames = 8;
  return make_rig(options, scene);
}

// The simulated scanner with a calibration capture's rig (make_calibration_rig: the hand
// poses, then the turntable views), rendering on the CPU; the caller places the board
// (place_object) and moves the table.
inline std::shared_ptr<SimScanner> calibration_scanner(const SimCalibrationOptions& options,
                                                       const std::string& uri = "sim://chessboard") {
  const Scene board = make_chessboard_scene(options.board);
  return SimScanner::create(make_calibration_rig(options, board), board, Device::cpu(), uri);
}

}  // namespace sls::sim
