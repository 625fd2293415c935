// The knurled objects of the simulator, shared by the CPU and CUDA renderers (scene_shared.h
// has the conventions): the knurled head screw (a prism over a star polygon, exact distance
// and intersection) and the knurled knob (a wave knurl, certified marching).
#pragma once

#include <cmath>

#include "drivers/sim/scene_primitives_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::sim {

// ---------------------------------------------------------------------------------------
// Shared by the knurled objects: clips a ray to the solid cylinder rho <= radius,
// 0 <= z <= height and to (t_min, t_max). Returns false when nothing is left; else [lo, hi]
// and the ray parameters of the two cap planes (huge() when the ray is horizontal).
template <typename T>
SLS_HOST_DEVICE inline bool clip_to_cylinder(T radius, T height, const RayT<T>& ray, T t_min, T t_max, T* lo,
                                             T* hi, T* t_cap_near, T* t_cap_far) {
  const Vec3T<T> o = ray.origin;
  const Vec3T<T> d = ray.direction;
  T z_lo = -detail::huge<T>(), z_hi = detail::huge<T>();
  if (d.z != T(0)) {
    const T ta = -o.z / d.z;
    const T tb = (height - o.z) / d.z;
    z_lo = detail::min2(ta, tb);
    z_hi = detail::max2(ta, tb);
  } else if (o.z < T(0) || o.z > height) {
    return false;
  }
  *t_cap_near = d.z != T(0) ? z_lo : detail::huge<T>();
  *t_cap_far = d.z != T(0) ? z_hi : detail::huge<T>();
  T c_lo = -detail::huge<T>(), c_hi = detail::huge<T>();
  const T a = d.x * d.x + d.y * d.y;
  const T rho2 = o.x * o.x + o.y * o.y;
  if (a > T(0)) {
    const T b = o.x * d.x + o.y * d.y;
    // b^2 - a (rho^2 - R^2) through the perpendicular distance of the axis from the line:
    // no cancellation when the origin is far away.
    const T cross = o.x * d.y - o.y * d.x;
    const T disc = a * radius * radius - cross * cross;
    if (disc < T(0)) return false;
    const T sq = std::sqrt(disc);
    c_lo = (-b - sq) / a;
    c_hi = (-b + sq) / a;
  } else if (rho2 > radius * radius) {
    return false;
  }
  *lo = detail::max2(detail::max2(z_lo, c_lo), t_min);
  *hi = detail::min2(detail::min2(z_hi, c_hi), t_max);
  return *lo <= *hi;
}

// ---------------------------------------------------------------------------------------
// Knurled head screw: a prism over a star polygon. The cross-section has 2N vertices
// alternating ridge (radius ridge_radius, at angles 2 pi k / N) and root (root_radius, at
// 2 pi (k + 1/2) / N), extruded over 0 <= z <= height with flat caps. make_knurled_screw()
// fills the derived members; the host picks root_radius from the groove angle.
//
// "Sector k" is the wedge |theta - k Delta| <= Delta / 2 (Delta = 2 pi / N) around ridge k. In
// the sector's own frame (rotated by -k Delta) ridge k is P0 = (R, 0) and the roots are
// Q+- = (r cos(Delta/2), +-r sin(Delta/2)); flank '+' is P0-Q+, flank '-' is P0-Q-.
template <typename T>
struct KnurledScrewT {
  int teeth = 0;
  T ridge_radius = T(0);
  T root_radius = T(0);
  T height = T(0);
  AlbedoT<T> albedo;
  // Derived.
  T sector = T(0);                         // Delta
  T cos_sector = T(0), sin_sector = T(0);  // of Delta
  T cos_half = T(0), sin_half = T(0);      // of Delta / 2
  T root_x = T(0), root_y = T(0);          // Q+ in the sector frame
  T flank_nx = T(0), flank_ny = T(0);      // unit outward normal of flank '+' (flank '-': (nx, -ny))
  T flank_offset = T(0);                   // n . P0 (the same for both flanks)

