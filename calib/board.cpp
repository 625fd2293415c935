#include "calib/board.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cmath>

#include <map>
#include <numeric>

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "sdk/core/error.h"

namespace sls::calib {
namespace {

constexpr int kSearchLongSide = 1600;

// white − black as float, the contrast the corners are refined on.
cv::Mat contrast_image(const Image16u& white, const Image16u& black) {
  cv::Mat out(white.height(), white.width(), CV_32F);
  for (int y = 0; y < white.height(); ++y) {
    float* row = out.ptr<float>(y);
    for (int x = 0; x < white.width(); ++x) {
      row[x] = static_cast<float>(white(x, y)) - static_cast<float>(black(x, y));
    }
  }
  return out;
}

// 8-bit for the detector: the contrast stretched so its 99.5th percentile is white.
cv::Mat to_8bit(const cv::Mat& contrast) {
  std::vector<float> values;
  values.reserve(static_cast<std::size_t>(contrast.total() / 16 + 1));
  for (int y = 0; y < contrast.rows; y += 4) {
    const float* row = contrast.ptr<float>(y);
    for (int x = 0; x < contrast.cols; x += 4) values.push_back(row[x]);
  }
  const auto top = values.begin() + static_cast<std::ptrdiff_t>(0.995 * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), top, values.end());
  const double scale = *top > 0.0f ? 255.0 / static_cast<double>(*top) : 1.0;
  cv::Mat out;
  contrast.convertTo(out, CV_8U, scale, 0.0);  // saturates below 0 and above 255
  return out;
}

// What both detectors search and refine on: the contrast, its 8-bit stretch, and that reduced
// by an integer factor to at most kSearchLongSide on the long side.
struct BoardImages {
  cv::Mat contrast, image8, search;
  int factor = 1;
};

BoardImages board_images(const Image16u& white, const Image16u& black) {
  if (white.empty() || white.width() != black.width() || white.height() != black.height()) {
    throw_error(ErrorCode::kInvalidArgument, "board detection: white {}x{} and black {}x{} images differ",
                white.width(), white.height(), black.width(), black.height());
  }
  BoardImages images;
  images.contrast = contrast_image(white, black);
  images.image8 = to_8bit(images.contrast);
  const int long_side = std::max(images.image8.cols, images.image8.rows);
  images.factor = std::max(1, (long_side + kSearchLongSide - 1) / kSearchLongSide);
  images.search = images.image8;
  if (images.factor > 1) {
    cv::resize(images.image8, images.search, cv::Size(), 1.0 / images.factor, 1.0 / images.factor, cv::INTER_AREA);
  }
  return images;
}

// OpenCV's predefined dictionaries by name.
const std::map<std::string, cv::aruco::PREDEFINED_DICTIONARY_NAME>& dictionaries() {
  using namespace cv::aruco;
  static const std::map<std::string, PREDEFINED_DICTIONARY_NAME> names = {
      {"DICT_4X4_50", DICT_4X4_50},       {"DICT_4X4_100", DICT_4X4_100},
      {"DICT_4X4_250", DICT_4X4_250},     {"DICT_4X4_1000", DICT_4X4_1000},
      {"DICT_5X5_50", DICT_5X5_50},       {"DICT_5X5_100", DICT_5X5_100},
      {"DICT_5X5_250", DICT_5X5_250},     {"DICT_5X5_1000", DICT_5X5_1000},
      {"DICT_6X6_50", DICT_6X6_50},       {"DICT_6X6_100", DICT_6X6_100},
      {"DICT_6X6_250", DICT_6X6_250},     {"DICT_6X6_1000", DICT_6X6_1000},
      {"DICT_7X7_50", DICT_7X7_50},       {"DICT_7X7_100", DICT_7X7_100},
      {"DICT_7X7_250", DICT_7X7_250},     {"DICT_7X7_1000", DICT_7X7_1000},
      {"DICT_ARUCO_ORIGINAL", DICT_ARUCO_ORIGINAL},
      {"DICT_APRILTAG_16H5", DICT_APRILTAG_16h5}, {"DICT_APRILTAG_25H9", DICT_APRILTAG_25h9},
      {"DICT_APRILTAG_36H10", DICT_APRILTAG_36h10}, {"DICT_APRILTAG_36H11", DICT_APRILTAG_36h11},
  };
  return names;
}

std::string upper(std::string text) {
  for (char& c : text) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return text;
}

cv::Ptr<cv::aruco::Dictionary> dictionary_of(const BoardSpec& board) {
  return cv::aruco::getPredefinedDictionary(dictionaries().at(charuco_dictionary_name(board.dictionary)));
}

// OpenCV's board in square units (square 1, so its corners are whole numbers).
cv::Ptr<cv::aruco::CharucoBoard> opencv_board(const BoardSpec& board) {
  return cv::aruco::CharucoBoard::create(board.inner_cols + 1, board.inner_rows + 1, 1.0f,
                                         static_cast<float>(board.marker_m / board.square_m), dictionary_of(board));
}

}  // namespace

