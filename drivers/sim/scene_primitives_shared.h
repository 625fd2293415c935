// The simulator's scene primitives, shared by the CPU and CUDA renderers (scene_shared.h has
// the conventions): rays and hits, the albedo texture, and the plane, sphere and chessboard
// (or ChArUco) sheet with their intersections.
#pragma once

#include <cmath>

#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::sim {

enum class SceneKind : int {
  kPlane = 0,
  kSphere = 1,
  kChessboard = 2,
  kKnurledScrew = 3,
  kKnurledKnob = 4,
};

// Which part of a surface a hit lies on. Sheets, spheres and the knurled side are kPartSide.
enum SurfacePart : int {
  kPartSide = 0,
  kPartBottomCap = 1,  // knurled objects: the flat cap at z = 0 (outward normal -z)
  kPartTopCap = 2,     // knurled objects: the flat cap at z = height (outward normal +z)
};

template <typename T>
struct RayT {
  Vec3T<T> origin;
  Vec3T<T> direction;  // unit length
};

template <typename T>
struct HitT {
  T t = T(0);
  Vec3T<T> point{T(0), T(0), T(0)};
  Vec3T<T> normal{T(0), T(0), T(0)};  // unit, outward (sheets: always +z)
  T albedo = T(0);                    // in [0, 1]
  int part = kPartSide;               // SurfacePart
  // Finer location, -1 on caps and smooth surfaces. Knurled objects: the cross-section's
  // vertices are numbered 0..2N-1 by angle, vertex 2k = ridge k, vertex 2k+1 = root k+1/2;
  // screw flank j joins vertices j and j+1, knob half-tooth j spans u in [j/2, (j+1)/2] (the
  // same flank). Chessboard: square index row * squares_x + column, -1 on the margin.
  int feature = -1;
};

using Ray = RayT<double>;
using Hit = HitT<double>;

namespace detail {

template <typename T> SLS_HOST_DEVICE constexpr T pi() { return T(3.14159265358979323846); }
// Stands in for infinity: numeric_limits is not callable from device code without
// --expt-relaxed-constexpr, and 1e30 m is far beyond any scene.
template <typename T> SLS_HOST_DEVICE constexpr T huge() { return T(1e30); }
template <typename T> SLS_HOST_DEVICE inline T min2(T a, T b) { return a < b ? a : b; }
template <typename T> SLS_HOST_DEVICE inline T max2(T a, T b) { return a > b ? a : b; }
template <typename T> SLS_HOST_DEVICE inline T clamp(T v, T lo, T hi) { return v < lo ? lo : (v > hi ? hi : v); }
template <typename T> SLS_HOST_DEVICE inline T sqr(T v) { return v * v; }
template <typename T> SLS_HOST_DEVICE inline T abs(T v) { return v < T(0) ? -v : v; }

// Tolerances of the iterative (knob) intersection and of interval padding. Functions, not
// static members, so device code can use them without odr-use.
template <typename T> struct Precision;
template <> struct Precision<double> {
  // The march switches from certified Lipschitz steps to bracketing below this value of the
  // implicit function, and probes at most probe() ahead for a sign change.
  SLS_HOST_DEVICE static constexpr double near() { return 1e-9; }
  SLS_HOST_DEVICE static constexpr double probe() { return 1e-6; }
  // Final bracket width in t (the brief asks |dt| < 1e-12 m).
  SLS_HOST_DEVICE static constexpr double t_tolerance() { return 1e-13; }
  // Relative padding of clip intervals against rounding of the bounding quadratics.
  SLS_HOST_DEVICE static constexpr double relative_pad() { return 1e-14; }
  SLS_HOST_DEVICE static constexpr int max_steps() { return 4000; }
};
template <> struct Precision<float> {
  SLS_HOST_DEVICE static constexpr float near() { return 2e-8f; }
  SLS_HOST_DEVICE static constexpr float probe() { return 2e-6f; }
  // The march runs in a parameter local to the bounding-cylinder entry, so its resolution
  // is far finer than float's ulp at 0.1 m; the entry point's own rounding dominates.
  SLS_HOST_DEVICE static constexpr float t_tolerance() { return 1e-9f; }
  SLS_HOST_DEVICE static constexpr float relative_pad() { return 2e-7f; }
  SLS_HOST_DEVICE static constexpr int max_steps() { return 4000; }
};

}  // namespace detail

