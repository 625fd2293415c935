// The SLS camera model, shared by CPU and CUDA code: pinhole with Brown–Conrady distortion
// (radial k1 k2 k3, tangential p1 p2), the same model and coefficient meaning as OpenCV's
// calibrateCamera / projectPoints. Used for cameras and, in reverse, for the projector.
//
// Frames: the camera looks along +z; pixel (0,0) is the centre of the top-left pixel.
// "normalized" coordinates are (x/z, y/z) before distortion; "distorted" after it.
#pragma once

#include <cmath>

#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls {

template <typename T>
struct CameraIntrinsicsT {
  int width = 0;   // image size in pixels
  int height = 0;
  T fx = 0, fy = 0;  // focal lengths in pixels
  T cx = 0, cy = 0;  // principal point in pixels
  T k1 = 0, k2 = 0, k3 = 0;  // radial distortion
  T p1 = 0, p2 = 0;          // tangential distortion

  template <typename U>
  SLS_HOST_DEVICE CameraIntrinsicsT<U> cast() const {
    CameraIntrinsicsT<U> out;
    out.width = width; out.height = height;
    out.fx = static_cast<U>(fx); out.fy = static_cast<U>(fy);
    out.cx = static_cast<U>(cx); out.cy = static_cast<U>(cy);
    out.k1 = static_cast<U>(k1); out.k2 = static_cast<U>(k2); out.k3 = static_cast<U>(k3);
    out.p1 = static_cast<U>(p1); out.p2 = static_cast<U>(p2);
    return out;
  }
  SLS_HOST_DEVICE bool has_distortion() const {
    return k1 != T(0) || k2 != T(0) || k3 != T(0) || p1 != T(0) || p2 != T(0);
  }
};

using CameraIntrinsics = CameraIntrinsicsT<double>;
using CameraIntrinsicsF = CameraIntrinsicsT<float>;

// Applies lens distortion to normalized coordinates.
template <typename T>
SLS_HOST_DEVICE inline Vec2T<T> distort_normalized(const CameraIntrinsicsT<T>& c, Vec2T<T> n) {
  const T r2 = n.x * n.x + n.y * n.y;
  const T radial = T(1) + r2 * (c.k1 + r2 * (c.k2 + r2 * c.k3));
  const T xy = n.x * n.y;
  return {n.x * radial + T(2) * c.p1 * xy + c.p2 * (r2 + T(2) * n.x * n.x),
          n.y * radial + c.p1 * (r2 + T(2) * n.y * n.y) + T(2) * c.p2 * xy};
}

// Jacobian of distort_normalized at n, row-major [dxd/dx dxd/dy; dyd/dx dyd/dy].
template <typename T>
SLS_HOST_DEVICE inline void distortion_jacobian(const CameraIntrinsicsT<T>& c, Vec2T<T> n, T jacobian[4]) {
  const T r2 = n.x * n.x + n.y * n.y;
  const T radial = T(1) + r2 * (c.k1 + r2 * (c.k2 + r2 * c.k3));
  const T dradial_dr2 = c.k1 + r2 * (T(2) * c.k2 + T(3) * c.k3 * r2);
  const T dradial_dx = T(2) * n.x * dradial_dr2;
  const T dradial_dy = T(2) * n.y * dradial_dr2;
  jacobian[0] = radial + n.x * dradial_dx + T(2) * c.p1 * n.y + T(6) * c.p2 * n.x;
  jacobian[1] = n.x * dradial_dy + T(2) * c.p1 * n.x + T(2) * c.p2 * n.y;
  jacobian[2] = n.y * dradial_dx + T(2) * c.p1 * n.x + T(2) * c.p2 * n.y;
  jacobian[3] = radial + n.y * dradial_dy + T(6) * c.p1 * n.y + T(2) * c.p2 * n.x;
}