std::string charuco_dictionary_name(const std::string& name) {
  std::string key = upper(name);
  if (key.rfind("DICT_", 0) != 0) key = "DICT_" + key;
  if (dictionaries().count(key) == 0) {
    std::string known;
    for (const std::string& each : charuco_dictionary_names()) known += (known.empty() ? "" : ", ") + each;
    throw_error(ErrorCode::kInvalidArgument, "unknown ArUco dictionary '{}' (known: {})", name, known);
  }
  return key;
}

std::vector<std::string> charuco_dictionary_names() {
  std::vector<std::string> names;
  for (const auto& [name, value] : dictionaries()) names.push_back(name);
  return names;
}

BoardSpec parse_board_spec(const std::string& text, double square_m, double marker_m, const std::string& dictionary) {
  BoardSpec board;
  const bool charuco = text.rfind("charuco:", 0) == 0;
  const std::string size = charuco ? text.substr(8) : text;
  int cols = 0, rows = 0;
  char trailing = 0;
  if (std::sscanf(size.c_str(), "%dx%d%c", &cols, &rows, &trailing) != 2) {
    throw_error(ErrorCode::kInvalidArgument,
                "--board {}: expected COLSxROWS inner corners of a chessboard (e.g. 9x7) or charuco:COLSxROWS squares "
                "of a ChArUco board (e.g. charuco:12x9)",
                text);
  }
  if (!(square_m > 0.0)) throw_error(ErrorCode::kInvalidArgument, "--board needs --square (the square's side in metres)");
  board.square_m = square_m;
  if (!charuco) {
    if (marker_m > 0.0 || !dictionary.empty()) {
      throw_error(ErrorCode::kInvalidArgument,
                  "--marker and --dictionary describe a ChArUco board: --board charuco:COLSxROWS (--board {} is a "
                  "chessboard)",
                  text);
    }
    board.inner_cols = cols;
    board.inner_rows = rows;
    board.validate();
    return board;
  }
  board.kind = BoardKind::kCharuco;
  board.inner_cols = cols - 1;
  board.inner_rows = rows - 1;
  if (!(marker_m > 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "--board {} needs --marker (the ArUco marker's side in metres)", text);
  }
  board.marker_m = marker_m;
  if (!dictionary.empty()) board.dictionary = charuco_dictionary_name(dictionary);
  board.validate();
  return board;
}

std::vector<Eigen::Vector3d> BoardSpec::object_points() const {
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(corner_count()));
  // A ChArUco board's corner k is OpenCV's chessboardCorners[k] at ((i + 1) s, (j + 1) s):
  // the same order (checked in tests/unit/calib/test_charuco.cpp), moved by one square.
  for (int row = 0; row < inner_rows; ++row) {
    for (int col = 0; col < inner_cols; ++col) points.emplace_back(col * square_m, row * square_m, 0.0);
  }
  return points;
}