// ---------------------------------------------------------------------------------------
// Albedo: a base value plus an optional smooth solid texture
//   albedo(p) = clamp(base + amplitude * cos(w x) cos(w y) cos(w z), 0, 1),  w = 2 pi / period,
// a 3D texture so it is continuous across the parts of a solid; amplitude 0 = uniform.
template <typename T>
struct AlbedoT {
  T base = T(0.6);
  T amplitude = T(0);
  T period = T(0.001);

  template <typename U>
  SLS_HOST_DEVICE AlbedoT<U> cast() const {
    return {static_cast<U>(base), static_cast<U>(amplitude), static_cast<U>(period)};
  }
};

template <typename T>
SLS_HOST_DEVICE inline T albedo_at(const AlbedoT<T>& a, Vec3T<T> p) {
  if (a.amplitude == T(0) || !(a.period > T(0))) return detail::clamp(a.base, T(0), T(1));
  const T w = T(2) * detail::pi<T>() / a.period;
  return detail::clamp(a.base + a.amplitude * std::cos(w * p.x) * std::cos(w * p.y) * std::cos(w * p.z),
                       T(0), T(1));
}

// ---------------------------------------------------------------------------------------
// Plane: the sheet z = 0, normal +z; unbounded when a half extent is <= 0, else the
// rectangle |x| <= half_extent_x, |y| <= half_extent_y.
template <typename T>
struct PlaneT {
  T half_extent_x = T(0);
  T half_extent_y = T(0);
  T albedo = T(0.6);

  template <typename U>
  SLS_HOST_DEVICE PlaneT<U> cast() const {
    return {static_cast<U>(half_extent_x), static_cast<U>(half_extent_y), static_cast<U>(albedo)};
  }
};

// Shared by plane and chessboard: the sheet z = 0 clipped to a rectangle (or not).
template <typename T>
SLS_HOST_DEVICE inline bool intersect_sheet(T half_x, T half_y, const RayT<T>& ray, T t_min, T t_max, T* t_out,
                                            Vec3T<T>* point) {
  if (ray.direction.z == T(0)) return false;
  const T t = -ray.origin.z / ray.direction.z;
  if (!(t > t_min && t < t_max)) return false;
  Vec3T<T> p = ray.origin + t * ray.direction;
  p.z = T(0);  // exactly on the sheet
  if (half_x > T(0) && half_y > T(0) && (detail::abs(p.x) > half_x || detail::abs(p.y) > half_y)) return false;
  *t_out = t;
  *point = p;
  return true;
}

template <typename T>
SLS_HOST_DEVICE inline bool intersect_plane(const PlaneT<T>& s, const RayT<T>& ray, T t_min, T t_max, HitT<T>* hit) {
  T t;
  Vec3T<T> p;
  if (!intersect_sheet(s.half_extent_x, s.half_extent_y, ray, t_min, t_max, &t, &p)) return false;
  hit->t = t;
  hit->point = p;
  hit->normal = {T(0), T(0), T(1)};
  hit->albedo = detail::clamp(s.albedo, T(0), T(1));
  hit->part = kPartSide;
  hit->feature = -1;
  return true;
}

// ---------------------------------------------------------------------------------------
// Sphere.
template <typename T>
struct SphereT {
  Vec3T<T> center{T(0), T(0), T(0)};
  T radius = T(0.01);
  T albedo = T(0.6);

  template <typename U>
  SLS_HOST_DEVICE SphereT<U> cast() const {
    return {{static_cast<U>(center.x), static_cast<U>(center.y), static_cast<U>(center.z)},
            static_cast<U>(radius), static_cast<U>(albedo)};
  }
};

