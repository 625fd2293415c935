// Conversions between the SDK's camera model and pose and OpenCV's matrices, for calib/'s
// solvers (OpenCV types stay inside calib/).
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/pose.h"

namespace sls::calib {

inline CameraIntrinsics intrinsics_from(const cv::Mat& k, const cv::Mat& d, int width, int height) {
  CameraIntrinsics c;
  c.width = width;
  c.height = height;
  c.fx = k.at<double>(0, 0);
  c.fy = k.at<double>(1, 1);
  c.cx = k.at<double>(0, 2);
  c.cy = k.at<double>(1, 2);
  const cv::Mat flat = d.reshape(1, 1);
  const auto coefficient = [&](int i) { return i < flat.cols ? flat.at<double>(0, i) : 0.0; };
  c.k1 = coefficient(0);
  c.k2 = coefficient(1);
  c.p1 = coefficient(2);
  c.p2 = coefficient(3);
  c.k3 = coefficient(4);
  return c;
}

// OpenCV's camera matrix and distortion (k1 k2 p1 p2 k3) of an intrinsics.
inline cv::Mat camera_matrix_of(const CameraIntrinsics& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
}
inline cv::Mat distortion_of(const CameraIntrinsics& c) {
  return (cv::Mat_<double>(1, 5) << c.k1, c.k2, c.p1, c.p2, c.k3);
}

inline Pose pose_from(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Matrix3d rotation;
  for (int i = 0; i < 9; ++i) rotation(i / 3, i % 3) = r.at<double>(i / 3, i % 3);
  return Pose(rotation, Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
}

inline std::vector<cv::Point3f> to_cv(const std::vector<Eigen::Vector3d>& points) {
  std::vector<cv::Point3f> out;
  for (const Eigen::Vector3d& p : points) {
    out.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  }
  return out;
}

inline cv::Point2f to_cv(const Eigen::Vector2d& p) { return {static_cast<float>(p.x()), static_cast<float>(p.y())}; }

}  // namespace sls::calib
