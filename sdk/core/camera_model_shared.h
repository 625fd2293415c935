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

// d(r·radial(r²))/dr at t = r²: positive while the radial distortion is still unfolding.
template <typename T>
SLS_HOST_DEVICE inline T radial_slope(const CameraIntrinsicsT<T>& c, T t) {
  return T(1) + t * (T(3) * c.k1 + t * (T(5) * c.k2 + t * T(7) * c.k3));
}

// True when r -> r·radial(r²) increases on all of [0, sqrt(r2)], i.e. the undistorted point
// lies inside the lens's first fold. Beyond it Newton can converge to a "preimage" that is
// physically meaningless (e.g. mirrored through the centre where radial < 0). The slope is
// a cubic in t = r², so its minimum on [0, r2] is at an end or at a root of its derivative
// 3k1 + 10k2 t + 21k3 t². Tangential terms are ignored: they are orders of magnitude smaller.
template <typename T>
SLS_HOST_DEVICE inline bool inside_first_fold(const CameraIntrinsicsT<T>& c, T r2) {
  if (!(radial_slope(c, r2) > T(0))) return false;
  const T a = T(21) * c.k3, b = T(10) * c.k2, c0 = T(3) * c.k1;
  T roots[2];
  int count = 0;
  if (a == T(0)) {
    if (b != T(0)) roots[count++] = -c0 / b;
  } else {
    const T discriminant = b * b - T(4) * a * c0;
    if (discriminant >= T(0)) {
      const T root = std::sqrt(discriminant);
      roots[count++] = (-b + root) / (T(2) * a);
      roots[count++] = (-b - root) / (T(2) * a);
    }
  }
  for (int i = 0; i < count; ++i) {
    if (roots[i] > T(0) && roots[i] < r2 && !(radial_slope(c, roots[i]) > T(0))) return false;
  }
  return true;
}

// Inverts the distortion by Newton's method, starting at the distorted point. Returns false
// when it does not converge, or converges beyond the lens's first fold (far outside the
// calibrated field, where the polynomial folds back and a distorted point has no physical
// preimage).
template <typename T>
SLS_HOST_DEVICE inline bool undistort_normalized(const CameraIntrinsicsT<T>& c, Vec2T<T> distorted,
                                                 Vec2T<T>* undistorted) {
  Vec2T<T> n = distorted;
  if (!c.has_distortion()) {
    *undistorted = n;
    return true;
  }
  // Converged when the residual is a few ulps of the coordinate (1e-15 for double, 2e-7 for
  // float at unit scale; relative for larger coordinates so wide lenses converge too).
  const T scale = T(1) + std::fabs(distorted.x) + std::fabs(distorted.y);
  const T tolerance = (sizeof(T) >= 8 ? T(1e-15) : T(2e-7)) * scale;
  constexpr bool kIsDouble = sizeof(T) >= 8;
  for (int iteration = 0; iteration < 20; ++iteration) {
    const Vec2T<T> residual = distort_normalized(c, n) - distorted;
    const bool converged = std::fabs(residual.x) <= tolerance && std::fabs(residual.y) <= tolerance;
    if (converged && kIsDouble) {
      *undistorted = n;
      return inside_first_fold(c, n.x * n.x + n.y * n.y);
    }
    T j[4];
    distortion_jacobian(c, n, j);
    const T det = j[0] * j[3] - j[1] * j[2];
    if (!(std::fabs(det) > T(1e-12))) break;
    n.x -= (j[3] * residual.x - j[1] * residual.y) / det;
    n.y -= (-j[2] * residual.x + j[0] * residual.y) / det;
    // In float the tolerance sits just above the rounding noise, so a point that meets it
    // may still be ~2e-7 off (1e-3 px at f = 5000 px): one more, quadratically convergent,
    // step brings it down to the noise floor for the price of one Jacobian.
    if (converged) {
      *undistorted = n;
      return inside_first_fold(c, n.x * n.x + n.y * n.y);
    }
  }
  const Vec2T<T> residual = distort_normalized(c, n) - distorted;
  *undistorted = n;
  // Float iterations can stall a few ulps above the tolerance: accept 2e-6 normalized units
  // (0.01 px at f = 5000 px) for float, 1e-12 for double.
  const T accept = (sizeof(T) >= 8 ? T(1e-12) : T(2e-6)) * scale;
  return std::fabs(residual.x) <= accept && std::fabs(residual.y) <= accept &&
         inside_first_fold(c, n.x * n.x + n.y * n.y);
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
  // One reciprocal and two products, not two divisions: an IEEE division is a dozen
  // instructions on a GPU, and the integration and ICP kernels project every voxel or pixel.
  const T inverse_z = T(1) / point_camera.z;
  const Vec2T<T> n = {point_camera.x * inverse_z, point_camera.y * inverse_z};
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