template <typename T>
SLS_HOST_DEVICE inline bool intersect_sphere(const SphereT<T>& s, const RayT<T>& ray, T t_min, T t_max, HitT<T>* hit) {
  // Relative to the centre, with the numerically stable root pair (no cancellation).
  const Vec3T<T> oc = ray.origin - s.center;
  const T a = dot(ray.direction, ray.direction);
  const T b = dot(oc, ray.direction);
  // c = |oc|^2 - r^2 factored as (|oc| - r)(|oc| + r) keeps digits when the origin is far.
  const T len = norm(oc);
  const T c = (len - s.radius) * (len + s.radius);
  // Discriminant through the perpendicular distance, which does not cancel: b^2 - a c =
  // a (r^2 - |oc - (b/a) d|^2).
  const Vec3T<T> perp = oc - (b / a) * ray.direction;
  const T disc = a * (s.radius - norm(perp)) * (s.radius + norm(perp));
  if (disc < T(0)) return false;
  const T q = -(b + (b >= T(0) ? T(1) : T(-1)) * std::sqrt(disc));
  T t0 = q / a;
  T t1 = q != T(0) ? c / q : t0;
  if (t0 > t1) {
    const T tmp = t0;
    t0 = t1;
    t1 = tmp;
  }
  T t = t0;
  if (!(t > t_min && t < t_max)) {
    t = t1;
    if (!(t > t_min && t < t_max)) return false;
  }
  hit->t = t;
  hit->point = ray.origin + t * ray.direction;
  const Vec3T<T> n = hit->point - s.center;
  hit->normal = (T(1) / norm(n)) * n;
  hit->albedo = detail::clamp(s.albedo, T(0), T(1));
  hit->part = kPartSide;
  hit->feature = -1;
  return true;
}

// ---------------------------------------------------------------------------------------
// Chessboard: a sheet z = 0 (normal +z) with squares_x * squares_y squares of side `square`
// centred on the origin, square (column i, row j) spanning
//   x in [-squares_x*square/2 + i*square, ... + square], y likewise with j;
// square (0, 0) and every square with i + j even is dark. A light margin of width `margin`
// surrounds the squares; outside the plate there is nothing.
//
// ChArUco (marker_cells > 0): which squares are dark is given per square (dark_squares), and
// each light square holds a marker of side `marker` centred in it: a grid of marker_cells x
// marker_cells cells (the marker's bits inside a one-cell dark border), cell (row r, column c)
// dark when bit r * marker_cells + c of marker_dark[square] is set, r along +y and c along +x
// of this sheet frame. The table is plain bits (the host fills it from OpenCV's dictionary in
// calib/, drivers/sim never includes OpenCV), sized for the kernels' by-value parameters.
constexpr int kCharucoMaxSquares = 192;  // e.g. 16 x 12
constexpr int kCharucoMaxCells = 8;      // markers of up to 6 x 6 bits (64 cells in a word)

template <typename T>
struct ChessboardT {
  int squares_x = 10;
  int squares_y = 8;
  T square = T(0.0012);
  T margin = T(0.0006);
  T albedo_dark = T(0.1);
  T albedo_light = T(0.9);
  // ChArUco only (marker_cells 0: a plain chessboard).
  int marker_cells = 0;
  T marker = T(0);
  unsigned int dark_squares[kCharucoMaxSquares / 32] = {};     // bit (square % 32) of word square / 32
  unsigned long long marker_dark[kCharucoMaxSquares] = {};    // per square, its cells (above)

