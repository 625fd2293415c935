// How a camera pixel sees a varying albedo: the chessboard's albedo integrated exactly over a
// pixel's footprint on the sheet (each dark square clipped to it, its area taken), and which
// scenes need that at all. Shared by the CPU and CUDA renderers (render_shared.h); split from
// scene_shared.h, which holds the scenes' geometry and point albedo.
#pragma once

#include <cmath>

#include "drivers/sim/scene_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::sim {

namespace detail {

// Clips the convex polygon in[0 .. n-1] to the half-plane coordinate `axis` (0: x, 1: y)
// <= bound (below) or >= bound (!below); returns the vertex count of out (at most n + 1).
template <typename T>
SLS_HOST_DEVICE inline int clip_polygon(const Vec2T<T>* in, int n, int axis, T bound, bool below, Vec2T<T>* out) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const Vec2T<T> p = in[i];
    const Vec2T<T> q = in[i + 1 == n ? 0 : i + 1];
    const T dp = (axis == 0 ? p.x : p.y) - bound;
    const T dq = (axis == 0 ? q.x : q.y) - bound;
    const bool p_in = below ? dp <= T(0) : dp >= T(0);
    const bool q_in = below ? dq <= T(0) : dq >= T(0);
    if (p_in) out[m++] = p;
    if (p_in != q_in) {
      const T t = dp / (dp - dq);
      Vec2T<T> r{p.x + t * (q.x - p.x), p.y + t * (q.y - p.y)};
      if (axis == 0) r.x = bound; else r.y = bound;  // exactly on the line
      out[m++] = r;
    }
  }
  return m;
}

// Area and first moments (the integrals of x and y) of a simple polygon, signed by its
// orientation (counter-clockwise positive).
template <typename T>
SLS_HOST_DEVICE inline void polygon_moments(const Vec2T<T>* v, int n, T* area, T* moment_x, T* moment_y) {
  T a = T(0), mx = T(0), my = T(0);
  for (int i = 0; i < n; ++i) {
    const Vec2T<T> p = v[i];
    const Vec2T<T> q = v[i + 1 == n ? 0 : i + 1];
    const T cross = p.x * q.y - q.x * p.y;
    a += cross;
    mx += (p.x + q.x) * cross;
    my += (p.y + q.y) * cross;
  }
  *area = a / T(2);
  *moment_x = mx / T(6);
  *moment_y = my / T(6);
}

// Adds the area and first moments of the part of the rectangle [x0, x1] x [y0, y1] inside
// the convex quadrilateral quad[0..3].
template <typename T>
SLS_HOST_DEVICE inline void add_rectangle_moments(const Vec2T<T> quad[4], T x0, T x1, T y0, T y1, T* area,
                                                  T* moment_x, T* moment_y) {
  Vec2T<T> a[8], b[8];
  int n = clip_polygon(quad, 4, 0, x0, false, a);
  n = clip_polygon(a, n, 0, x1, true, b);
  n = clip_polygon(b, n, 1, y0, false, a);
  n = clip_polygon(a, n, 1, y1, true, b);
  if (n < 3) return;
  T ca, cx, cy;
  polygon_moments(b, n, &ca, &cx, &cy);
  *area += ca;
  *moment_x += cx;
  *moment_y += cy;
}

}  // namespace detail

// The most squares chessboard_mean_albedo() walks (a pixel footprint larger than that is
// left to the caller).
constexpr int kChessboardMaxFootprintSquares = 64;
// And the most ChArUco marker cells it walks.
constexpr int kChessboardMaxFootprintCells = 256;

