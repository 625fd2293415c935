// Surface extraction's per-voxel and per-cell math, shared by the CPU loop (fusion/extract.cpp)
// and any CUDA kernel (DESIGN.md section 6): zero crossings of U along the voxel grid's
// edges (the paper's cloud, and the vertices of the marching-cubes mesh) and each cell's
// marching-cubes case.
//
// Grid edge (i, j, k, axis) joins voxel (i, j, k) with its +x, +y or +z neighbour (axis 0,
// 1, 2). Its id, index(i, j, k) * 3 + axis, names the vertex every cell around the edge
// shares, and ids grow in the order of a k-major, then j, then i, then axis loop.
// A voxel takes part only when it has been observed at least `min_weight` times (and at
// least once: W = 0 is never a surface).
#pragma once

#include <cstdint>

#include "fusion/marching_cubes_tables.h"
#include "fusion/volume_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::fusion {

// A zero crossing: where U changes sign along a grid edge, in the volume frame.
struct SurfaceCrossing {
  Vec3f point_volume{0.0f, 0.0f, 0.0f};
  Vec3f normal_volume{0.0f, 0.0f, 0.0f};  // unit, towards growing U (out of the solid)
  float weight = 0.0f;                    // the smaller of the two voxels' weights
};

// Each function below reads the voxels with the format known when compiled (the *_as<F>
// templates, which the GPU's kernels instantiate once per format: a format test at each of a
// cell's 16 reads is most of what a ship's search does); the plain names test it once.
template <VoxelFormat F>
SLS_HOST_DEVICE inline bool voxel_usable_as(const VolumeView& v, std::size_t index, float min_weight) {
  const float w = v.w_as<F>(index);
  return w > 0.0f && w >= min_weight;
}
SLS_HOST_DEVICE inline bool voxel_usable(const VolumeView& v, std::size_t index, float min_weight) {
  return v.format == VoxelFormat::kFloat32 ? voxel_usable_as<VoxelFormat::kFloat32>(v, index, min_weight)
                                           : voxel_usable_as<VoxelFormat::kCompact>(v, index, min_weight);
}

SLS_HOST_DEVICE inline std::uint64_t grid_edge_id(const VolumeView& v, int i, int j, int k, int axis) {
  return static_cast<std::uint64_t>(v.index(i, j, k)) * 3u + static_cast<std::uint64_t>(axis);
}

// Gradient of U at a voxel (per voxel, not per metre) from its observed axis neighbours:
// central differences where both are observed, one-sided where one is, 0 along an axis with
// neither. The fallback normal where the trilinear surface_normal() lacks samples (the
// volume's border, the rim of the observed band).
template <VoxelFormat F>
SLS_HOST_DEVICE inline Vec3f voxel_gradient_as(const VolumeView& v, int i, int j, int k) {
  const float centre = v.u_as<F>(v.index(i, j, k));
  float g[3] = {0.0f, 0.0f, 0.0f};
  for (int axis = 0; axis < 3; ++axis) {
    const int dx = axis == 0 ? 1 : 0, dy = axis == 1 ? 1 : 0, dz = axis == 2 ? 1 : 0;
    float plus = 0.0f, minus = 0.0f;
    bool has_plus = false, has_minus = false;
    if (v.contains(i + dx, j + dy, k + dz)) {
      const std::size_t index = v.index(i + dx, j + dy, k + dz);
      has_plus = v.w_as<F>(index) > 0.0f;
      if (has_plus) plus = v.u_as<F>(index);
    }
    if (v.contains(i - dx, j - dy, k - dz)) {
      const std::size_t index = v.index(i - dx, j - dy, k - dz);
      has_minus = v.w_as<F>(index) > 0.0f;
      if (has_minus) minus = v.u_as<F>(index);
    }
    if (has_plus && has_minus) {
      g[axis] = 0.5f * (plus - minus);
    } else if (has_plus) {
      g[axis] = plus - centre;
    } else if (has_minus) {
      g[axis] = centre - minus;
    }
  }
  return Vec3f{g[0], g[1], g[2]};
}