  template <typename U>
  SLS_HOST_DEVICE KnurledScrewT<U> cast() const {
    KnurledScrewT<U> o;
    o.teeth = teeth;
    o.ridge_radius = static_cast<U>(ridge_radius);
    o.root_radius = static_cast<U>(root_radius);
    o.height = static_cast<U>(height);
    o.albedo = albedo.template cast<U>();
    o.sector = static_cast<U>(sector);
    o.cos_sector = static_cast<U>(cos_sector);
    o.sin_sector = static_cast<U>(sin_sector);
    o.cos_half = static_cast<U>(cos_half);
    o.sin_half = static_cast<U>(sin_half);
    o.root_x = static_cast<U>(root_x);
    o.root_y = static_cast<U>(root_y);
    o.flank_nx = static_cast<U>(flank_nx);
    o.flank_ny = static_cast<U>(flank_ny);
    o.flank_offset = static_cast<U>(flank_offset);
    return o;
  }
};

template <typename T>
SLS_HOST_DEVICE inline KnurledScrewT<T> make_knurled_screw(int teeth, T ridge_radius, T root_radius, T height,
                                                           AlbedoT<T> albedo) {
  KnurledScrewT<T> s;
  s.teeth = teeth;
  s.ridge_radius = ridge_radius;
  s.root_radius = root_radius;
  s.height = height;
  s.albedo = albedo;
  s.sector = T(2) * detail::pi<T>() / static_cast<T>(teeth);
  s.cos_sector = std::cos(s.sector);
  s.sin_sector = std::sin(s.sector);
  s.cos_half = std::cos(T(0.5) * s.sector);
  s.sin_half = std::sin(T(0.5) * s.sector);
  s.root_x = root_radius * s.cos_half;
  s.root_y = root_radius * s.sin_half;
  // Perpendicular to Q+ - P0 = (root_x - R, root_y), pointing away from the axis.
  const T nx = s.root_y;
  const T ny = ridge_radius - s.root_x;
  const T len = std::sqrt(nx * nx + ny * ny);
  s.flank_nx = nx / len;
  s.flank_ny = ny / len;
  s.flank_offset = s.flank_nx * ridge_radius;
  return s;
}

namespace detail {

// The sector k nearest to the angle of (x, y), and (x, y) rotated into its frame.
template <typename T>
SLS_HOST_DEVICE inline int screw_sector(const KnurledScrewT<T>& s, T x, T y, T* lx, T* ly, T* c, T* sn) {
  const T theta = std::atan2(y, x);
  const int k = static_cast<int>(std::floor(theta / s.sector + T(0.5)));
  const T phi = static_cast<T>(k) * s.sector;
  *c = std::cos(phi);
  *sn = std::sin(phi);
  *lx = *c * x + *sn * y;
  *ly = -*sn * x + *c * y;
  return k;
}

template <typename T>
SLS_HOST_DEVICE inline int wrap_index(int i, int n) {
  const int m = i % n;
  return m < 0 ? m + n : m;
}

// Squared distance from (px, py) to the segment (ax, ay)-(bx, by).
template <typename T>
SLS_HOST_DEVICE inline T segment_distance2(T px, T py, T ax, T ay, T bx, T by) {
  const T ex = bx - ax, ey = by - ay;
  const T wx = px - ax, wy = py - ay;
  const T u = clamp((wx * ex + wy * ey) / (ex * ex + ey * ey), T(0), T(1));
  return sqr(wx - u * ex) + sqr(wy - u * ey);
}

// Lower bound of the distance from a point at radius rho to any point at radius in
// [r_lo, r_hi] whose angle differs from the point's by at least delta (<= pi): the distance
// to the radial segment at exactly delta, which grows with delta.
template <typename T>
SLS_HOST_DEVICE inline T annulus_angle_bound(T rho, T r_lo, T r_hi, T delta) {
  if (delta >= pi<T>()) return rho + r_lo;
  const T c = std::cos(delta);
  const T r = clamp(rho * c, r_lo, r_hi);
  return std::sqrt(max2(rho * rho + r * r - T(2) * rho * r * c, T(0)));
}

}  // namespace detail