std::string BoardSpec::describe() const {
  if (!is_charuco()) return fmt::format("{}x{} inner corners, {} m squares", inner_cols, inner_rows, square_m);
  return fmt::format("ChArUco {}x{} squares ({}x{} inner corners), {} m squares, {} m markers of {}", inner_cols + 1,
                     inner_rows + 1, inner_cols, inner_rows, square_m, marker_m, dictionary);
}

void BoardSpec::validate() const {
  if (inner_cols < 3 || inner_rows < 3 || inner_cols > 100 || inner_rows > 100) {
    if (is_charuco()) {
      throw_error(ErrorCode::kInvalidArgument, "ChArUco board of {}x{} squares (need 4..101 each way)", inner_cols + 1,
                  inner_rows + 1);
    }
    throw_error(ErrorCode::kInvalidArgument, "board of {}x{} inner corners (need 3..100 each way)", inner_cols,
                inner_rows);
  }
  if (!(square_m > 0.0) || !std::isfinite(square_m)) {
    throw_error(ErrorCode::kInvalidArgument, "board square size {} must be positive", square_m);
  }
  if (!is_charuco()) return;
  if (!(marker_m > 0.0) || !std::isfinite(marker_m)) {
    throw_error(ErrorCode::kInvalidArgument, "ChArUco marker size {} must be positive (--marker)", marker_m);
  }
  if (marker_m >= square_m) {
    throw_error(ErrorCode::kInvalidArgument,
                "ChArUco marker size {} m must be smaller than the square size {} m (a marker sits inside its square)",
                marker_m, square_m);
  }
  const std::string name = charuco_dictionary_name(dictionary);
  const int light_squares = (inner_cols + 1) * (inner_rows + 1) / 2;
  const int markers = dictionary_of(*this)->bytesList.rows;
  if (light_squares > markers) {
    throw_error(ErrorCode::kInvalidArgument,
                "ChArUco board of {}x{} squares needs {} markers; the dictionary {} has {} (choose a larger one)",
                inner_cols + 1, inner_rows + 1, light_squares, name, markers);
  }
}

BoardPattern charuco_pattern(const BoardSpec& board) {
  if (!board.is_charuco()) throw_error(ErrorCode::kInvalidArgument, "charuco_pattern: {} is not ChArUco", board.describe());
  board.validate();
  const cv::Ptr<cv::aruco::CharucoBoard> cv_board = opencv_board(board);
  const cv::Ptr<cv::aruco::Dictionary>& dictionary = cv_board->dictionary;
  BoardPattern pattern;
  pattern.squares_x = board.inner_cols + 1;
  pattern.squares_y = board.inner_rows + 1;
  pattern.square_m = board.square_m;
  pattern.marker_m = board.marker_m;
  pattern.cells = dictionary->markerSize + 2;
  const int cells = pattern.cells;
  const std::size_t squares = static_cast<std::size_t>(pattern.squares_x * pattern.squares_y);
  pattern.dark_square.assign(squares, 1);
  pattern.dark_cells.assign(squares * static_cast<std::size_t>(cells * cells), 0);
  const double ratio = board.marker_m / board.square_m;
  for (std::size_t m = 0; m < cv_board->ids.size(); ++m) {
    const std::vector<cv::Point3f>& q = cv_board->objPoints[m];  // top-left, top-right, bottom-right, bottom-left
    const double cx = 0.25 * static_cast<double>(q[0].x + q[1].x + q[2].x + q[3].x);
    const double cy = 0.25 * static_cast<double>(q[0].y + q[1].y + q[2].y + q[3].y);
    const int i = static_cast<int>(std::floor(cx)), j = static_cast<int>(std::floor(cy));
    if (i < 0 || j < 0 || i >= pattern.squares_x || j >= pattern.squares_y) {
      throw_error(ErrorCode::kInternal, "ChArUco marker {} outside the board ({}, {})", cv_board->ids[m], cx, cy);
    }
    const std::size_t square = static_cast<std::size_t>(j * pattern.squares_x + i);
    pattern.dark_square[square] = 0;
    cv::Mat bits;
    dictionary->drawMarker(cv_board->ids[m], cells, bits, 1);
    // Each cell of the square's grid (board axes) looked up in the marker's own image, whose
    // x runs from its corner 0 to 1 and y from 0 to 3: whatever way OpenCV turns the marker.
    const Eigen::Vector2d p0(q[0].x, q[0].y), e1(q[1].x - q[0].x, q[1].y - q[0].y), e3(q[3].x - q[0].x, q[3].y - q[0].y);
    for (int r = 0; r < cells; ++r) {
      for (int c = 0; c < cells; ++c) {
        const Eigen::Vector2d centre(i + 0.5 * (1.0 - ratio) + (c + 0.5) * ratio / cells,
                                     j + 0.5 * (1.0 - ratio) + (r + 0.5) * ratio / cells);
        const double u = (centre - p0).dot(e1) / e1.squaredNorm() * cells;
        const double v = (centre - p0).dot(e3) / e3.squaredNorm() * cells;
        const int col = static_cast<int>(std::floor(u)), row = static_cast<int>(std::floor(v));
        if (col < 0 || row < 0 || col >= cells || row >= cells) {
          throw_error(ErrorCode::kInternal, "ChArUco marker {}: cell ({}, {}) outside it", cv_board->ids[m], r, c);
        }
        pattern.dark_cells[square * static_cast<std::size_t>(cells * cells) + static_cast<std::size_t>(r * cells + c)] =
            bits.at<std::uint8_t>(row, col) < 128 ? 1 : 0;
      }
    }
  }
  return pattern;
}

