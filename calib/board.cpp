#include "calib/board.h"

#include <algorithm>
#include <cmath>

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

}  // namespace

std::vector<Eigen::Vector3d> BoardSpec::object_points() const {
  std::vector<Eigen::Vector3d> points;
  points.reserve(static_cast<std::size_t>(corner_count()));
  for (int row = 0; row < inner_rows; ++row) {
    for (int col = 0; col < inner_cols; ++col) points.emplace_back(col * square_m, row * square_m, 0.0);
  }
  return points;
}

void BoardSpec::validate() const {
  if (inner_cols < 3 || inner_rows < 3 || inner_cols > 100 || inner_rows > 100) {
    throw_error(ErrorCode::kInvalidArgument, "board of {}x{} inner corners (need 3..100 each way)", inner_cols,
                inner_rows);
  }
  if (!(square_m > 0.0) || !std::isfinite(square_m)) {
    throw_error(ErrorCode::kInvalidArgument, "board square size {} must be positive", square_m);
  }
}

BoardDetection detect_chessboard(const Image16u& white, const Image16u& black, const BoardSpec& board) {
  board.validate();
  if (white.empty() || white.width() != black.width() || white.height() != black.height()) {
    throw_error(ErrorCode::kInvalidArgument, "board detection: white {}x{} and black {}x{} images differ",
                white.width(), white.height(), black.width(), black.height());
  }
  BoardDetection detection;
  const cv::Mat contrast = contrast_image(white, black);
  const cv::Mat image8 = to_8bit(contrast);
  const int long_side = std::max(image8.cols, image8.rows);
  const int factor = std::max(1, (long_side + kSearchLongSide - 1) / kSearchLongSide);
  cv::Mat search = image8;
  if (factor > 1) cv::resize(image8, search, cv::Size(), 1.0 / factor, 1.0 / factor, cv::INTER_AREA);

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
  return detection;
}

}  // namespace sls::calib