// Is (x, y) inside (or on) the star polygon?
template <typename T>
SLS_HOST_DEVICE inline bool knurled_screw_contains_2d(const KnurledScrewT<T>& s, T x, T y) {
  const T rho2 = x * x + y * y;
  if (rho2 <= s.root_radius * s.root_radius) return true;
  if (rho2 > s.ridge_radius * s.ridge_radius) return false;
  T lx, ly, c, sn;
  detail::screw_sector(s, x, y, &lx, &ly, &c, &sn);
  const T ny = ly >= T(0) ? s.flank_ny : -s.flank_ny;
  return s.flank_nx * lx + ny * ly <= s.flank_offset;
}

// Exact signed distance to the star polygon in the plane (negative inside). The polygon is
// invariant under the dihedral group generated by the mirrors through its ridges and roots;
// for a reflection group the image of any boundary point in the point's own chamber (half
// sector) is at least as close to the point, so the nearest flank is one of its own sector's.
template <typename T>
SLS_HOST_DEVICE inline T knurled_screw_polygon_distance(const KnurledScrewT<T>& s, T x, T y) {
  T lx, ly, c, sn;
  detail::screw_sector(s, x, y, &lx, &ly, &c, &sn);
  const T ny = ly >= T(0) ? s.flank_ny : -s.flank_ny;
  const bool inside = s.flank_nx * lx + ny * ly <= s.flank_offset;
  // Both flanks, so rounding at the mirror y = 0 cannot pick the wrong one.
  const T d2 = detail::min2(detail::segment_distance2(lx, ly, s.ridge_radius, T(0), s.root_x, s.root_y),
                            detail::segment_distance2(lx, ly, s.ridge_radius, T(0), s.root_x, -s.root_y));
  const T d = std::sqrt(d2);
  return inside ? -d : d;
}

// Exact signed distance of the prism (the standard extrusion formula).
template <typename T>
SLS_HOST_DEVICE inline T knurled_screw_sdf(const KnurledScrewT<T>& s, Vec3T<T> p) {
  const T wx = knurled_screw_polygon_distance(s, p.x, p.y);
  const T wy = detail::abs(p.z - T(0.5) * s.height) - T(0.5) * s.height;
  return detail::min2(detail::max2(wx, wy), T(0)) +
         std::sqrt(detail::sqr(detail::max2(wx, T(0))) + detail::sqr(detail::max2(wy, T(0))));
}