BoardDetection detect_chessboard(const Image16u& white, const Image16u& black, const BoardSpec& board) {
  board.validate();
  if (board.is_charuco()) return detect_charuco(white, black, board);
  BoardDetection detection;
  const BoardImages images = board_images(white, black);
  const cv::Mat& contrast = images.contrast;
  const cv::Mat& search = images.search;
  const int factor = images.factor;

  const cv::Size pattern(board.inner_cols, board.inner_rows);
  std::vector<cv::Point2f> found;
  // The sector-based detector (Duda & Frese 2018) first: it locates corners more accurately
  // than corner-window refinement on blurred or oblique views; the classic one as fallback.
  bool refined = cv::findChessboardCornersSB(search, pattern, found, cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY);
  bool ok = refined;
  if (!ok) {
    ok = cv::findChessboardCorners(search, pattern, found, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
  }
  if (!ok || found.size() != static_cast<std::size_t>(board.corner_count())) {
    detection.reason = fmt::format("board of {}x{} inner corners not found", board.inner_cols, board.inner_rows);
    return detection;
  }
  // Pixel centres: a pixel of the reduced image covers `factor` full pixels.
  for (cv::Point2f& p : found) {
    p.x = (p.x + 0.5f) * static_cast<float>(factor) - 0.5f;
    p.y = (p.y + 0.5f) * static_cast<float>(factor) - 0.5f;
  }
  double spacing = 0.0;
  int pairs = 0;
  for (int row = 0; row < board.inner_rows; ++row) {
    for (int col = 0; col + 1 < board.inner_cols; ++col) {
      const cv::Point2f d = found[static_cast<std::size_t>(row * board.inner_cols + col + 1)] -
                            found[static_cast<std::size_t>(row * board.inner_cols + col)];
      spacing += std::hypot(static_cast<double>(d.x), static_cast<double>(d.y));
      ++pairs;
    }
  }
  detection.square_px = spacing / pairs;
  if (!refined || factor > 1) {
    // Found at a reduced size or by the classic detector: refined on the full image, in a
    // window of a good part of a square that does not reach the next corner on an oblique view.
    const int half_window = std::clamp(static_cast<int>(0.3 * detection.square_px), 3, 40);
    cv::cornerSubPix(contrast, found, cv::Size(half_window, half_window), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
  }
  const cv::Point2f first = found.front(), last = found.back();
  if (first.x + first.y > last.x + last.y) std::reverse(found.begin(), found.end());
  detection.found = true;
  detection.corners.reserve(found.size());
  for (const cv::Point2f& p : found) detection.corners.emplace_back(p.x, p.y);
  detection.ids.resize(found.size());
  std::iota(detection.ids.begin(), detection.ids.end(), 0);
  return detection;
}

BoardDetection detect_charuco(const Image16u& white, const Image16u& black, const BoardSpec& board) {
  board.validate();
  if (!board.is_charuco()) return detect_chessboard(white, black, board);
  BoardDetection detection;
  const BoardImages images = board_images(white, black);
  const cv::Mat& contrast = images.contrast;
  const cv::Mat& image8 = images.image8;
  const cv::Mat& search = images.search;
  const int factor = images.factor;

  const cv::Ptr<cv::aruco::CharucoBoard> cv_board = opencv_board(board);
  const cv::Ptr<cv::aruco::DetectorParameters> parameters = cv::aruco::DetectorParameters::create();
  parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
  std::vector<std::vector<cv::Point2f>> markers, rejected;
  std::vector<int> marker_ids;
  cv::aruco::detectMarkers(search, cv_board->dictionary, markers, marker_ids, parameters, rejected);
  // Markers the detector rejected but the board's layout predicts (a partly hidden board).
  cv::aruco::refineDetectedMarkers(search, cv_board, markers, marker_ids, rejected);
  if (marker_ids.empty()) {
    detection.reason = fmt::format("ChArUco board not found: no marker of {} in the image ({})",
                                   charuco_dictionary_name(board.dictionary), board.describe());
    return detection;
  }
  for (std::vector<cv::Point2f>& marker : markers) {
    for (cv::Point2f& p : marker) {
      p.x = (p.x + 0.5f) * static_cast<float>(factor) - 0.5f;
      p.y = (p.y + 0.5f) * static_cast<float>(factor) - 0.5f;
    }
  }
  std::vector<cv::Point2f> corners;
  std::vector<int> ids;
  cv::aruco::interpolateCornersCharuco(markers, marker_ids, image8, cv_board, corners, ids);
  if (static_cast<int>(ids.size()) < kMinCharucoCorners) {
    detection.reason = fmt::format("too few ChArUco corners: {} found from {} marker(s) (need {})", ids.size(),
                                   marker_ids.size(), kMinCharucoCorners);
    return detection;
  }
  int min_col = board.inner_cols, max_col = -1, min_row = board.inner_rows, max_row = -1;
  for (int id : ids) {
    min_col = std::min(min_col, id % board.inner_cols);
    max_col = std::max(max_col, id % board.inner_cols);
    min_row = std::min(min_row, id / board.inner_cols);
    max_row = std::max(max_row, id / board.inner_cols);
  }
  if (min_col == max_col || min_row == max_row) {
    detection.reason = fmt::format("ChArUco corners all in one {} ({} corners): no pose from them",
                                   min_col == max_col ? "column" : "row", ids.size());
    return detection;
  }
  // Spacing of neighbouring corners (ids one apart in a row, or one row apart).
  std::map<int, cv::Point2f> by_id;
  for (std::size_t k = 0; k < ids.size(); ++k) by_id[ids[k]] = corners[k];
  double spacing = 0.0;
  int pairs = 0;
  for (const auto& [id, p] : by_id) {
    for (int next : {id % board.inner_cols + 1 < board.inner_cols ? id + 1 : -1, id + board.inner_cols}) {
      const auto it = by_id.find(next);
      if (next < 0 || it == by_id.end()) continue;
      spacing += std::hypot(static_cast<double>(it->second.x - p.x), static_cast<double>(it->second.y - p.y));
      ++pairs;
    }
  }
  if (pairs == 0) {  // no two neighbours: from the markers' sides
    for (const std::vector<cv::Point2f>& marker : markers) {
      for (int k = 0; k < 4; ++k) {
        const cv::Point2f d = marker[static_cast<std::size_t>((k + 1) % 4)] - marker[static_cast<std::size_t>(k)];
        spacing += std::hypot(static_cast<double>(d.x), static_cast<double>(d.y)) * board.square_m / board.marker_m;
        ++pairs;
      }
    }
  }
  detection.square_px = spacing / pairs;
  // Where each corner is, from the markers beside it (not from OpenCV's interpolation, whose
  // corner refinement on the 8-bit image can lock onto a marker's corner next to it on an
  // oblique view): a homography fitted to the corners of the markers within 1.5 squares (the
  // two or four that touch it; more when fewer are found), applied to the corner's board point.
  std::map<int, std::size_t> marker_of_id;
  for (std::size_t m = 0; m < cv_board->ids.size(); ++m) marker_of_id[cv_board->ids[m]] = m;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const cv::Point3f& corner = cv_board->chessboardCorners[static_cast<std::size_t>(ids[k])];
    std::vector<cv::Point2f> board_points, image_points;
    for (double reach : {1.5, 2.5, 4.0}) {
      board_points.clear();
      image_points.clear();
      for (std::size_t d = 0; d < marker_ids.size(); ++d) {
        const std::vector<cv::Point3f>& q = cv_board->objPoints[marker_of_id.at(marker_ids[d])];
        const double cx = 0.25 * static_cast<double>(q[0].x + q[1].x + q[2].x + q[3].x);
        const double cy = 0.25 * static_cast<double>(q[0].y + q[1].y + q[2].y + q[3].y);
        if (std::hypot(cx - static_cast<double>(corner.x), cy - static_cast<double>(corner.y)) > reach) continue;
        for (std::size_t c = 0; c < 4; ++c) {
          board_points.emplace_back(q[c].x, q[c].y);
          image_points.push_back(markers[d][c]);
        }
      }
      if (board_points.size() >= 8) break;
    }
    if (board_points.size() < 8) continue;  // OpenCV's position stays
    const cv::Mat h = cv::findHomography(board_points, image_points, 0);
    if (h.empty()) continue;
    std::vector<cv::Point2f> predicted;
    cv::perspectiveTransform(std::vector<cv::Point2f>{{corner.x, corner.y}}, predicted, h);
    corners[k] = predicted.front();
  }
  // Refined on the full contrast image in a window as wide as the gap between a square's edge
  // and its marker, (square − marker) / 2, so that the markers' edges beside the corner (which
  // do not pass through it and would pull it) stay at its border. Measured on simulated ci
  // views (docs/benchmarks.md): 0.6 of the gap leaves 0.35 px RMS (too few pixels to converge
  // from the homography's start), the gap 0.07 px, 1.6 gaps 0.2 px (markers pull).
  const double gap_px = 0.5 * (board.square_m - board.marker_m) / board.square_m * detection.square_px;
  const int half_window = std::clamp(static_cast<int>(std::min(0.3 * detection.square_px, gap_px)), 2, 40);
  cv::cornerSubPix(contrast, corners, cv::Size(half_window, half_window), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
  // In id order (a chessboard's order, for the corners a view has).
  std::vector<std::size_t> order(ids.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&ids](std::size_t a, std::size_t b) { return ids[a] < ids[b]; });
  detection.found = true;
  for (std::size_t k : order) {
    detection.corners.emplace_back(corners[k].x, corners[k].y);
    detection.ids.push_back(ids[k]);
  }
  return detection;
}

BoardDetection detect_board(const Image16u& white, const Image16u& black, const BoardSpec& board) {
  return board.is_charuco() ? detect_charuco(white, black, board) : detect_chessboard(white, black, board);
}

}  // namespace sls::calib