// The normal at a crossing on edge (i, j, k, axis) at fraction t from voxel (i, j, k):
// surface_normal() of the trilinear field where its samples exist, else the voxel gradients
// of the edge's ends blended at t, else the edge's own direction (U grows along it as
// `u_rise` says). Always unit length.
template <VoxelFormat F>
SLS_HOST_DEVICE inline Vec3f crossing_normal_as(const VolumeView& v, Vec3f point_volume, int i, int j, int k,
                                                int axis, float t, float u_rise) {
  Vec3f normal{0.0f, 0.0f, 0.0f};
  if (surface_normal_as<F>(v, point_volume, &normal)) return normal;
  const int dx = axis == 0 ? 1 : 0, dy = axis == 1 ? 1 : 0, dz = axis == 2 ? 1 : 0;
  const Vec3f g0 = voxel_gradient_as<F>(v, i, j, k);
  const Vec3f g1 = voxel_gradient_as<F>(v, i + dx, j + dy, k + dz);
  const Vec3f g = (1.0f - t) * g0 + t * g1;
  const float length = norm(g);
  if (length > 0.0f) return (1.0f / length) * g;
  const float sign = u_rise >= 0.0f ? 1.0f : -1.0f;
  return Vec3f{sign * static_cast<float>(dx), sign * static_cast<float>(dy), sign * static_cast<float>(dz)};
}

// Where grid edge (i, j, k, axis) crosses zero, if it does: both voxels inside the volume and
// usable, and U changes sign (U < 0 against U >= 0, as the marching-cubes case bits). The
// point is linearly interpolated between the voxel centres. Without the normal, so a caller
// that keeps few crossings (a region) tests the place before paying for the gradient.
struct EdgeZero {
  Vec3f point_volume;
  float t;       // along the edge, in [0, 1]
  float u_step;  // U(b) - U(a)
  float weight;  // the smaller of the two voxels' weights
};

template <VoxelFormat F>
SLS_HOST_DEVICE inline bool edge_zero_as(const VolumeView& v, int i, int j, int k, int axis, float min_weight,
                                         EdgeZero* out) {
  const int dx = axis == 0 ? 1 : 0, dy = axis == 1 ? 1 : 0, dz = axis == 2 ? 1 : 0;
  if (!v.contains(i + dx, j + dy, k + dz)) return false;
  const std::size_t a = v.index(i, j, k);
  const std::size_t b = v.index(i + dx, j + dy, k + dz);
  if (!voxel_usable_as<F>(v, a, min_weight) || !voxel_usable_as<F>(v, b, min_weight)) return false;
  const float ua = v.u_as<F>(a), ub = v.u_as<F>(b);
  if ((ua < 0.0f) == (ub < 0.0f)) return false;
  const float t = ua / (ua - ub);  // signs differ, so ua - ub != 0 and t is in [0, 1]
  Vec3f point = v.voxel_centre(i, j, k);
  const float step = t * v.voxel_size_m;
  if (axis == 0) point.x += step;
  if (axis == 1) point.y += step;
  if (axis == 2) point.z += step;
  out->point_volume = point;
  out->t = t;
  out->u_step = ub - ua;
  const float wa = v.w_as<F>(a), wb = v.w_as<F>(b);
  out->weight = wa < wb ? wa : wb;
  return true;
}

// The crossing of edge_zero with its normal (the gradient of U there).
template <VoxelFormat F>
SLS_HOST_DEVICE inline SurfaceCrossing edge_zero_crossing_as(const VolumeView& v, int i, int j, int k, int axis,
                                                             const EdgeZero& zero) {
  SurfaceCrossing crossing;
  crossing.point_volume = zero.point_volume;
  crossing.normal_volume = crossing_normal_as<F>(v, zero.point_volume, i, j, k, axis, zero.t, zero.u_step);
  crossing.weight = zero.weight;
  return crossing;
}

