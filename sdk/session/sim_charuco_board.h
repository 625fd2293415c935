// The simulator's ChArUco boards, with their markers from calib (OpenCV's dictionary as calib's
// plain bit table, calib::charuco_pattern): the simulator renders the table and never includes
// OpenCV, and the drivers do not depend on calib (DESIGN.md section 2), so the board is made
// here, above both. The one place that makes one: `sls sim --board charuco` and `--object
// charuco`, and every sim:// calibration target with board=charuco opened through
// device_open_options() (the SDK's devices: the C API, `sls scan --camera`, `sls calibrate
// --camera`). In a build without calib (no OpenCV: the GPU machine) they throw kUnsupported.
#pragma once

#include <optional>
#include <string>

#include "drivers/device_registry.h"
#include "drivers/sim/scene.h"
#include "sdk/core/device.h"

namespace sls::session {

// The default marker side as a fraction of the square (OpenCV's examples' ratio): 7 cells of a
// 5x5-bit marker, 4.3 camera pixels each at ci on the calibration board.
constexpr double kSimCharucoMarkerRatio = 0.75;

// The ChArUco board `spec` on `geometry`: "charuco" keeps geometry's squares (its inner corners
// + 1 each way), "charuco:COLSxROWS" (as `sls sim --board` spells it) has COLS x ROWS squares;
// square_m 0: geometry's square; marker_m 0: kSimCharucoMarkerRatio of the square; dictionary
// empty: calib's default (DICT_5X5_100). The light border is kept within half a square.
// Throws sls::Error: kInvalidArgument naming the fault (a bad spec, a marker not smaller than
// its square, an unknown dictionary or one too small for the board), kUnsupported without calib.
sim::ChessboardParameters sim_charuco_board(const std::string& spec, sim::ChessboardParameters geometry,
                                            double square_m = 0.0, double marker_m = 0.0,
                                            const std::string& dictionary = "");

// How the SDK opens devices: simulated ones render on `sim_device` (unless their URI says), and
// a sim:// calibration target's board=charuco is made by sim_charuco_board.
drivers::OpenOptions device_open_options(const std::optional<Device>& sim_device);

}  // namespace sls::session
