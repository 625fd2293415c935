// The calibration target: a chessboard of inner_cols x inner_rows inner corners, found in a
// view's white image (OpenCV's detector, then sub-pixel refinement at full resolution), or a
// ChArUco board (OpenCV's aruco module: a chessboard whose light squares hold ArUco markers, so
// that each corner is known by its id and a view of part of the board counts).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "sdk/core/image.h"

namespace sls::calib {

enum class BoardKind { kChessboard, kCharuco };

// The dictionary a ChArUco board's markers come from when none is named.
inline constexpr const char* kDefaultCharucoDictionary = "DICT_5X5_100";
// A ChArUco view with fewer corners than this is rejected ("too few corners"): a pose is
// barely determined by fewer, and OpenCV interpolates a corner only from markers beside it.
constexpr int kMinCharucoCorners = 8;

struct BoardSpec {
  int inner_cols = 9;     // inner corners along a row (OpenCV's pattern width)
  int inner_rows = 7;
  double square_m = 0.0;  // side of a square; the unit every length of the result comes out in
  BoardKind kind = BoardKind::kChessboard;
  // ChArUco only: squares are (inner_cols + 1) x (inner_rows + 1) (OpenCV's CharucoBoard
  // squaresX x squaresY), each light square holding a marker of this side from `dictionary`
  // (OpenCV's name, e.g. "DICT_5X5_100"), marker i in the i-th light square as OpenCV lays them.
  double marker_m = 0.0;
  std::string dictionary = kDefaultCharucoDictionary;

  bool is_charuco() const { return kind == BoardKind::kCharuco; }
  int corner_count() const { return inner_cols * inner_rows; }
  // The inner corners in the board frame (z = 0), row by row, x fastest: OpenCV's order, and
  // for a ChArUco board its corner ids (OpenCV's chessboardCorners, moved so that corner 0 is
  // the origin, as a chessboard's).
  std::vector<Eigen::Vector3d> object_points() const;
  // "9x7 chessboard (inner corners), 0.6 mm squares" / "ChArUco 10x8 squares, ...".
  std::string describe() const;
  // Throws sls::Error(kInvalidArgument) naming the cause: fewer than 3 x 3 corners, square not
  // positive; for ChArUco a marker not smaller than its square, an unknown dictionary, or one
  // with fewer markers than the board has light squares.
  void validate() const;
};

// A board from the command line's words: "COLSxROWS" (a chessboard's inner corners, e.g.
// 9x7) or "charuco:COLSxROWS" (a ChArUco board's squares, e.g. charuco:12x9), the square's
// side, and for ChArUco the marker's side and the dictionary (empty: kDefaultCharucoDictionary).
// Validated; throws sls::Error(kInvalidArgument) naming the flag at fault (--board, --square,
// --marker, --dictionary).
BoardSpec parse_board_spec(const std::string& text, double square_m, double marker_m, const std::string& dictionary);

// Parses a dictionary's name (OpenCV's: DICT_4X4_50 ... DICT_7X7_1000, DICT_ARUCO_ORIGINAL,
// DICT_APRILTAG_16h5 ...; case-insensitive, "DICT_" optional). Throws kInvalidArgument for an
// unknown one, listing the known names.
std::string charuco_dictionary_name(const std::string& name);
std::vector<std::string> charuco_dictionary_names();

// A ChArUco board's printed pattern in the board frame (object_points()'s: square (I, J), I
// along x and J along y from 0, spans [(I − 1) s, I s] x [(J − 1) s, J s]), from OpenCV's
// dictionary, for a renderer that must not depend on OpenCV (the simulator): per square, dark
// or holding a marker; per marker square its cells x cells grid (the marker's bits inside a
// one-cell dark border), the marker centred in the square with side marker_m.
struct BoardPattern {
  int squares_x = 0, squares_y = 0;
  double square_m = 0.0, marker_m = 0.0;
  int cells = 0;                          // per marker side, border included (marker bits + 2)
  std::vector<std::uint8_t> dark_square;  // squares_x * squares_y, J * squares_x + I: 1 dark
  // Per square, cells * cells (row r along the board's y, column c along its x, r * cells + c):
  // 1 where the marker is dark; all 0 for a dark square.
  std::vector<std::uint8_t> dark_cells;
};
// Throws as validate() for a board that is not a valid ChArUco board.
BoardPattern charuco_pattern(const BoardSpec& board);

struct BoardDetection {
  bool found = false;
  std::string reason;                    // why not, when !found
  std::vector<Eigen::Vector2d> corners;  // camera pixels
  std::vector<int> ids;                  // per corner: its index in object_points()
  double square_px = 0.0;                // mean spacing of neighbouring corners
};

// Finds the board in the contrast image white − black (robust to ambient light). Large
// images are searched at a reduced size (≤ ~1600 px on the long side) and the corners refined
// on the full image. The ordering is made unique (corner 0 nearest the image's top-left):
// a board of odd x odd squares is symmetric under 180°, and the turntable-axis fit needs the
// same board frame in every view. A chessboard is found whole (ids 0 .. N − 1) or not at all.
BoardDetection detect_chessboard(const Image16u& white, const Image16u& black, const BoardSpec& board);

// A ChArUco board: its markers (OpenCV's detector and refinement against the board), then the
// corners between them (interpolateCornersCharuco, sub-pixel on the full image), each with its
// id; any part of the board counts. Not found, naming why: no marker of the dictionary, or
// fewer than kMinCharucoCorners corners, or corners all in one row or column.
BoardDetection detect_charuco(const Image16u& white, const Image16u& black, const BoardSpec& board);

// detect_chessboard or detect_charuco, by board.kind.
BoardDetection detect_board(const Image16u& white, const Image16u& black, const BoardSpec& board);

}  // namespace sls::calib
