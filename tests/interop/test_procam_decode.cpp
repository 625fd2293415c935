// Real data (shared/data/procam-calibration, MIT licence): five Gray-code captures of a
// chessboard with a 1024x768 projector and a 1280x1024 camera, in the pattern order of
// OpenCV's structured_light GrayCodePattern. Our decoder decodes them; over the (planar)
// board, the undistorted projector coordinates must be a homography of the undistorted
// camera pixels. The residual RMS per capture is printed and bounded, beside OpenCV's own
// decode (GrayCodePattern::getProjPixel) of the same images.
#include <cstdio>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "calib/opencv_conversions.h"
#include "sdk/core/image_io.h"
#include "sdk/decode/decoder.h"
#include "tests/interop/opencv_graycode.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

constexpr int kProjectorWidth = 1024;
constexpr int kProjectorHeight = 768;

struct ProcamData {
  ScannerCalibration calibration;
  cv::Mat camera_matrix, camera_distortion, projector_matrix, projector_distortion;
};

ProcamData load_calibration() {
  cv::FileStorage file(test::shared_data_path("procam-calibration/calibration_result.xml"), cv::FileStorage::READ);
  EXPECT_TRUE(file.isOpened());
  ProcamData data;
  file["cam_int"] >> data.camera_matrix;
  file["cam_dist"] >> data.camera_distortion;
  file["proj_int"] >> data.projector_matrix;
  file["proj_dist"] >> data.projector_distortion;
  cv::Mat rotation, translation;
  file["roration"] >> rotation;  // sic: the key's spelling in that file
  file["translation"] >> translation;
  data.calibration.camera = calib::intrinsics_from(data.camera_matrix, data.camera_distortion, 1280, 1024);
  data.calibration.projector = calib::intrinsics_from(data.projector_matrix, data.projector_distortion, kProjectorWidth,
                                          kProjectorHeight);
  // OpenCV's stereo convention: X_projector = R X_camera + T, in chessboard units (75 per
  // square, size unknown): taken as millimetres. Only the projector coordinates matter here.
  Eigen::Matrix3d r;
  for (int i = 0; i < 9; ++i) r(i / 3, i % 3) = rotation.at<double>(i / 3, i % 3);
  const Eigen::Vector3d t(translation.at<double>(0), translation.at<double>(1), translation.at<double>(2));
  data.calibration.T_camera_projector = Pose(r, 1e-3 * t).inverse();
  return data;
}

// The homography fit of the decoded projector coordinates over the board (every 2nd pixel
// inside the hull of the inner corners): least squares, then again without the gross
// misdecodes (> 3 px).
struct BoardFit {
  std::size_t board_pixels = 0, decoded = 0, inliers = 0;
  double rms_px = 0.0;
  double decoded_fraction() const { return static_cast<double>(decoded) / static_cast<double>(board_pixels); }
  double outlier_fraction() const { return 1.0 - static_cast<double>(inliers) / static_cast<double>(decoded); }
};

BoardFit fit_board_homography(const ProcamData& data, const std::vector<cv::Point2f>& hull, const Image32f& u,
                              const Image32f& v) {
  BoardFit fit;
  std::vector<cv::Point2f> camera_points, projector_points;
  for (int y = 0; y < u.height(); y += 2) {
    for (int x = 0; x < u.width(); x += 2) {
      if (cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(x), static_cast<float>(y)), false) < 0) continue;
      ++fit.board_pixels;
      if (!std::isfinite(u(x, y)) || !std::isfinite(v(x, y))) continue;
      camera_points.emplace_back(static_cast<float>(x), static_cast<float>(y));
      projector_points.emplace_back(u(x, y), v(x, y));
    }
  }
  fit.decoded = camera_points.size();
  std::vector<cv::Point2f> camera_ideal, projector_ideal;
  cv::undistortPoints(camera_points, camera_ideal, data.camera_matrix, data.camera_distortion, cv::noArray(),
                      data.camera_matrix);
  cv::undistortPoints(projector_points, projector_ideal, data.projector_matrix, data.projector_distortion,
                      cv::noArray(), data.projector_matrix);
  cv::Mat homography = cv::findHomography(camera_ideal, projector_ideal, 0);
  double sum_squares = 0.0;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<cv::Point2f> mapped, kept_camera, kept_projector;
    cv::perspectiveTransform(camera_ideal, mapped, homography);
    sum_squares = 0.0;
    fit.inliers = 0;
    for (std::size_t i = 0; i < mapped.size(); ++i) {
      const double dx = mapped[i].x - projector_ideal[i].x, dy = mapped[i].y - projector_ideal[i].y;
      const double squared = dx * dx + dy * dy;
      if (squared > 9.0) continue;
      sum_squares += squared;
      ++fit.inliers;
      kept_camera.push_back(camera_ideal[i]);
      kept_projector.push_back(projector_ideal[i]);
    }
    if (pass == 0) homography = cv::findHomography(kept_camera, kept_projector, 0);
  }
  fit.rms_px = std::sqrt(sum_squares / static_cast<double>(fit.inliers));
  return fit;
}

