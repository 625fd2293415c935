#include "calib/view_observation.h"

#include <algorithm>
#include <cmath>
#include <utility>

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

// The projector coordinates of the pixels the local homographies read (the windows around
// the corners) and NaN elsewhere in the region, with the decoded share of the windows' pixels.
// The windows are decoded as one mosaic of tiles: the decoder works pixel by pixel, so each
// pixel decodes as it would in the whole region, for a quarter of the region's pixels at the
// paper's size (63 windows of 121 x 121 px in a board region of ~2000 x 1700).
struct WindowDecode {
  Image32f projector_u, projector_v;
  double decoded_fraction = 0.0;
};

WindowDecode decode_corner_windows(const std::vector<Image16u>& region_stack,
                                   const std::vector<Eigen::Vector2d>& corners, double square_px,
                                   const PatternSet& patterns, const ObservationOptions& options) {
  const int width = region_stack.front().width(), height = region_stack.front().height();
  const int half = local_homography_half_window(square_px, options.homography);
  const int tile = 2 * half + 1;
  const int count = static_cast<int>(corners.size());
  const int columns = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(count))));
  const int rows = (count + columns - 1) / columns;
  std::vector<CornerWindow> windows(corners.size());
  for (std::size_t c = 0; c < corners.size(); ++c) windows[c] = local_homography_window(corners[c], half, width, height);
  // Tile c holds window c at its top left; the rest of a clipped window's tile stays black.
  const auto tile_origin = [tile, columns](std::size_t c) {
    return std::pair<int, int>{static_cast<int>(c) % columns * tile, static_cast<int>(c) / columns * tile};
  };
  std::vector<Image16u> mosaic(region_stack.size());
  for (std::size_t i = 0; i < region_stack.size(); ++i) {
    mosaic[i] = Image16u(columns * tile, rows * tile, 0);
    for (std::size_t c = 0; c < windows.size(); ++c) {
      const auto [tx, ty] = tile_origin(c);
      for (int y = 0; y < windows[c].height(); ++y) {
        const std::uint16_t* from = &region_stack[i](windows[c].x0, windows[c].y0 + y);
        std::copy(from, from + windows[c].width(), &mosaic[i](tx, ty + y));
      }
    }
  }
  const DecodedFrame decoded = decode_projector_coordinates(patterns, mosaic, options.decode, options.device);
  WindowDecode out;
  out.projector_u = Image32f(width, height, NAN);
  out.projector_v = Image32f(width, height, NAN);
  std::size_t pixels = 0, ok = 0;
  for (std::size_t c = 0; c < windows.size(); ++c) {
    const auto [tx, ty] = tile_origin(c);
    for (int y = 0; y < windows[c].height(); ++y) {
      for (int x = 0; x < windows[c].width(); ++x) {
        const float u = decoded.projector_u(tx + x, ty + y);
        out.projector_u(windows[c].x0 + x, windows[c].y0 + y) = u;
        out.projector_v(windows[c].x0 + x, windows[c].y0 + y) = decoded.projector_v(tx + x, ty + y);
        ++pixels;
        ok += std::isfinite(u) ? 1u : 0u;
      }
    }
  }
  out.decoded_fraction = pixels > 0 ? static_cast<double>(ok) / static_cast<double>(pixels) : 0.0;
  return out;
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
  std::vector<Eigen::Vector2d> corners_in_region = board.corners;
  for (Eigen::Vector2d& c : corners_in_region) c -= Eigen::Vector2d(sighting.region.x0, sighting.region.y0);
  auto start = std::chrono::steady_clock::now();
  const WindowDecode decoded = decode_corner_windows(region_stack, corners_in_region, board.square_px, patterns, options);
  view.decode_s = 1e-3 * ms_since(start);
  view.decoded_fraction = decoded.decoded_fraction;
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
