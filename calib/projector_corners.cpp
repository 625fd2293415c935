#include "calib/projector_corners.h"

#include <algorithm>
#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "sdk/core/error.h"

namespace sls::calib {
namespace {

bool decoded(const Image32f& u, const Image32f& v, int x, int y) {
  return std::isfinite(u(x, y)) && std::isfinite(v(x, y));
}

}  // namespace

DecodeOptions decode_options_for_unknown_camera(int bit_depth) {
  DecodeOptions options;
  options.bit_depth = bit_depth;
  options.black_level_dn = 0.0;
  options.gain_e_per_dn = 10000.0 / std::ldexp(1.0, bit_depth);
  options.read_noise_dn = 0.5;
  return options;
}

DecodedFrame decode_projector_coordinates(const PatternSet& patterns, const std::vector<Image16u>& stack,
                                          const DecodeOptions& options, const Device& device) {
  bool columns = false, rows = false;
  for (const PatternDesc& p : patterns.patterns) {
    if (p.kind == PatternKind::kGrayCode || p.kind == PatternKind::kPhaseShift) {
      (p.axis == PatternAxis::kColumns ? columns : rows) = true;
    }
  }
  if (!columns || !rows) {
    throw_error(ErrorCode::kInvalidArgument,
                "pattern set '{}' codes only the projector's {}: calibrating the projector needs columns and rows",
                patterns.name, columns ? "columns" : "rows");
  }
  if (stack.empty() || stack.front().empty()) {
    throw_error(ErrorCode::kInvalidArgument, "decode for calibration: empty image stack");
  }
  // A nominal rig (the calibration being made does not exist yet): the decoder triangulates
  // after decoding, and needs one. Its depth range and epipolar test are opened so every
  // decoded coordinate survives (as OutOfRange at worst); only the coordinates are used.
  ScannerCalibration nominal;
  const int width = stack.front().width(), height = stack.front().height();
  nominal.camera.width = width;
  nominal.camera.height = height;
  nominal.camera.fx = nominal.camera.fy = std::max(width, height);
  nominal.camera.cx = 0.5 * (width - 1);
  nominal.camera.cy = 0.5 * (height - 1);
  nominal.projector.width = patterns.projector_width;
  nominal.projector.height = patterns.projector_height;
  nominal.projector.fx = nominal.projector.fy = std::max(patterns.projector_width, patterns.projector_height);
  nominal.projector.cx = 0.5 * (patterns.projector_width - 1);
  nominal.projector.cy = 0.5 * (patterns.projector_height - 1);
  nominal.T_camera_projector =
      Pose(Eigen::Matrix3d(Eigen::AngleAxisd(-0.35, Eigen::Vector3d::UnitY())), Eigen::Vector3d(0.1, 0.0, 0.0));
  DecodeOptions open = options;
  open.min_triangulation_angle_deg = 0.0;
  open.min_depth_m = 1e-9;
  open.max_depth_m = 1e9;
  open.max_epipolar_error_px = 1e9;
  Decoder decoder(patterns, nominal, device, open);
  DecodedFrame frame = decoder.decode(stack);
  for (std::size_t i = 0; i < frame.mask.pixel_count(); ++i) {
    const std::uint8_t mask = frame.mask.data()[i];
    if (mask != kDecodeOk && mask != kDecodeOutOfRange) {
      frame.projector_u.data()[i] = frame.projector_v.data()[i] = NAN;
    }
  }
  return frame;
}

int ProjectorCorners::valid_count() const {
  return static_cast<int>(std::count(valid.begin(), valid.end(), std::uint8_t{1}));
}

int local_homography_half_window(double square_px, const LocalHomographyOptions& options) {
  return options.half_window_px > 0 ? options.half_window_px : std::clamp(static_cast<int>(0.5 * square_px), 10, 60);
}

CornerWindow local_homography_window(const Eigen::Vector2d& corner, int half, int width, int height) {
  const int cx = static_cast<int>(std::lround(corner.x()));
  const int cy = static_cast<int>(std::lround(corner.y()));
  CornerWindow window;
  window.x0 = std::max(0, cx - half);
  window.x1 = std::min(width - 1, cx + half);
  window.y0 = std::max(0, cy - half);
  window.y1 = std::min(height - 1, cy + half);
  return window;
}

ProjectorCorners projector_corners_by_local_homography(const Image32f& projector_u, const Image32f& projector_v,
                                                       const std::vector<Eigen::Vector2d>& camera_corners,
                                                       double square_px, const LocalHomographyOptions& options) {
  if (projector_u.width() != projector_v.width() || projector_u.height() != projector_v.height()) {
    throw_error(ErrorCode::kInvalidArgument, "local homographies: u and v images differ in size");
  }
  const int half = local_homography_half_window(square_px, options);
  ProjectorCorners out;
  out.corners.assign(camera_corners.size(), Eigen::Vector2d::Zero());
  out.valid.assign(camera_corners.size(), 0);
  out.samples.assign(camera_corners.size(), 0);
  const int width = projector_u.width(), height = projector_u.height();
  for (std::size_t c = 0; c < camera_corners.size(); ++c) {
    const CornerWindow window = local_homography_window(camera_corners[c], half, width, height);
    const int x0 = window.x0, x1 = window.x1, y0 = window.y0, y1 = window.y1;
    int count = 0;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) count += decoded(projector_u, projector_v, x, y) ? 1 : 0;
    if (count < options.min_samples) continue;
    // A regular stride keeps the samples spread over the window.
    const int stride = std::max(1, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(count) / options.max_samples))));
    std::vector<cv::Point2d> camera_points, projector_points;
    for (int y = y0; y <= y1; y += stride) {
      for (int x = x0; x <= x1; x += stride) {
        if (!decoded(projector_u, projector_v, x, y)) continue;
        // Relative to the corner: keeps the homography's fit well conditioned.
        camera_points.emplace_back(x - camera_corners[c].x(), y - camera_corners[c].y());
        projector_points.emplace_back(projector_u(x, y), projector_v(x, y));
      }
    }
    if (static_cast<int>(camera_points.size()) < options.min_samples) continue;
    std::vector<unsigned char> inliers;
    cv::Mat homography = cv::findHomography(camera_points, projector_points, cv::RANSAC, options.inlier_px, inliers,
                                            2000, 0.999);
    if (homography.empty()) continue;
    // Least squares on the inliers alone (RANSAC's model comes from 4 points).
    std::vector<cv::Point2d> camera_inliers, projector_inliers;
    for (std::size_t i = 0; i < inliers.size(); ++i) {
      if (inliers[i] == 0) continue;
      camera_inliers.push_back(camera_points[i]);
      projector_inliers.push_back(projector_points[i]);
    }
    if (static_cast<int>(camera_inliers.size()) < options.min_samples) continue;
    homography = cv::findHomography(camera_inliers, projector_inliers, 0);
    if (homography.empty()) continue;
    // The corner is the origin of the relative camera coordinates: H * (0, 0, 1).
    const double w = homography.at<double>(2, 2);
    if (!(std::fabs(w) > 1e-12)) continue;
    out.corners[c] = Eigen::Vector2d(homography.at<double>(0, 2) / w, homography.at<double>(1, 2) / w);
    out.valid[c] = std::isfinite(out.corners[c].x()) && std::isfinite(out.corners[c].y()) ? 1 : 0;
    out.samples[c] = static_cast<int>(camera_inliers.size());
  }
  return out;
}

}  // namespace sls::calib
