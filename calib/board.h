// The calibration target: a chessboard of inner_cols x inner_rows inner corners, found in a
// view's white image (OpenCV's detector, then sub-pixel refinement at full resolution).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "sdk/core/image.h"

namespace sls::calib {

struct BoardSpec {
  int inner_cols = 9;     // inner corners along a row (OpenCV's pattern width)
  int inner_rows = 7;
  double square_m = 0.0;  // side of a square; the unit every length of the result comes out in

  int corner_count() const { return inner_cols * inner_rows; }
  // The inner corners in the board frame (z = 0), row by row, x fastest: OpenCV's order.
  std::vector<Eigen::Vector3d> object_points() const;
  // Throws sls::Error(kInvalidArgument): fewer than 3 x 3 corners, square not positive.
  void validate() const;
};

struct BoardDetection {
  bool found = false;
  std::string reason;                    // why not, when !found
  std::vector<Eigen::Vector2d> corners;  // camera pixels, in object_points() order
  double square_px = 0.0;                // mean spacing of neighbouring corners
};

// Finds the board in the contrast image white − black (robust to ambient light). Large
// images are searched at a reduced size (≤ ~1600 px on the long side) and the corners refined
// on the full image. The ordering is made unique (corner 0 nearest the image's top-left):
// a board of odd x odd squares is symmetric under 180°, and the turntable-axis fit needs the
// same board frame in every view.
BoardDetection detect_chessboard(const Image16u& white, const Image16u& black, const BoardSpec& board);

}  // namespace sls::calib