TEST(ProcamDecode, BoardProjectorCoordinatesAreAHomographyOfCameraPixels) {
  const ProcamData data = load_calibration();
  DecodeOptions options;
  // An 8-bit camera of unknown noise: assume ~40 e-/DN (a 10 ke- pixel over 8 bits) and
  // 0.5 DN read noise; the black reference comes from the black pattern itself.
  options.bit_depth = 8;
  options.black_level_dn = 0.0;
  options.gain_e_per_dn = 40.0;
  options.read_noise_dn = 0.5;
  options.min_depth_m = 1e-4;  // depth is in unknown units here: keep every coordinate
  options.max_depth_m = 1e6;
  // That file's projector model does not describe these captures' geometry: at the depth the
  // rows give, it predicts columns about twice the decoded ones (hundreds of pixels off the
  // epipolar curves). Only the projector coordinates are judged here, so the ray-ray
  // epipolar test (exercised on the simulator, test_decoder) is switched off.
  options.max_epipolar_error_px = 1e9;
  Decoder decoder(test::opencv_graycode_pattern_set(1024, 768), data.calibration, Device::cpu(), options);
  cv::structured_light::GrayCodePattern::Params params;
  params.width = kProjectorWidth;
  params.height = kProjectorHeight;
  const auto graycode = cv::structured_light::GrayCodePattern::create(params);
  for (int capture = 0; capture < 5; ++capture) {
    std::vector<Image16u> stack;
    for (int k = 0; k < 42; ++k) {
      const std::string path =
          test::shared_data_path("procam-calibration/capture_" + std::to_string(capture) + "/graycode_" +
                                 (k < 10 ? "0" : "") + std::to_string(k) + ".png");
      stack.push_back(read_png_u16(path));
    }
    const DecodedFrame decoded = decoder.decode(stack);

    // The board: the convex hull of its 9x7 inner corners, found in the white image.
    cv::Mat white(stack[40].height(), stack[40].width(), CV_8U);
    for (int y = 0; y < white.rows; ++y)
      for (int x = 0; x < white.cols; ++x) white.at<unsigned char>(y, x) = static_cast<unsigned char>(stack[40](x, y));
    std::vector<cv::Point2f> corners;
    ASSERT_TRUE(cv::findChessboardCorners(white, cv::Size(9, 7), corners)) << "capture " << capture;
    std::vector<cv::Point2f> hull;
    cv::convexHull(corners, hull);

    std::size_t shadow = 0, low_modulation = 0, inconsistent = 0, board_pixels = 0;
    for (int y = 0; y < white.rows; y += 2) {
      for (int x = 0; x < white.cols; x += 2) {
        if (cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(x), static_cast<float>(y)), false) < 0) continue;
        ++board_pixels;
        const unsigned mask = decoded.mask(x, y);
        shadow += (mask & kDecodeShadow) != 0 ? 1u : 0u;
        low_modulation += (mask & kDecodeLowModulation) != 0 ? 1u : 0u;
        inconsistent += (mask & kDecodeInconsistent) != 0 ? 1u : 0u;
      }
    }
    const BoardFit ours = fit_board_homography(data, hull, decoded.projector_u, decoded.projector_v);
    std::printf("capture %d: %zu board pixels (every 2nd), %.1f %% decoded, homography residual RMS %.3f projector px, "
                "%.2f %% beyond 3 px; not decoded: %.1f %% shadow, %.1f %% low modulation, %.1f %% inconsistent\n",
                capture, ours.board_pixels, 100.0 * ours.decoded_fraction(), ours.rms_px,
                100.0 * ours.outlier_fraction(),
                100.0 * static_cast<double>(shadow) / static_cast<double>(board_pixels),
                100.0 * static_cast<double>(low_modulation) / static_cast<double>(board_pixels),
                100.0 * static_cast<double>(inconsistent) / static_cast<double>(board_pixels));
    // OpenCV on the same 42 images, its default thresholds.
    std::vector<cv::Mat> gray_images;
    for (int k = 0; k < 40; ++k) gray_images.push_back(test::to_opencv_8bit(stack[static_cast<std::size_t>(k)], 8));
    const test::OpenCvGrayDecode opencv = test::decode_with_opencv(
        graycode, gray_images, test::to_opencv_8bit(stack[40], 8), test::to_opencv_8bit(stack[41], 8));
    const BoardFit theirs = fit_board_homography(data, hull, opencv.u, opencv.v);
    // Judged on the same pixels: ours where OpenCV decoded too.
    Image32f common_u = decoded.projector_u, common_v = decoded.projector_v;
    for (int y = 0; y < common_u.height(); ++y) {
      for (int x = 0; x < common_u.width(); ++x) {
        if (!std::isfinite(opencv.u(x, y))) common_u(x, y) = common_v(x, y) = NAN;
      }
    }
    const BoardFit ours_common = fit_board_homography(data, hull, common_u, common_v);
    std::printf("capture %d, OpenCV GrayCodePattern: %.1f %% decoded, homography residual RMS %.3f projector px, "
                "%.2f %% beyond 3 px; ours on the same pixels %.3f px\n",
                capture, 100.0 * theirs.decoded_fraction(), theirs.rms_px, 100.0 * theirs.outlier_fraction(),
                ours_common.rms_px);

    // The dark squares of the printed board are within the noise for the finest bits: they
    // are rejected (inconsistent), not misdecoded. What decodes fits the homography with
    // integer Gray codes' quantisation.
    EXPECT_GT(ours.decoded_fraction(), 0.5) << capture;
    EXPECT_LT(ours.rms_px, 1.0) << capture;  // integer Gray codes alone: ~0.4 px of quantisation (1/sqrt(12) per axis)
    EXPECT_LT(ours.outlier_fraction(), 0.02) << capture;
    // Beside OpenCV on the same images: the same integer codes give as good a fit on the same
    // pixels, and ours decodes more of the board (noise-scaled decision margins instead of
    // fixed 8-bit thresholds).
    EXPECT_LE(ours_common.rms_px, theirs.rms_px + 0.005) << capture;
    EXPECT_GT(ours.decoded, theirs.decoded) << capture;
  }
}

}  // namespace
}  // namespace sls