// edge_zero and its normal in one.
template <VoxelFormat F>
SLS_HOST_DEVICE inline bool edge_crossing_as(const VolumeView& v, int i, int j, int k, int axis, float min_weight,
                                             SurfaceCrossing* out) {
  EdgeZero zero;
  if (!edge_zero_as<F>(v, i, j, k, axis, min_weight, &zero)) return false;
  *out = edge_zero_crossing_as<F>(v, i, j, k, axis, zero);
  return true;
}
SLS_HOST_DEVICE inline bool edge_crossing(const VolumeView& v, int i, int j, int k, int axis, float min_weight,
                                          SurfaceCrossing* out) {
  return v.format == VoxelFormat::kFloat32 ? edge_crossing_as<VoxelFormat::kFloat32>(v, i, j, k, axis, min_weight, out)
                                           : edge_crossing_as<VoxelFormat::kCompact>(v, i, j, k, axis, min_weight, out);
}

// The marching-cubes case of cell (i, j, k), whose corners are voxels (i..i+1, j..j+1,
// k..k+1): bit c set when corner c is inside (U < 0). -1 when the cell leaves the volume or
// a corner is not usable (no surface is guessed across unobserved voxels).
template <VoxelFormat F>
SLS_HOST_DEVICE inline int cell_case_as(const VolumeView& v, int i, int j, int k, float min_weight) {
  if (i < 0 || j < 0 || k < 0 || i + 1 >= v.nx || j + 1 >= v.ny || k + 1 >= v.nz) return -1;
  int cube_case = 0;
  for (int c = 0; c < 8; ++c) {
    const std::size_t index = v.index(i + mc::corner_dx(c), j + mc::corner_dy(c), k + mc::corner_dz(c));
    if (!voxel_usable_as<F>(v, index, min_weight)) return -1;
    if (v.u_as<F>(index) < 0.0f) cube_case |= 1 << c;
  }
  return cube_case;
}
SLS_HOST_DEVICE inline int cell_case(const VolumeView& v, int i, int j, int k, float min_weight) {
  return v.format == VoxelFormat::kFloat32 ? cell_case_as<VoxelFormat::kFloat32>(v, i, j, k, min_weight)
                                           : cell_case_as<VoxelFormat::kCompact>(v, i, j, k, min_weight);
}

// The grid edge under edge e (0..11) of cell (i, j, k): its first voxel and axis.
SLS_HOST_DEVICE inline void cell_grid_edge(int i, int j, int k, int e, int* gi, int* gj, int* gk, int* axis) {
  const int a = mc::edge_corner_a(e), b = mc::edge_corner_b(e);
  const int ax = mc::corner_dx(a), ay = mc::corner_dy(a), az = mc::corner_dz(a);
  const int bx = mc::corner_dx(b), by = mc::corner_dy(b), bz = mc::corner_dz(b);
  *gi = i + (ax < bx ? ax : bx);
  *gj = j + (ay < by ? ay : by);
  *gk = k + (az < bz ? az : bz);
  *axis = ax != bx ? 0 : (ay != by ? 1 : 2);
}


// A crossing found on grid edge `edge_id` (grid_edge_id()): what the CPU loops and the CUDA
// kernels hand to the host, which orders them by edge id.
struct EdgeCrossing {
  std::uint64_t edge_id = 0;
  SurfaceCrossing crossing;
};

// A marching-cubes cell (the voxel index of its first corner) and its case (1..254).
struct CellCase {
  std::uint64_t cell = 0;
  std::int32_t cube_case = 0;
};

// The centre of cell (i, j, k) (corners voxels i..i+1, j..j+1, k..k+1), volume frame.
SLS_HOST_DEVICE inline Vec3f cell_centre(const VolumeView& v, int i, int j, int k) {
  return Vec3f{(static_cast<float>(i) + 1.0f) * v.voxel_size_m, (static_cast<float>(j) + 1.0f) * v.voxel_size_m,
               (static_cast<float>(k) + 1.0f) * v.voxel_size_m};
}