namespace detail {

// First crossing of the 2D ray with the polygon's flanks for t in [s0, s1] (and > t_min),
// walking the sectors in the order the ray sweeps them (the polar angle along a line is
// monotonic). Returns the hit's t or huge(); fills the outward normal and flank index.
template <typename T>
SLS_HOST_DEVICE inline T screw_walk(const KnurledScrewT<T>& s, const RayT<T>& ray, T s0, T s1, T t_min, T pad,
                                    T* nx_out, T* ny_out, int* flank_out) {
  const Vec3T<T> o = ray.origin;
  const Vec3T<T> d = ray.direction;
  const T px = o.x + s0 * d.x;
  const T py = o.y + s0 * d.y;
  const T q = std::atan2(py, px) / s.sector + T(0.5);
  int k = static_cast<int>(std::floor(q));
  const T frac = q - static_cast<T>(k);
  const T cr = o.x * d.y - o.y * d.x;
  int dir = cr > T(0) ? 1 : (cr < T(0) ? -1 : 0);
  int max_sectors = s.teeth + 2;
  bool through_axis = false;
  // Rounding may put the start one sector ahead; starting one behind costs a flank test.
  const T edge = T(1e-4);
  if (dir > 0 && frac < edge) k -= 1;
  if (dir < 0 && frac > T(1) - edge) k += 1;
  if (dir == 0) {
    // The line passes through the axis: constant angle; test the sector and its neighbours.
    dir = 1;
    k -= 1;
    max_sectors = 3;
    through_axis = true;
  }
  const T phi = static_cast<T>(k) * s.sector;
  T c = std::cos(phi), sn = std::sin(phi);
  T ox = c * o.x + sn * o.y, oy = -sn * o.x + c * o.y;
  T dx = c * d.x + sn * d.y, dy = -sn * d.x + c * d.y;
  const T lo = s0 - pad, hi = s1 + pad;
  const T sin_step = static_cast<T>(dir) * s.sin_sector;
  const T bx = s.cos_half, by = static_cast<T>(dir) * s.sin_half;  // the boundary the ray leaves by
  for (int i = 0; i < max_sectors; ++i) {
    T best = huge<T>();
    T bnx = T(0), bny = T(0);
    int side = 0;
    // Flank '+' (y in [0, root_y]) and flank '-' (y in [-root_y, 0]).
    for (int f = 0; f < 2; ++f) {
      const T fnx = s.flank_nx;
      const T fny = f == 0 ? s.flank_ny : -s.flank_ny;
      const T den = fnx * dx + fny * dy;
      if (den == T(0)) continue;
      const T t = (s.flank_offset - (fnx * ox + fny * oy)) / den;
      if (!(t >= lo && t <= hi && t > t_min && t < best)) continue;
      // The end tolerance `pad` keeps a ray that runs exactly into a root (down a groove's
      // bisector) from slipping between the two flanks by rounding.
      const T y = oy + t * dy;
      const bool on_segment = f == 0 ? (y >= -pad && y <= s.root_y + pad) : (y <= pad && y >= -s.root_y - pad);
      if (!on_segment) continue;
      best = t;
      bnx = fnx;
      bny = fny;
      side = f == 0 ? 0 : -1;  // flank '+' of sector k is flank 2k, flank '-' is 2k - 1
    }
    if (best < huge<T>()) {
      *nx_out = c * bnx - sn * bny;
      *ny_out = sn * bnx + c * bny;
      *flank_out = wrap_index<T>(2 * k + side, 2 * s.teeth);
      return best;
    }
    // Where the ray leaves this sector; stop when that is past s1 or never happens.
    if (!through_axis) {
      const T cross_d = bx * dy - by * dx;
      if (cross_d == T(0)) break;
      const T tb = -(bx * oy - by * ox) / cross_d;
      if (!(tb <= hi)) break;
      if ((ox + tb * dx) * bx + (oy + tb * dy) * by <= T(0)) break;
    }
    // Next sector: rotate the ray by -dir Delta and the frame by +dir Delta.
    k += dir;
    T nx = ox * s.cos_sector + oy * sin_step;
    oy = -ox * sin_step + oy * s.cos_sector;
    ox = nx;
    nx = dx * s.cos_sector + dy * sin_step;
    dy = -dx * sin_step + dy * s.cos_sector;
    dx = nx;
    const T nc = c * s.cos_sector - sn * sin_step;
    sn = sn * s.cos_sector + c * sin_step;
    c = nc;
  }
  return huge<T>();
}

}  // namespace detail

