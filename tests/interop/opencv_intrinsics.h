// Interop tests: camera intrinsics from OpenCV's camera matrix and distortion vector
// (order k1 k2 p1 p2 k3).
#pragma once

#include <opencv2/core.hpp>

#include "sdk/core/camera_model_shared.h"

namespace sls::test {

inline CameraIntrinsics intrinsics_from_opencv(const cv::Mat& k, const cv::Mat& d, int width, int height) {
  CameraIntrinsics c;
  c.width = width;
  c.height = height;
  c.fx = k.at<double>(0, 0);
  c.fy = k.at<double>(1, 1);
  c.cx = k.at<double>(0, 2);
  c.cy = k.at<double>(1, 2);
  c.k1 = d.at<double>(0);
  c.k2 = d.at<double>(1);
  c.p1 = d.at<double>(2);
  c.p2 = d.at<double>(3);
  c.k3 = d.at<double>(4);
  return c;
}

}  // namespace sls::test