// An oriented box as an extraction filter (fusion/extract.h's OrientedRegion holds it on the
// host): a volume-frame point p is inside when q = T_box_volume * p lies in [lo, hi] on every
// axis, bounds included; the filter keeps the inside, or the outside with keep_outside (the
// moving volume ships what lies outside its new placement). Evaluated in float on the
// volume-frame point, by the same code on both backends, so they keep the same points.
struct RegionFilter {
  Rigid3f T_box_volume{};
  Vec3f lo{0.0f, 0.0f, 0.0f};
  Vec3f hi{0.0f, 0.0f, 0.0f};
  int keep_outside = 0;
};

SLS_HOST_DEVICE inline bool region_keeps(const RegionFilter& r, Vec3f point_volume) {
  const Vec3f q = transform_point(r.T_box_volume, point_volume);
  const bool inside = q.x >= r.lo.x && q.y >= r.lo.y && q.z >= r.lo.z && q.x <= r.hi.x && q.y <= r.hi.y &&
                      q.z <= r.hi.z;
  return inside != (r.keep_outside != 0);
}

// Whether a cell of the region's mesh (a cell belongs to the region when its centre does) is
// around grid edge (i, j, k, axis): the (up to) four cells sharing the edge, inside the grid.
// The vertices of the region's triangles are the crossings on such edges.
SLS_HOST_DEVICE inline bool edge_has_region_cell(const VolumeView& v, const RegionFilter& r, int i, int j, int k,
                                                 int axis) {
  const int u = (axis + 1) % 3, w = (axis + 2) % 3;  // the two axes across the edge
  for (int du = 0; du < 2; ++du) {
    for (int dw = 0; dw < 2; ++dw) {
      int cell[3] = {i, j, k};
      cell[u] -= du;
      cell[w] -= dw;
      if (cell[0] < 0 || cell[1] < 0 || cell[2] < 0 || cell[0] + 1 >= v.nx || cell[1] + 1 >= v.ny ||
          cell[2] + 1 >= v.nz) {
        continue;
      }
      if (region_keeps(r, cell_centre(v, cell[0], cell[1], cell[2]))) return true;
    }
  }
  return false;
}

// Whether a region that keeps its outside drops everything found from the voxels first..last
// (inclusive, per axis): a crossing on one of their edges, a cell around such an edge and a
// cell of theirs all have their points (crossings, cell centres) within [first - 1/2, last +
// 3/2] voxels (voxel centres at +1/2); when that box lies inside the region's box (convex:
// its corners do, by 0.05 voxel for float rounding), the region keeps none of them. Lets the
// GPU skip the bulk of a moving volume that stays (false for a region that keeps its inside).
SLS_HOST_DEVICE inline bool region_drops_voxels(const RegionFilter& r, float voxel_size_m, const int first[3],
                                                const int last[3]) {
  if (r.keep_outside == 0) return false;
  const float tolerance = 0.05f * voxel_size_m;
  for (int corner = 0; corner < 8; ++corner) {
    float p[3];
    for (int axis = 0; axis < 3; ++axis) {
      const bool high = ((corner >> axis) & 1) != 0;
      p[axis] = (high ? static_cast<float>(last[axis]) + 1.5f : static_cast<float>(first[axis]) - 0.5f) * voxel_size_m;
    }
    const Vec3f q = transform_point(r.T_box_volume, Vec3f{p[0], p[1], p[2]});
    const bool inside = q.x >= r.lo.x + tolerance && q.y >= r.lo.y + tolerance && q.z >= r.lo.z + tolerance &&
                        q.x <= r.hi.x - tolerance && q.y <= r.hi.y - tolerance && q.z <= r.hi.z - tolerance;
    if (!inside) return false;
  }
  return true;
}

}  // namespace sls::fusion