  template <typename U>
  SLS_HOST_DEVICE ChessboardT<U> cast() const {
    ChessboardT<U> o;
    o.squares_x = squares_x;
    o.squares_y = squares_y;
    o.square = static_cast<U>(square);
    o.margin = static_cast<U>(margin);
    o.albedo_dark = static_cast<U>(albedo_dark);
    o.albedo_light = static_cast<U>(albedo_light);
    o.marker_cells = marker_cells;
    o.marker = static_cast<U>(marker);
    for (int k = 0; k < kCharucoMaxSquares / 32; ++k) o.dark_squares[k] = dark_squares[k];
    for (int k = 0; k < kCharucoMaxSquares; ++k) o.marker_dark[k] = marker_dark[k];
    return o;
  }
  SLS_HOST_DEVICE T half_width() const { return T(0.5) * static_cast<T>(squares_x) * square + margin; }
  SLS_HOST_DEVICE T half_height() const { return T(0.5) * static_cast<T>(squares_y) * square + margin; }
  SLS_HOST_DEVICE bool is_charuco() const { return marker_cells > 0; }
  // Whether square (i, j) is dark as a whole (a chessboard's parity, a ChArUco board's table).
  SLS_HOST_DEVICE bool square_dark(int i, int j) const {
    if (!is_charuco()) return (i + j) % 2 == 0;
    const int k = j * squares_x + i;
    return ((dark_squares[k / 32] >> (k % 32)) & 1u) != 0u;
  }
  // Whether cell (r, c) of square (i, j)'s marker is dark (a light square's).
  SLS_HOST_DEVICE bool cell_dark(int i, int j, int r, int c) const {
    return ((marker_dark[j * squares_x + i] >> (r * marker_cells + c)) & 1ull) != 0ull;
  }
};

// Square index (row * squares_x + column) under (x, y), or -1 on the margin.
template <typename T>
SLS_HOST_DEVICE inline int chessboard_square(const ChessboardT<T>& s, T x, T y) {
  const T u = (x + T(0.5) * static_cast<T>(s.squares_x) * s.square) / s.square;
  const T v = (y + T(0.5) * static_cast<T>(s.squares_y) * s.square) / s.square;
  if (!(u >= T(0) && v >= T(0) && u < static_cast<T>(s.squares_x) && v < static_cast<T>(s.squares_y))) return -1;
  const int i = static_cast<int>(std::floor(u));
  const int j = static_cast<int>(std::floor(v));
  return j * s.squares_x + i;
}

template <typename T>
SLS_HOST_DEVICE inline T chessboard_albedo(const ChessboardT<T>& s, T x, T y) {
  const int square = chessboard_square(s, x, y);
  if (square < 0) return s.albedo_light;
  const int i = square % s.squares_x;
  const int j = square / s.squares_x;
  if (s.square_dark(i, j)) return s.albedo_dark;
  if (!s.is_charuco()) return s.albedo_light;
  // The marker's cell under (x, y), in cells from the marker's corner of least x and y.
  const T offset = T(0.5) * (s.square - s.marker);
  const T cell = s.marker / static_cast<T>(s.marker_cells);
  const T mx = (x + T(0.5) * static_cast<T>(s.squares_x) * s.square - static_cast<T>(i) * s.square - offset) / cell;
  const T my = (y + T(0.5) * static_cast<T>(s.squares_y) * s.square - static_cast<T>(j) * s.square - offset) / cell;
  const T n = static_cast<T>(s.marker_cells);
  if (!(mx >= T(0) && my >= T(0) && mx < n && my < n)) return s.albedo_light;
  return s.cell_dark(i, j, static_cast<int>(std::floor(my)), static_cast<int>(std::floor(mx))) ? s.albedo_dark
                                                                                               : s.albedo_light;
}

template <typename T>
SLS_HOST_DEVICE inline bool intersect_chessboard(const ChessboardT<T>& s, const RayT<T>& ray, T t_min, T t_max,
                                                 HitT<T>* hit) {
  T t;
  Vec3T<T> p;
  if (!intersect_sheet(s.half_width(), s.half_height(), ray, t_min, t_max, &t, &p)) return false;
  hit->t = t;
  hit->point = p;
  hit->normal = {T(0), T(0), T(1)};
  hit->feature = chessboard_square(s, p.x, p.y);
  hit->albedo = chessboard_albedo(s, p.x, p.y);
  hit->part = kPartSide;
  return true;
}

}  // namespace sls::sim
