// One board pose as the calibration sees it: the board's corners in the camera image and,
// through the decoded patterns, in the projector.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/board.h"
#include "calib/projector_corners.h"
#include "sdk/core/device.h"
#include "sdk/core/image.h"
#include "sdk/core/image_io.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/pattern_set.h"

namespace sls::calib {

struct ViewObservation {
  std::string name;                          // e.g. "frame 3" or the capture's subfolder
  std::optional<double> turntable_angle_deg; // set for the turntable-axis views
  bool board_found = false;
  std::string rejected_reason;               // empty while the view is usable
  std::vector<Eigen::Vector2d> camera_corners;
  // Per camera corner: its id, the index of its point in BoardSpec::object_points(). A
  // chessboard's views have every corner (0 .. N − 1); a ChArUco view those it found.
  std::vector<int> corner_ids;
  ProjectorCorners projector;
  double square_px = 0.0;
  double decoded_fraction = 0.0;             // of the pixels around the corners (the local homographies' windows)
  // Where the time went (seconds): finding the board, decoding, the local homographies.
  double detect_s = 0.0, decode_s = 0.0, homography_s = 0.0;
};

struct ObservationOptions {
  BoardSpec board;
  DecodeOptions decode;
  LocalHomographyOptions homography;
  // A view whose projector sees fewer of the corners found in the camera than this is rejected
  // ("too few decoded corners"): a partly shadowed board biases nothing, but a handful of
  // corners adds little.
  double min_projector_corner_fraction = 0.5;
  Device device = Device::cpu();
};

// The board-frame points of the view's corners (object_points() at corner_ids).
std::vector<Eigen::Vector3d> view_object_points(const ViewObservation& view, const std::vector<Eigen::Vector3d>& board_points);

// A view's board found in its white − black image, and the part of the image that its
// corners and their homography windows reach (a quarter of a 4000 x 3000 image, typically):
// all of the view's other images that the calibration reads.
struct BoardSighting {
  BoardDetection board;
  ImageRegion region;    // set when board.found
  double detect_s = 0.0;
};

// The positions of the white and the black image in the set; kInvalidArgument without them.
std::size_t white_image_index(const PatternSet& patterns);
std::size_t black_image_index(const PatternSet& patterns);

// Finds the board (detect_board) and its region. Never throws for a bad view.
BoardSighting sight_board(const Image16u& white, const Image16u& black, const ObservationOptions& options);

// The view from its sighting and its images cropped to the sighting's region, in the pattern
// set's order: the board's corners decoded in the projector. A sighting without a board
// gives a view rejected for its reason.
ViewObservation observe_sighted_view(const std::string& name, std::optional<double> turntable_angle_deg,
                                     const BoardSighting& sighting, const std::vector<Image16u>& region_stack,
                                     const PatternSet& patterns, const ObservationOptions& options);

// Detects the board in the white − black image and finds its corners in the projector
// (sight_board, then observe_sighted_view on the stack cropped to the region).
// `stack` in the pattern set's order (white and black included). Never throws for a bad
// view (the reason is in rejected_reason); throws sls::Error for bad arguments (a stack
// that does not match the set, a set without white/black or without both axes).
ViewObservation observe_view(const std::string& name, std::optional<double> turntable_angle_deg,
                             const std::vector<Image16u>& stack, const PatternSet& patterns,
                             const ObservationOptions& options);

}  // namespace sls::calib
