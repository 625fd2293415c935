// OpenCV (imgcodecs, 4.6) reads the PFM files we write exactly as we do, and we read the ones
// it writes: same size, same float bits, same row order.
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "sdk/core/image_io.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

std::uint32_t bits_of(float value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  return bits;
}

Image32f test_image(int width, int height) {
  Image32f image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image(x, y) = 1e-3f * static_cast<float>(x * 7 + y * 131) - 50.0f;
    }
  }
  // Values whose bits a careless reader would change: NaN, infinities, -0, a subnormal.
  image(0, 0) = std::numeric_limits<float>::quiet_NaN();
  image(1, 0) = std::numeric_limits<float>::infinity();
  image(2, 0) = -std::numeric_limits<float>::infinity();
  image(3, 0) = -0.0f;
  image(4, 0) = 1e-40f;
  image(width - 1, height - 1) = 12345.678f;
  return image;
}

TEST(PfmOpenCv, OpenCvReadsOurPfm) {
  test::TemporaryDirectory dir;
  const Image32f image = test_image(321, 123);
  const std::string path = dir.file("ours.pfm");
  write_pfm(path, image);
  const cv::Mat mat = cv::imread(path, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(mat.empty()) << "OpenCV could not read " << path;
  ASSERT_EQ(mat.type(), CV_32FC1);
  ASSERT_EQ(mat.cols, image.width());
  ASSERT_EQ(mat.rows, image.height());
  for (int y = 0; y < mat.rows; ++y) {
    for (int x = 0; x < mat.cols; ++x) {
      ASSERT_EQ(bits_of(mat.at<float>(y, x)), bits_of(image(x, y))) << x << "," << y;
    }
  }
}

TEST(PfmOpenCv, WeReadOpenCvsPfm) {
  test::TemporaryDirectory dir;
  const Image32f image = test_image(64, 48);
  cv::Mat mat(image.height(), image.width(), CV_32FC1);
  for (int y = 0; y < mat.rows; ++y) {
    for (int x = 0; x < mat.cols; ++x) mat.at<float>(y, x) = image(x, y);
  }
  const std::string path = dir.file("opencv.pfm");
  ASSERT_TRUE(cv::imwrite(path, mat));
  const Image32f back = read_pfm(path);
  ASSERT_EQ(back.width(), mat.cols);
  ASSERT_EQ(back.height(), mat.rows);
  for (int y = 0; y < mat.rows; ++y) {
    for (int x = 0; x < mat.cols; ++x) {
      ASSERT_EQ(bits_of(back(x, y)), bits_of(mat.at<float>(y, x))) << x << "," << y;
    }
  }
}

}  // namespace
}  // namespace sls