template <typename T>
SLS_HOST_DEVICE inline bool intersect_knurled_screw(const KnurledScrewT<T>& s, const RayT<T>& ray, T t_min, T t_max,
                                                    HitT<T>* hit) {
  T lo, hi, tc0, tc1;
  if (!clip_to_cylinder(s.ridge_radius, s.height, ray, t_min, t_max, &lo, &hi, &tc0, &tc1)) return false;
  const Vec3T<T> o = ray.origin;
  const Vec3T<T> d = ray.direction;
  // Caps first: a cap hit bounds the search along the side.
  T t_cap = detail::huge<T>();
  int cap_part = kPartSide;
  for (int i = 0; i < 2; ++i) {
    const T tc = i == 0 ? tc0 : tc1;
    if (!(tc > t_min && tc < t_max && tc < detail::huge<T>())) continue;
    const T x = o.x + tc * d.x, y = o.y + tc * d.y;
    if (knurled_screw_contains_2d(s, x, y)) {
      t_cap = tc;
      // The cap plane the ray meets at tc: z = 0 when it moves up there from below, etc.
      cap_part = ((i == 0) == (d.z > T(0))) ? kPartBottomCap : kPartTopCap;
      break;
    }
  }
  // Side: the flanks lie in the annulus root_radius <= rho <= ridge_radius; inside the root
  // circle the ray is inside the solid, so at most two intervals need a sector walk.
  T t_side = detail::huge<T>();
  T nx = T(0), ny = T(0);
  int flank = -1;
  const T a = d.x * d.x + d.y * d.y;
  const T end = detail::min2(hi, t_cap);
  if (a > T(0) && lo <= end) {
    const T pad = detail::Precision<T>::relative_pad() *
                  (detail::abs(lo) + detail::abs(end) + s.ridge_radius);
    const T b = o.x * d.x + o.y * d.y;
    const T cross = o.x * d.y - o.y * d.x;
    const T disc = a * s.root_radius * s.root_radius - cross * cross;
    if (disc > T(0)) {
      const T sq = std::sqrt(disc);
      const T ti0 = (-b - sq) / a, ti1 = (-b + sq) / a;
      const T e1 = detail::min2(end, ti0);
      if (lo <= e1) t_side = detail::screw_walk(s, ray, lo, e1, t_min, pad, &nx, &ny, &flank);
      const T s2 = detail::max2(lo, ti1);
      if (t_side >= detail::huge<T>() && s2 <= end) t_side = detail::screw_walk(s, ray, s2, end, t_min, pad, &nx, &ny, &flank);
    } else {
      t_side = detail::screw_walk(s, ray, lo, end, t_min, pad, &nx, &ny, &flank);
    }
  }
  if (t_side < detail::huge<T>() && t_side <= t_cap) {
    hit->t = t_side;
    hit->point = o + t_side * d;
    hit->normal = {nx, ny, T(0)};
    hit->part = kPartSide;
    hit->feature = flank;
  } else if (t_cap < detail::huge<T>()) {
    hit->t = t_cap;
    hit->point = o + t_cap * d;
    hit->point.z = cap_part == kPartBottomCap ? T(0) : s.height;
    hit->normal = {T(0), T(0), cap_part == kPartBottomCap ? T(-1) : T(1)};
    hit->part = cap_part;
    hit->feature = -1;
  } else {
    return false;
  }
  hit->albedo = albedo_at(s.albedo, hit->point);
  return true;
}

// ---------------------------------------------------------------------------------------
// Knurled knob: a wave knurl. The side is the implicit surface rho = R(theta, z) with
//   u(theta, z) = (N theta + A sin(omega z)) / (2 pi),   omega = 2 pi / wave_length,
//   R = outer_radius - depth * tri(u),   tri(u) = 2 |u - round(u)|  (0 on ridges, 1 in roots),
// closed by flat caps at z = 0 and z = height. Half-tooth j is j/2 <= u <= (j+1)/2.
//
// Intersection marches F = max(g, -z, z - height), where g = rho - R for rho >= root_radius
// and, closer to the axis, g = rho - r - (R - r) rho / r (same sign, no 1/rho blow-up). Along a
// unit ray |dF/dt| <= L = max(Lh |d_xy| + Lv |d_z|, |d_z|) with
//   Lh = sqrt(1 + (depth N / (pi root_radius))^2)  (radial and angular flank slope),
//   Lv = 2 depth A / wave_length                   (the wave's slope in z),
// so steps of F / L never pass a root (docs/simulator-scenes.md has the derivation).
template <typename T>
struct KnurledKnobT {
  int teeth = 0;
  T outer_radius = T(0);
  T depth = T(0);
  T height = T(0);
  T wave_phase = T(0);   // A, radians of u-phase (2 pi = one pitch)
  T wave_length = T(1);  // lambda
  AlbedoT<T> albedo;
  // Derived.
  T root_radius = T(0);
  T omega = T(0);
  T lipschitz_horizontal = T(1);
  T lipschitz_vertical = T(0);

