// OpenCV's structured_light GrayCodePattern as the reference decoder that ours is compared
// with (issue #4): its pattern order described as one of our pattern sets (so the simulator
// renders exactly OpenCV's patterns) and a decode of a captured stack with OpenCV's own
// per-pixel call, getProjPixel, plus its shadow mask (white - black > blackThreshold), the
// way a single-camera projector-camera user decodes with it. Header-only, tests/ only.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/structured_light.hpp>

#include "sdk/core/image.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/decode/pattern_shared.h"

namespace sls::test {

// OpenCV's order (now part of sdk/decode, where `sls calibrate --patterns` finds it by name).
inline PatternSet opencv_graycode_pattern_set(int width, int height, bool references = true) {
  return make_opencv_graycode_pattern_set(width, height, references);
}

// GrayCodePattern reads 8-bit images: a camera image of `bit_depth` bits scaled down to 8.
inline cv::Mat to_opencv_8bit(const Image16u& image, int bit_depth) {
  cv::Mat out(image.height(), image.width(), CV_8U);
  const int shift = bit_depth - 8;
  for (int y = 0; y < image.height(); ++y) {
    auto* row = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < image.width(); ++x) row[x] = static_cast<std::uint8_t>(image(x, y) >> shift);
  }
  return out;
}

struct OpenCvGrayDecode {
  Image32f u;  // projector column (integer), NaN where not decoded
  Image32f v;  // projector row
  std::size_t decoded = 0;
};

// `gray_images`: OpenCV's Gray patterns in its order (no references), 8-bit. Thresholds are
// OpenCV's defaults (3DUNDERWORLD's): white 5, black 40.
inline OpenCvGrayDecode decode_with_opencv(const cv::Ptr<cv::structured_light::GrayCodePattern>& graycode,
                                           const std::vector<cv::Mat>& gray_images, const cv::Mat& white,
                                           const cv::Mat& black, int black_threshold = 40) {
  OpenCvGrayDecode out;
  out.u = Image32f(white.cols, white.rows, NAN);
  out.v = Image32f(white.cols, white.rows, NAN);
  for (int y = 0; y < white.rows; ++y) {
    for (int x = 0; x < white.cols; ++x) {
      if (static_cast<int>(white.at<std::uint8_t>(y, x)) - static_cast<int>(black.at<std::uint8_t>(y, x)) <=
          black_threshold) {
        continue;  // OpenCV's shadow mask
      }
      cv::Point projector_pixel;
      if (graycode->getProjPixel(gray_images, x, y, projector_pixel)) continue;  // true = error
      out.u(x, y) = static_cast<float>(projector_pixel.x);
      out.v(x, y) = static_cast<float>(projector_pixel.y);
      ++out.decoded;
    }
  }
  return out;
}

}  // namespace sls::test
