// Small rigs for the simulator's tests: the ci preset at a given camera width, 8 frames; and a
// scanner set up for a calibration capture (also used by tests/unit/calib).
#pragma once

#include <cstdint>
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

// A ChArUco-like board for the renderer's tests: the squares of `board` (default: the default
// chessboard's) with markers of 0.9 mm (7 x 7 cells, a dark border round pseudo-random bits) in
// its light squares. Not ArUco codes (those come from OpenCV through calib, which these tests
// do not link): what is tested is the rendering of whatever bit table it is given.
inline ChessboardParameters synthetic_charuco(int cells = 7, ChessboardParameters board = {}) {
  board.charuco.marker = 0.9e-3;
  board.charuco.cells = cells;
  board.charuco.dictionary = "synthetic";
  const int squares_x = board.inner_corners_x + 1, squares_y = board.inner_corners_y + 1;
  std::uint32_t state = 12345u;
  for (int j = 0; j < squares_y; ++j) {
    for (int i = 0; i < squares_x; ++i) {
      const bool dark = (i + j) % 2 == 0;
      board.charuco.dark_square.push_back(dark ? 1 : 0);
      for (int r = 0; r < cells; ++r) {
        for (int c = 0; c < cells; ++c) {
          state = state * 1664525u + 1013904223u;
          const bool border = r == 0 || c == 0 || r == cells - 1 || c == cells - 1;
          board.charuco.dark_cells.push_back(!dark && (border || (state >> 31) != 0u) ? 1 : 0);
        }
      }
    }
  }
  return board;
}

}  // namespace sls::sim