  template <typename U>
  SLS_HOST_DEVICE KnurledKnobT<U> cast() const {
    KnurledKnobT<U> o;
    o.teeth = teeth;
    o.outer_radius = static_cast<U>(outer_radius);
    o.depth = static_cast<U>(depth);
    o.height = static_cast<U>(height);
    o.wave_phase = static_cast<U>(wave_phase);
    o.wave_length = static_cast<U>(wave_length);
    o.albedo = albedo.template cast<U>();
    o.root_radius = static_cast<U>(root_radius);
    o.omega = static_cast<U>(omega);
    // Rounded up so the float bound is still a bound.
    o.lipschitz_horizontal = static_cast<U>(lipschitz_horizontal * T(1.000001));
    o.lipschitz_vertical = static_cast<U>(lipschitz_vertical * T(1.000001));
    return o;
  }
};

template <typename T>
SLS_HOST_DEVICE inline KnurledKnobT<T> make_knurled_knob(int teeth, T outer_radius, T depth, T height, T wave_phase,
                                                         T wave_length, AlbedoT<T> albedo) {
  KnurledKnobT<T> k;
  k.teeth = teeth;
  k.outer_radius = outer_radius;
  k.depth = depth;
  k.height = height;
  k.wave_phase = wave_phase;
  k.wave_length = wave_length;
  k.albedo = albedo;
  k.root_radius = outer_radius - depth;
  k.omega = T(2) * detail::pi<T>() / wave_length;
  const T a = depth * static_cast<T>(teeth) / (detail::pi<T>() * k.root_radius);
  k.lipschitz_horizontal = std::sqrt(T(1) + a * a);
  k.lipschitz_vertical = T(2) * depth * detail::abs(wave_phase) / wave_length;
  return k;
}

// The phase u at (theta, z).
template <typename T>
SLS_HOST_DEVICE inline T knurled_knob_phase(const KnurledKnobT<T>& k, T theta, T z) {
  return (static_cast<T>(k.teeth) * theta + k.wave_phase * std::sin(k.omega * z)) / (T(2) * detail::pi<T>());
}

// tri(u) and its slope sign (+1 rising from a ridge, -1 falling towards the next ridge).
template <typename T>
SLS_HOST_DEVICE inline T knurled_knob_tri(T u, T* slope_sign) {
  const T f = u - std::floor(u);
  if (f < T(0.5)) {
    *slope_sign = T(1);
    return T(2) * f;
  }
  *slope_sign = T(-1);
  return T(2) * (T(1) - f);
}

// The side's radius R(theta, z).
template <typename T>
SLS_HOST_DEVICE inline T knurled_knob_radius(const KnurledKnobT<T>& k, T theta, T z) {
  T sign;
  return k.outer_radius - k.depth * knurled_knob_tri(knurled_knob_phase(k, theta, z), &sign);
}

// Unit outward normal of the side at p (on a ridge or root line: the side u rounds to).
template <typename T>
SLS_HOST_DEVICE inline Vec3T<T> knurled_knob_side_normal(const KnurledKnobT<T>& k, Vec3T<T> p) {
  const T rho = std::sqrt(p.x * p.x + p.y * p.y);
  const T theta = std::atan2(p.y, p.x);
  T sign;
  knurled_knob_tri(knurled_knob_phase(k, theta, p.z), &sign);
  // grad (rho - R) = e_rho - (R_theta / rho) e_theta - R_z e_z.
  const T g_theta = sign * k.depth * static_cast<T>(k.teeth) / (detail::pi<T>() * rho);
  const T g_z = sign * k.depth * k.wave_phase * k.omega * std::cos(k.omega * p.z) / detail::pi<T>();
  const T cx = p.x / rho, sy = p.y / rho;
  const Vec3T<T> g{cx - g_theta * sy, sy + g_theta * cx, g_z};
  return (T(1) / norm(g)) * g;
}