// Inverts the distortion by Newton's method, starting at the distorted point. Returns false
// when it does not converge (far outside the calibrated field, where the polynomial folds).
template <typename T>
SLS_HOST_DEVICE inline bool undistort_normalized(const CameraIntrinsicsT<T>& c, Vec2T<T> distorted,
                                                 Vec2T<T>* undistorted) {
  Vec2T<T> n = distorted;
  if (!c.has_distortion()) {
    *undistorted = n;
    return true;
  }
  // Converged when the residual is a few ulps of the coordinate (1e-15 for double, 1e-6 for float).
  const T tolerance = sizeof(T) >= 8 ? T(1e-15) : T(2e-7);
  for (int iteration = 0; iteration < 20; ++iteration) {
    const Vec2T<T> residual = distort_normalized(c, n) - distorted;
    if (std::fabs(residual.x) <= tolerance && std::fabs(residual.y) <= tolerance) {
      *undistorted = n;
      return true;
    }
    T j[4];
    distortion_jacobian(c, n, j);
    const T det = j[0] * j[3] - j[1] * j[2];
    if (!(std::fabs(det) > T(1e-12))) break;
    n.x -= (j[3] * residual.x - j[1] * residual.y) / det;
    n.y -= (-j[2] * residual.x + j[0] * residual.y) / det;
  }
  const Vec2T<T> residual = distort_normalized(c, n) - distorted;
  *undistorted = n;
  // Float iterations can stall a few ulps above the tolerance: accept 2e-6 normalized units
  // (0.01 px at f = 5000 px) for float, 1e-12 for double.
  const T accept = sizeof(T) >= 8 ? T(1e-12) : T(2e-6);
  return std::fabs(residual.x) <= accept && std::fabs(residual.y) <= accept;
}

template <typename T>
SLS_HOST_DEVICE inline Vec2T<T> normalized_to_pixel(const CameraIntrinsicsT<T>& c, Vec2T<T> distorted) {
  return {c.fx * distorted.x + c.cx, c.fy * distorted.y + c.cy};
}

template <typename T>
SLS_HOST_DEVICE inline Vec2T<T> pixel_to_normalized(const CameraIntrinsicsT<T>& c, Vec2T<T> pixel) {
  return {(pixel.x - c.cx) / c.fx, (pixel.y - c.cy) / c.fy};
}

// Projects a camera-frame point to a pixel. Returns false for points at or behind the
// camera centre (z <= 0); the pixel may still lie outside the image.
template <typename T>
SLS_HOST_DEVICE inline bool project(const CameraIntrinsicsT<T>& c, Vec3T<T> point_camera, Vec2T<T>* pixel) {
  if (!(point_camera.z > T(0))) return false;
  const Vec2T<T> n = {point_camera.x / point_camera.z, point_camera.y / point_camera.z};
  *pixel = normalized_to_pixel(c, distort_normalized(c, n));
  return true;
}

// The viewing ray through a pixel, as a camera-frame direction with z = 1 (so multiplying
// by a depth along the optical axis gives the 3D point). Returns false when undistortion
// does not converge.
template <typename T>
SLS_HOST_DEVICE inline bool unproject(const CameraIntrinsicsT<T>& c, Vec2T<T> pixel, Vec3T<T>* ray_camera) {
  Vec2T<T> n;
  const bool ok = undistort_normalized(c, pixel_to_normalized(c, pixel), &n);
  *ray_camera = {n.x, n.y, T(1)};
  return ok;
}

// Where a distorted pixel would land in the ideal (distortion-free) pinhole image with the
// same fx fy cx cy: the undistort step of image rectification.
template <typename T>
SLS_HOST_DEVICE inline bool undistort_pixel(const CameraIntrinsicsT<T>& c, Vec2T<T> pixel, Vec2T<T>* ideal_pixel) {
  Vec2T<T> n;
  const bool ok = undistort_normalized(c, pixel_to_normalized(c, pixel), &n);
  *ideal_pixel = normalized_to_pixel(c, n);
  return ok;
}

}  // namespace sls
