// Real data (shared/data/procam-calibration, MIT licence): five Gray-code captures of a
// chessboard with a 1024x768 projector and a 1280x1024 camera, in the pattern order of
// OpenCV's structured_light GrayCodePattern. Our decoder decodes them; over the (planar)
// board, the undistorted projector coordinates must be a homography of the undistorted
// camera pixels. The residual RMS per capture is printed and bounded.
#include <cstdio>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "sdk/core/image_io.h"
#include "sdk/decode/decoder.h"
#include "tests/interop/opencv_intrinsics.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

constexpr int kProjectorWidth = 1024;
constexpr int kProjectorHeight = 768;

// OpenCV's GrayCodePattern order: per column bit (coarsest first) a pattern and its inverse,
// the same for the rows, then white and black.
PatternSet opencv_graycode_set() {
  PatternSet set;
  set.name = "opencv_graycode_1024x768";
  set.projector_width = kProjectorWidth;
  set.projector_height = kProjectorHeight;
  for (const PatternAxis axis : {PatternAxis::kColumns, PatternAxis::kRows}) {
    for (int bit = 9; bit >= 0; --bit) {
      for (const bool inverted : {false, true}) {
        PatternDesc d;
        d.kind = PatternKind::kGrayCode;
        d.axis = axis;
        d.extent = axis == PatternAxis::kColumns ? kProjectorWidth : kProjectorHeight;
        d.bit = bit;
        d.inverted = inverted;
        set.patterns.push_back(d);
      }
    }
  }
  for (const PatternKind kind : {PatternKind::kWhite, PatternKind::kBlack}) {
    PatternDesc d;
    d.kind = kind;
    d.extent = kProjectorWidth;
    set.patterns.push_back(d);
  }
  return set;
}

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
  data.calibration.camera = test::intrinsics_from_opencv(data.camera_matrix, data.camera_distortion, 1280, 1024);
  data.calibration.projector = test::intrinsics_from_opencv(data.projector_matrix, data.projector_distortion, kProjectorWidth,
                                          kProjectorHeight);
  // OpenCV's stereo convention: X_projector = R X_camera + T, in chessboard units (75 per
  // square, size unknown): taken as millimetres. Only the projector coordinates matter here.
  Eigen::Matrix3d r;
  for (int i = 0; i < 9; ++i) r(i / 3, i % 3) = rotation.at<double>(i / 3, i % 3);
  const Eigen::Vector3d t(translation.at<double>(0), translation.at<double>(1), translation.at<double>(2));
  data.calibration.T_camera_projector = Pose(r, 1e-3 * t).inverse();
  return data;
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
  Decoder decoder(opencv_graycode_set(), data.calibration, Device::cpu(), options);
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

    std::vector<cv::Point2f> camera_points, projector_points;
    std::size_t board_pixels = 0, shadow = 0, low_modulation = 0, inconsistent = 0;
    for (int y = 0; y < white.rows; y += 2) {
      for (int x = 0; x < white.cols; x += 2) {
        if (cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(x), static_cast<float>(y)), false) < 0) continue;
        ++board_pixels;
        const unsigned mask = decoded.mask(x, y);
        shadow += (mask & kDecodeShadow) != 0 ? 1u : 0u;
        low_modulation += (mask & kDecodeLowModulation) != 0 ? 1u : 0u;
        inconsistent += (mask & kDecodeInconsistent) != 0 ? 1u : 0u;
        const float u = decoded.projector_u(x, y), v = decoded.projector_v(x, y);
        if (!std::isfinite(u) || !std::isfinite(v)) continue;
        camera_points.emplace_back(static_cast<float>(x), static_cast<float>(y));
        projector_points.emplace_back(u, v);
      }
    }
    const double decoded_fraction = static_cast<double>(camera_points.size()) / static_cast<double>(board_pixels);
    std::vector<cv::Point2f> camera_ideal, projector_ideal;
    cv::undistortPoints(camera_points, camera_ideal, data.camera_matrix, data.camera_distortion, cv::noArray(),
                        data.camera_matrix);
    cv::undistortPoints(projector_points, projector_ideal, data.projector_matrix, data.projector_distortion,
                        cv::noArray(), data.projector_matrix);
    // Least squares, then again without the gross misdecodes (> 3 px).
    cv::Mat homography = cv::findHomography(camera_ideal, projector_ideal, 0);
    double sum_squares = 0.0;
    std::size_t inliers = 0;
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<cv::Point2f> mapped, kept_camera, kept_projector;
      cv::perspectiveTransform(camera_ideal, mapped, homography);
      sum_squares = 0.0;
      inliers = 0;
      for (std::size_t i = 0; i < mapped.size(); ++i) {
        const double dx = mapped[i].x - projector_ideal[i].x, dy = mapped[i].y - projector_ideal[i].y;
        const double squared = dx * dx + dy * dy;
        if (squared > 9.0) continue;
        sum_squares += squared;
        ++inliers;
        kept_camera.push_back(camera_ideal[i]);
        kept_projector.push_back(projector_ideal[i]);
      }
      if (pass == 0) homography = cv::findHomography(kept_camera, kept_projector, 0);
    }
    const double rms = std::sqrt(sum_squares / static_cast<double>(inliers));
    const double outliers = 1.0 - static_cast<double>(inliers) / static_cast<double>(camera_points.size());
    std::printf("capture %d: %zu board pixels (every 2nd), %.1f %% decoded, homography residual RMS %.3f projector px, "
                "%.2f %% beyond 3 px; not decoded: %.1f %% shadow (dark squares), %.1f %% low modulation, %.1f %% "
                "inconsistent\n",
                capture, board_pixels, 100.0 * decoded_fraction, rms, 100.0 * outliers,
                100.0 * static_cast<double>(shadow) / static_cast<double>(board_pixels),
                100.0 * static_cast<double>(low_modulation) / static_cast<double>(board_pixels),
                100.0 * static_cast<double>(inconsistent) / static_cast<double>(board_pixels));
    // The printed board's dark squares fall under the decoder's default 16 DN shadow contrast
    // (a default sized for 12-bit cameras): they are rejected, not misdecoded. Everything
    // else on the board decodes.
    const double lit = static_cast<double>(board_pixels - shadow);
    EXPECT_GT(static_cast<double>(camera_points.size()) / lit, 0.97) << capture;
    EXPECT_GT(decoded_fraction, 0.45) << capture;
    EXPECT_LT(rms, 1.0) << capture;  // integer Gray codes alone: ~0.4 px of quantisation (1/√12 per axis)
    EXPECT_LT(outliers, 0.02) << capture;
  }
}

}  // namespace
}  // namespace sls