// F = max(g, -z, z - height) (see above): <= 0 inside the solid; *part says which term is
// largest, *slope its derivative along d (the side's from its gradient).
template <typename T>
SLS_HOST_DEVICE inline T knurled_knob_implicit(const KnurledKnobT<T>& k, Vec3T<T> p, Vec3T<T> d, int* part,
                                               T* slope) {
  const T rho = std::sqrt(p.x * p.x + p.y * p.y);
  const T theta = std::atan2(p.y, p.x);
  T sign;
  const T tri = knurled_knob_tri(knurled_knob_phase(k, theta, p.z), &sign);
  const T R = k.outer_radius - k.depth * tri;
  const T r = k.root_radius;
  T g;
  if (rho >= r) {
    g = rho - R;
  } else {
    g = rho - r - (R - r) * (rho / r);
  }
  T value = g;
  *part = kPartSide;
  if (-p.z > value) {
    value = -p.z;
    *part = kPartBottomCap;
  }
  if (p.z - k.height > value) {
    value = p.z - k.height;
    *part = kPartTopCap;
  }
  if (*part == kPartBottomCap) {
    *slope = -d.z;
  } else if (*part == kPartTopCap) {
    *slope = d.z;
  } else if (rho > T(0)) {
    const T g_theta = sign * k.depth * static_cast<T>(k.teeth) / (detail::pi<T>() * rho);
    const T g_z = sign * k.depth * k.wave_phase * k.omega * std::cos(k.omega * p.z) / detail::pi<T>();
    const T cx = p.x / rho, sy = p.y / rho;
    *slope = (cx - g_theta * sy) * d.x + (sy + g_theta * cx) * d.y + g_z * d.z;
  } else {
    *slope = T(0);
  }
  return value;
}

namespace detail {

// Marches G = sign * F along p0 + s d for s in [0, span] from G(0) > 0 and returns the first
// root in *s_hit (false: none). Certified steps G / L, then, once G <= near() and falling, a
// probe up to probe() ahead for a sign change and Illinois refinement of the bracket.
// span_ends_on_boundary: s = span is where the ray leaves the bounding cylinder (not t_max),
// so a march from inside the solid (sign < 0) that reaches it has found the exit there even
// when rounding keeps G a hair above 0.
template <typename T>
SLS_HOST_DEVICE inline bool knob_march(const KnurledKnobT<T>& k, Vec3T<T> p0, Vec3T<T> d, T span, T sign, T L,
                                       bool span_ends_on_boundary, T* s_hit, int* steps_out) {
  using P = Precision<T>;
  int part;
  T slope;
  T s = T(0);
  T G = sign * knurled_knob_implicit(k, p0, d, &part, &slope);
  T dG = sign * slope;
  T a = T(0), Ga = G, b = T(0), Gb = T(0);
  bool bracket = false;
  int step = 0;
  for (; step < P::max_steps(); ++step) {
    if (G <= P::near() && dG < T(0)) {
      const T c = min2(s + min2(T(2) * G / (-dG), P::probe()), span);
      T sc;
      int pc;
      const T Gc = sign * knurled_knob_implicit(k, p0 + c * d, d, &pc, &sc);
      if (Gc <= T(0)) {
        a = s;
        Ga = G;
        b = c;
        Gb = Gc;
        bracket = true;
        break;
      }
    }
    if (s >= span) break;
    const T next = min2(s + G / L, span);
    if (!(next > s)) break;  // no progress possible (a tangential touch): a miss
    s = next;
    G = sign * knurled_knob_implicit(k, p0 + s * d, d, &part, &slope);
    dG = sign * slope;
    if (G <= T(0)) {  // only rounding ends a certified step beyond the root
      a = s;
      Ga = T(0);
      b = s;
      Gb = G;
      bracket = true;
      break;
    }
  }
  if (steps_out) *steps_out = step;
  if (!bracket) {
    if (sign < T(0) && span_ends_on_boundary && s >= span - P::probe()) {
      *s_hit = span;
      return true;
    }
    return false;
  }
  // Illinois (modified regula falsi) on [a, b] with G(a) > 0 >= G(b); every third step
  // bisects if the bracket has not halved since the last check.
  int side = 0;
  T ref_width = b - a;
  for (int it = 0; it < 300 && b - a > P::t_tolerance(); ++it) {
    bool bisect = false;
    if (it % 3 == 2) {
      bisect = b - a > T(0.5) * ref_width;
      ref_width = b - a;
    }
    T m = T(0.5) * (a + b);
    if (!bisect && Ga != Gb) {
      const T mf = b - Gb * (b - a) / (Gb - Ga);
      if (mf > a && mf < b) m = mf;
    }
    if (!(m > a && m < b)) break;  // the bracket is down to adjacent floating-point values
    T sm;
    int pm;
    const T Gm = sign * knurled_knob_implicit(k, p0 + m * d, d, &pm, &sm);
    if (Gm <= T(0)) {
      b = m;
      Gb = Gm;
      if (side == -1) Ga *= T(0.5);
      side = -1;
    } else {
      a = m;
      Ga = Gm;
      if (side == 1) Gb *= T(0.5);
      side = 1;
    }
  }
  *s_hit = abs(Gb) <= abs(Ga) ? b : a;
  return true;
}

}  // namespace detail

