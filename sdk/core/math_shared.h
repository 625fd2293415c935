// Small fixed-size vectors and a rigid transform that compile on host and device.
// Eigen stays on the host side (sdk/core/pose.h converts); kernels and *_shared.h code use
// these plain structs (DESIGN.md section 6).
#pragma once

#include <cmath>

#include "sdk/core/host_device.h"

namespace sls {

template <typename T>
struct Vec2T {
  T x, y;
};

template <typename T>
struct Vec3T {
  T x, y, z;
};

template <typename T> SLS_HOST_DEVICE inline Vec2T<T> operator+(Vec2T<T> a, Vec2T<T> b) { return {a.x + b.x, a.y + b.y}; }
template <typename T> SLS_HOST_DEVICE inline Vec2T<T> operator-(Vec2T<T> a, Vec2T<T> b) { return {a.x - b.x, a.y - b.y}; }
template <typename T> SLS_HOST_DEVICE inline Vec2T<T> operator*(T s, Vec2T<T> a) { return {s * a.x, s * a.y}; }
template <typename T> SLS_HOST_DEVICE inline T dot(Vec2T<T> a, Vec2T<T> b) { return a.x * b.x + a.y * b.y; }

template <typename T> SLS_HOST_DEVICE inline Vec3T<T> operator+(Vec3T<T> a, Vec3T<T> b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <typename T> SLS_HOST_DEVICE inline Vec3T<T> operator-(Vec3T<T> a, Vec3T<T> b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <typename T> SLS_HOST_DEVICE inline Vec3T<T> operator-(Vec3T<T> a) { return {-a.x, -a.y, -a.z}; }
template <typename T> SLS_HOST_DEVICE inline Vec3T<T> operator*(T s, Vec3T<T> a) { return {s * a.x, s * a.y, s * a.z}; }
template <typename T> SLS_HOST_DEVICE inline T dot(Vec3T<T> a, Vec3T<T> b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <typename T> SLS_HOST_DEVICE inline Vec3T<T> cross(Vec3T<T> a, Vec3T<T> b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <typename T> SLS_HOST_DEVICE inline T norm(Vec3T<T> a) { return std::sqrt(dot(a, a)); }

// Row-major 3x3 matrix.
template <typename T>
struct Mat3T {
  T m[9];
  SLS_HOST_DEVICE T operator()(int row, int col) const { return m[row * 3 + col]; }
};

template <typename T> SLS_HOST_DEVICE inline Vec3T<T> operator*(const Mat3T<T>& a, Vec3T<T> v) {
  return {a.m[0] * v.x + a.m[1] * v.y + a.m[2] * v.z,
          a.m[3] * v.x + a.m[4] * v.y + a.m[5] * v.z,
          a.m[6] * v.x + a.m[7] * v.y + a.m[8] * v.z};
}
template <typename T> SLS_HOST_DEVICE inline Mat3T<T> transpose(const Mat3T<T>& a) {
  return {{a.m[0], a.m[3], a.m[6], a.m[1], a.m[4], a.m[7], a.m[2], a.m[5], a.m[8]}};
}

// Rigid transform T_a_b: maps points in frame b to frame a, p_a = R * p_b + t.
template <typename T>
struct Rigid3T {
  Mat3T<T> rotation;
  Vec3T<T> translation;
};

template <typename T> SLS_HOST_DEVICE inline Vec3T<T> transform_point(const Rigid3T<T>& T_a_b, Vec3T<T> p_b) {
  return T_a_b.rotation * p_b + T_a_b.translation;
}
template <typename T> SLS_HOST_DEVICE inline Vec3T<T> rotate_vector(const Rigid3T<T>& T_a_b, Vec3T<T> v_b) {
  return T_a_b.rotation * v_b;
}
template <typename T> SLS_HOST_DEVICE inline Rigid3T<T> inverse(const Rigid3T<T>& T_a_b) {
  const Mat3T<T> rt = transpose(T_a_b.rotation);
  return {rt, -(rt * T_a_b.translation)};
}

using Vec2f = Vec2T<float>;
using Vec2d = Vec2T<double>;
using Vec3f = Vec3T<float>;
using Vec3d = Vec3T<double>;
using Rigid3f = Rigid3T<float>;
using Rigid3d = Rigid3T<double>;

}  // namespace sls
