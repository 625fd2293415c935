#include "calib/view_observation.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "sdk/core/stopwatch.h"

#include "sdk/core/error.h"

namespace sls::calib {
namespace {

int find_reference(const PatternSet& patterns, PatternKind kind) {
  for (std::size_t i = 0; i < patterns.patterns.size(); ++i) {
    if (patterns.patterns[i].kind == kind) return static_cast<int>(i);
  }
  throw_error(ErrorCode::kInvalidArgument, "pattern set '{}' has no {} image: the board is found in white − black",
              patterns.name, kind == PatternKind::kWhite ? "white" : "black");
}

// Decoded share of the pixels in the corners' bounding box (a coarse figure for the report).
double decoded_fraction(const DecodedFrame& frame, const std::vector<Eigen::Vector2d>& corners) {
  Eigen::Vector2d lo = corners.front(), hi = corners.front();
  for (const Eigen::Vector2d& c : corners) {
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
  }
  const int x0 = std::max(0, static_cast<int>(lo.x())), x1 = std::min(frame.projector_u.width() - 1, static_cast<int>(hi.x()));
  const int y0 = std::max(0, static_cast<int>(lo.y())), y1 = std::min(frame.projector_u.height() - 1, static_cast<int>(hi.y()));
  std::size_t total = 0, ok = 0;
  for (int y = y0; y <= y1; y += 2) {
    for (int x = x0; x <= x1; x += 2) {
      ++total;
      ok += std::isfinite(frame.projector_u(x, y)) ? 1u : 0u;
    }
  }
  return total > 0 ? static_cast<double>(ok) / static_cast<double>(total) : 0.0;
}

// The part of the image the board's corners and their homography windows reach: decoding
// only that (a quarter of a 4000 x 3000 image, typically) is what makes a paper-size
// calibration quick.
ImageRegion board_region(const std::vector<Eigen::Vector2d>& corners, double square_px, int width, int height) {
  Eigen::Vector2d lo = corners.front(), hi = corners.front();
  for (const Eigen::Vector2d& c : corners) {
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
  }
  const double margin = std::max(square_px, 64.0);  // covers the largest homography window (60 px)
  ImageRegion r;
  r.x0 = std::max(0, static_cast<int>(std::floor(lo.x() - margin)));
  r.y0 = std::max(0, static_cast<int>(std::floor(lo.y() - margin)));
  r.width = std::min(width, static_cast<int>(std::ceil(hi.x() + margin)) + 1) - r.x0;
  r.height = std::min(height, static_cast<int>(std::ceil(hi.y() + margin)) + 1) - r.y0;
  return r;
}

Image16u crop(const Image16u& image, const ImageRegion& r) {
  Image16u out(r.width, r.height);
  for (int y = 0; y < r.height; ++y) {
    for (int x = 0; x < r.width; ++x) out(x, y) = image(r.x0 + x, r.y0 + y);
  }
  return out;
}

}  // namespace

std::vector<Eigen::Vector3d> view_object_points(const ViewObservation& view,
                                                const std::vector<Eigen::Vector3d>& board_points) {
  if (view.corner_ids.empty()) {  // a view made without ids: a whole chessboard's corners
    if (view.camera_corners.size() != board_points.size()) {
      throw_error(ErrorCode::kInvalidArgument, "view '{}': {} corners without ids, the board has {}", view.name,
                  view.camera_corners.size(), board_points.size());
    }
    return board_points;
  }
  std::vector<Eigen::Vector3d> points;
  points.reserve(view.corner_ids.size());
  for (int id : view.corner_ids) points.push_back(board_points.at(static_cast<std::size_t>(id)));
  return points;
}

std::size_t white_image_index(const PatternSet& patterns) {
  return static_cast<std::size_t>(find_reference(patterns, PatternKind::kWhite));
}

std::size_t black_image_index(const PatternSet& patterns) {
  return static_cast<std::size_t>(find_reference(patterns, PatternKind::kBlack));
}

BoardSighting sight_board(const Image16u& white, const Image16u& black, const ObservationOptions& options) {
  BoardSighting sighting;
  const auto start = std::chrono::steady_clock::now();
  sighting.board = detect_board(white, black, options.board);
  sighting.detect_s = 1e-3 * ms_since(start);
  if (sighting.board.found) {
    sighting.region = board_region(sighting.board.corners, sighting.board.square_px, white.width(), white.height());
  }
  return sighting;
}

ViewObservation observe_sighted_view(const std::string& name, std::optional<double> turntable_angle_deg,
                                     const BoardSighting& sighting, const std::vector<Image16u>& region_stack,
                                     const PatternSet& patterns, const ObservationOptions& options) {
  ViewObservation view;
  view.name = name;
  view.turntable_angle_deg = turntable_angle_deg;
  view.detect_s = sighting.detect_s;
  const BoardDetection& board = sighting.board;
  if (!board.found) {
    view.rejected_reason = board.reason;
    return view;
  }
  if (region_stack.size() != patterns.size()) {
    throw_error(ErrorCode::kInvalidArgument, "view '{}': {} images, the pattern set '{}' has {}", name,
                region_stack.size(), patterns.name, patterns.size());
  }
  for (const Image16u& image : region_stack) {
    if (image.width() != sighting.region.width || image.height() != sighting.region.height) {
      throw_error(ErrorCode::kInvalidArgument, "view '{}': a {}x{} image where the board's region is {}x{}", name,
                  image.width(), image.height(), sighting.region.width, sighting.region.height);
    }
  }
  view.board_found = true;
  view.camera_corners = board.corners;
  view.corner_ids = board.ids;
  view.square_px = board.square_px;
  auto start = std::chrono::steady_clock::now();
  const DecodedFrame decoded = decode_projector_coordinates(patterns, region_stack, options.decode, options.device);
  view.decode_s = 1e-3 * ms_since(start);
  std::vector<Eigen::Vector2d> corners_in_region = board.corners;
  for (Eigen::Vector2d& c : corners_in_region) c -= Eigen::Vector2d(sighting.region.x0, sighting.region.y0);
  view.decoded_fraction = decoded_fraction(decoded, corners_in_region);
  start = std::chrono::steady_clock::now();
  view.projector = projector_corners_by_local_homography(decoded.projector_u, decoded.projector_v, corners_in_region,
                                                         board.square_px, options.homography);
  view.homography_s = 1e-3 * ms_since(start);
  const int found = static_cast<int>(view.camera_corners.size());
  const int needed = static_cast<int>(std::ceil(options.min_projector_corner_fraction * found));
  if (view.projector.valid_count() < needed) {
    view.rejected_reason = fmt::format("too few decoded corners: the projector sees {} of {} (need {})",
                                       view.projector.valid_count(), found, needed);
  }
  return view;
}

ViewObservation observe_view(const std::string& name, std::optional<double> turntable_angle_deg,
                             const std::vector<Image16u>& stack, const PatternSet& patterns,
                             const ObservationOptions& options) {
  if (stack.size() != patterns.size()) {
    throw_error(ErrorCode::kInvalidArgument, "view '{}': {} images, the pattern set '{}' has {}", name, stack.size(),
                patterns.name, patterns.size());
  }
  const BoardSighting sighting =
      sight_board(stack[white_image_index(patterns)], stack[black_image_index(patterns)], options);
  std::vector<Image16u> cropped;
  if (sighting.board.found) {
    cropped.resize(stack.size());
    for (std::size_t i = 0; i < stack.size(); ++i) cropped[i] = crop(stack[i], sighting.region);
  }
  return observe_sighted_view(name, turntable_angle_deg, sighting, cropped, patterns, options);
}

}  // namespace sls::calib