// steps_out (optional): the number of march steps, for statistics.
template <typename T>
SLS_HOST_DEVICE inline bool intersect_knurled_knob(const KnurledKnobT<T>& k, const RayT<T>& ray, T t_min, T t_max,
                                                   HitT<T>* hit, int* steps_out = nullptr) {
  T lo, hi, tc0, tc1;
  if (steps_out) *steps_out = 0;
  if (!clip_to_cylinder(k.outer_radius, k.height, ray, t_min, t_max, &lo, &hi, &tc0, &tc1)) return false;
  const Vec3T<T> d = ray.direction;
  // March in s = t - lo from the entry point: in float, s resolves far finer steps than t.
  const Vec3T<T> p0 = ray.origin + lo * d;
  const T dxy = std::sqrt(d.x * d.x + d.y * d.y);
  const T L = detail::max2(detail::max2(k.lipschitz_horizontal * dxy + k.lipschitz_vertical * detail::abs(d.z),
                                        detail::abs(d.z)),
                           T(1e-12));
  int part;
  T slope;
  const T F0 = knurled_knob_implicit(k, p0, d, &part, &slope);
  T s_hit = T(0);
  if (F0 <= T(0) && lo > t_min) {
    // Entering the bounding cylinder from outside onto the solid: a cap, or a ridge that
    // touches the cylinder.
    s_hit = T(0);
  } else {
    // From outside the solid, the first entry; from inside (the origin is in the solid), the exit.
    const T sign = F0 <= T(0) ? T(-1) : T(1);
    if (!detail::knob_march(k, p0, d, hi - lo, sign, L, hi < t_max, &s_hit, steps_out)) return false;
  }
  hit->t = lo + s_hit;
  hit->point = p0 + s_hit * d;
  knurled_knob_implicit(k, hit->point, d, &part, &slope);
  hit->part = part;
  if (part == kPartSide) {
    hit->normal = knurled_knob_side_normal(k, hit->point);
    const T u = knurled_knob_phase(k, std::atan2(hit->point.y, hit->point.x), hit->point.z);
    hit->feature = detail::wrap_index<T>(static_cast<int>(std::floor(T(2) * u)), 2 * k.teeth);
  } else {
    hit->point.z = part == kPartBottomCap ? T(0) : k.height;
    hit->normal = {T(0), T(0), part == kPartBottomCap ? T(-1) : T(1)};
    hit->feature = -1;
  }
  hit->albedo = albedo_at(k.albedo, hit->point);
  return true;
}

}  // namespace sls::sim
