#include "sdk/session/sim_charuco_board.h"

#include <algorithm>

#include <fmt/format.h>

#include "sdk/core/error.h"
#if defined(SLS_HAVE_CALIB)
#include "calib/board.h"
#endif

namespace sls::session {

sim::ChessboardParameters sim_charuco_board(const std::string& spec, sim::ChessboardParameters geometry,
                                            double square_m, double marker_m, const std::string& dictionary) {
  if (spec != "charuco" && spec.rfind("charuco:", 0) != 0) {
    throw_error(ErrorCode::kInvalidArgument, "board '{}': expected charuco or charuco:COLSxROWS", spec);
  }
#if defined(SLS_HAVE_CALIB)
  const std::string size =
      spec == "charuco" ? fmt::format("charuco:{}x{}", geometry.inner_corners_x + 1, geometry.inner_corners_y + 1)
                        : spec;
  const double square = square_m > 0.0 ? square_m : geometry.square;
  const calib::BoardSpec board =
      calib::parse_board_spec(size, square, marker_m > 0.0 ? marker_m : kSimCharucoMarkerRatio * square, dictionary);
  const calib::BoardPattern pattern = calib::charuco_pattern(board);
  geometry.inner_corners_x = board.inner_cols;
  geometry.inner_corners_y = board.inner_rows;
  geometry.square = board.square_m;
  geometry.margin = std::min(geometry.margin, 0.5 * board.square_m);
  geometry.charuco.marker = pattern.marker_m;
  geometry.charuco.cells = pattern.cells;
  geometry.charuco.dictionary = board.dictionary;
  geometry.charuco.dark_square = pattern.dark_square;
  geometry.charuco.dark_cells = pattern.dark_cells;
  return geometry;
#else
  (void)geometry;
  (void)square_m;
  (void)marker_m;
  (void)dictionary;
  throw_error(ErrorCode::kUnsupported,
              "built without OpenCV: a ChArUco board's markers come from OpenCV's aruco dictionary");
#endif
}

drivers::OpenOptions device_open_options(const std::optional<Device>& sim_device) {
  drivers::OpenOptions options;
  options.sim_device = sim_device;
  options.sim_charuco_board = [](const std::string& spec, const sim::ChessboardParameters& geometry) {
    return sim_charuco_board(spec, geometry);
  };
  return options;
}

}  // namespace sls::session
