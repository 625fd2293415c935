// The projector's view of the board (Moreno & Taubin 2012, "Simple, accurate, and robust
// projector-camera calibration"): the decoded projector coordinates of the camera pixels
// around each board corner, mapped to the corner by a local homography. The board is a plane,
// so near a corner camera pixels and projector pixels are related by a homography (lens
// distortion is smooth over a window); fitting one over hundreds of decoded pixels turns
// integer Gray codes or noisy phases into a sub-pixel projector position of the corner.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sdk/core/calibration.h"
#include "sdk/core/image.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/pattern_set.h"

namespace sls::calib {

// Decodes projector coordinates where no calibration exists yet: the decoder's triangulation
// needs one, so it gets a nominal rig (the projector beside the camera) with the depth range
// and the epipolar test opened; only the coordinates are kept. Both axes must be coded.
// Returns u, v (NaN where not decoded) in a DecodedFrame; depth is meaningless.
DecodedFrame decode_projector_coordinates(const PatternSet& patterns, const std::vector<Image16u>& stack,
                                          const DecodeOptions& options, const Device& device = Device::cpu());

// Decode options for a camera whose noise is unknown (captures made elsewhere): black from
// the black image, ~10 ke- of full well over the ADC's range, 0.5 DN of read noise.
DecodeOptions decode_options_for_unknown_camera(int bit_depth);

struct LocalHomographyOptions {
  int half_window_px = 0;       // 0: from the board's square size in the image (see below)
  int max_samples = 2500;       // decoded pixels per corner used at most (strided)
  int min_samples = 40;         // fewer decoded pixels: the corner has no projector position
  double inlier_px = 1.5;       // RANSAC threshold (projector pixels): Gray-code quantisation is ±0.5
};

struct ProjectorCorners {
  std::vector<Eigen::Vector2d> corners;  // projector pixels; meaningful where valid
  std::vector<std::uint8_t> valid;
  std::vector<int> samples;              // decoded pixels (inliers) behind each corner
  int valid_count() const;
};

// The camera pixels a corner's local homography reads: [x0, x1] x [y0, y1] around the corner's
// nearest pixel, `half` pixels each way, clipped to a width x height image.
struct CornerWindow {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
  int width() const { return x1 - x0 + 1; }
  int height() const { return y1 - y0 + 1; }
};
int local_homography_half_window(double square_px, const LocalHomographyOptions& options);
CornerWindow local_homography_window(const Eigen::Vector2d& corner, int half, int width, int height);

// `square_px`: the board's square size in the camera image (BoardDetection::square_px); the
// window's half size is 0.5 of it, 10..60 px (Moreno–Taubin's 47 x 47 px at their scale).
// Reads projector_u and projector_v only in the corners' windows.
ProjectorCorners projector_corners_by_local_homography(const Image32f& projector_u, const Image32f& projector_v,
                                                       const std::vector<Eigen::Vector2d>& camera_corners,
                                                       double square_px, const LocalHomographyOptions& options = {});

}  // namespace sls::calib