// The albedo of the chessboard averaged over the convex quadrilateral q[0..3] of its sheet
// (vertices in order round it, sheet x and y): the exact area integral of the piecewise
// constant albedo (each dark square, and each dark cell of a ChArUco board's markers, clipped
// to the quadrilateral, its area taken), as a
// camera pixel integrates the board over its footprint. *centroid (optional): the
// albedo-weighted centroid, where the pixel's light comes from on average. Returns false
// (nothing written) for a degenerate quadrilateral or one over more than
// kChessboardMaxFootprintSquares squares (or kChessboardMaxFootprintCells marker cells).
template <typename T>
SLS_HOST_DEVICE inline bool chessboard_mean_albedo(const ChessboardT<T>& s, const Vec2T<T> q[4], T* albedo,
                                                   Vec2T<T>* centroid = nullptr) {
  // Square units relative to q[0]: square (i, j) spans [i − i0, i + 1 − i0] x [j − j0, ...],
  // i0 = the grid coordinate of q[0]; local coordinates keep the tiny areas' digits.
  const T inverse = T(1) / s.square;
  const T i0 = (q[0].x + T(0.5) * static_cast<T>(s.squares_x) * s.square) * inverse;
  const T j0 = (q[0].y + T(0.5) * static_cast<T>(s.squares_y) * s.square) * inverse;
  Vec2T<T> quad[4];
  T lo_x = T(0), hi_x = T(0), lo_y = T(0), hi_y = T(0);
  for (int k = 0; k < 4; ++k) {
    quad[k] = {(q[k].x - q[0].x) * inverse, (q[k].y - q[0].y) * inverse};
    lo_x = detail::min2(lo_x, quad[k].x);
    hi_x = detail::max2(hi_x, quad[k].x);
    lo_y = detail::min2(lo_y, quad[k].y);
    hi_y = detail::max2(hi_y, quad[k].y);
  }
  T area, mx, my;
  detail::polygon_moments(quad, 4, &area, &mx, &my);
  if (!(detail::abs(area) > T(1e-20))) return false;
  const int first_i = static_cast<int>(detail::max2(std::floor(i0 + lo_x), T(0)));
  const int last_i = static_cast<int>(detail::min2(std::floor(i0 + hi_x), static_cast<T>(s.squares_x - 1)));
  const int first_j = static_cast<int>(detail::max2(std::floor(j0 + lo_y), T(0)));
  const int last_j = static_cast<int>(detail::min2(std::floor(j0 + hi_y), static_cast<T>(s.squares_y - 1)));
  if ((last_i - first_i + 1) * (last_j - first_j + 1) > kChessboardMaxFootprintSquares) return false;
  T dark_area = T(0), dark_mx = T(0), dark_my = T(0);
  // ChArUco: a marker's cells in square units (the marker centred in its square).
  const T cells = static_cast<T>(s.marker_cells);
  const T cell = s.is_charuco() ? s.marker * inverse / cells : T(0);
  const T offset = s.is_charuco() ? T(0.5) * (T(1) - s.marker * inverse) : T(0);
  int cells_walked = 0;
  for (int j = first_j; j <= last_j; ++j) {
    for (int i = first_i; i <= last_i; ++i) {
      const T x0 = static_cast<T>(i) - i0, y0 = static_cast<T>(j) - j0;
      if (s.square_dark(i, j)) {
        detail::add_rectangle_moments(quad, x0, static_cast<T>(i + 1) - i0, y0, static_cast<T>(j + 1) - j0, &dark_area,
                                      &dark_mx, &dark_my);
        continue;
      }
      if (!s.is_charuco()) continue;  // light (chessboard_albedo)
      // The marker's cells the quad's bounding box reaches, each dark one clipped to the quad.
      const T mx0 = x0 + offset, my0 = y0 + offset;
      const int first_c = detail::max2(0, static_cast<int>(std::floor((lo_x - mx0) / cell)));
      const int last_c = detail::min2(s.marker_cells - 1, static_cast<int>(std::floor((hi_x - mx0) / cell)));
      const int first_r = detail::max2(0, static_cast<int>(std::floor((lo_y - my0) / cell)));
      const int last_r = detail::min2(s.marker_cells - 1, static_cast<int>(std::floor((hi_y - my0) / cell)));
      for (int r = first_r; r <= last_r; ++r) {
        for (int c = first_c; c <= last_c; ++c) {
          if (++cells_walked > kChessboardMaxFootprintCells) return false;
          if (!s.cell_dark(i, j, r, c)) continue;
          const T cx0 = mx0 + static_cast<T>(c) * cell, cy0 = my0 + static_cast<T>(r) * cell;
          detail::add_rectangle_moments(quad, cx0, cx0 + cell, cy0, cy0 + cell, &dark_area, &dark_mx, &dark_my);
        }
      }
    }
  }
  // Light everywhere (margin included), dark where the dark squares (and marker cells) are.
  const T light = s.albedo_light, dark = s.albedo_dark;
  const T weight = light * area + (dark - light) * dark_area;
  *albedo = weight / area;
  if (centroid != nullptr) {
    if (detail::abs(weight) > T(0)) {
      const T cx = (light * mx + (dark - light) * dark_mx) / weight;
      const T cy = (light * my + (dark - light) * dark_my) / weight;
      *centroid = {q[0].x + cx * s.square, q[0].y + cy * s.square};
    } else {
      *centroid = {q[0].x + mx / area * s.square, q[0].y + my / area * s.square};
    }
  }
  return true;
}

// Whether the albedo varies over the surface — the chessboard's squares, a solid texture of
// non-zero amplitude — so that a camera pixel must integrate it over its footprint; a
// uniform albedo is the same at every point of the footprint.
template <typename T>
SLS_HOST_DEVICE inline bool albedo_varies(const SceneShapeT<T>& s) {
  switch (s.kind) {
    case SceneKind::kPlane:
    case SceneKind::kSphere: return false;
    case SceneKind::kChessboard: return s.chessboard.albedo_dark != s.chessboard.albedo_light;
    case SceneKind::kKnurledScrew: return s.screw.albedo.amplitude != T(0) && s.screw.albedo.period > T(0);
    case SceneKind::kKnurledKnob: return s.knob.albedo.amplitude != T(0) && s.knob.albedo.period > T(0);
  }
  return false;
}

}  // namespace sls::sim
