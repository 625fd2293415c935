// Per-pixel raycasting of the volume's zero level set, shared by the CPU and CUDA raycasters
// (DESIGN.md section 6): march the pixel's ray (from the camera's ray map, so the lens
// distortion is the SLS camera model's) through the volume in steps that shrink with |U|,
// stop at the first + to - crossing of the trilinear U, place the point by linear
// interpolation of the crossing and take the normal from the gradient of U.
#pragma once

#include <cmath>

#include "fusion/depth_shared.h"
#include "fusion/volume_shared.h"

namespace sls::fusion {

struct RaycastParams {
  float truncation_m = 0.0f;  // δ of the integration: far from the surface U = 1 means ">= δ away"
  float min_depth_m = 0.0f;   // camera-frame z range searched
  float max_depth_m = 1e30f;
};

struct RaycastHit {
  float depth_m;        // camera-frame z; 0 = no surface
  Vec3f point_camera;
  Vec3f normal_camera;  // unit, facing the camera
};

// The parameter interval [t0, t1] of origin + t * direction inside the box where trilinear
// samples exist (voxel centres 0.5 .. n - 0.5); false when the ray misses it.
SLS_HOST_DEVICE inline bool clip_to_volume(const VolumeView& v, Vec3f origin, Vec3f direction, float* t0,
                                           float* t1) {
  const float lo = 0.5f * v.voxel_size_m;
  const float hi[3] = {(static_cast<float>(v.nx) - 0.5f) * v.voxel_size_m,
                       (static_cast<float>(v.ny) - 0.5f) * v.voxel_size_m,
                       (static_cast<float>(v.nz) - 0.5f) * v.voxel_size_m};
  const float o[3] = {origin.x, origin.y, origin.z};
  const float d[3] = {direction.x, direction.y, direction.z};
  float enter = *t0, leave = *t1;
  for (int axis = 0; axis < 3; ++axis) {
    if (std::fabs(d[axis]) < 1e-12f) {
      if (o[axis] < lo || o[axis] > hi[axis]) return false;
      continue;
    }
    float a = (lo - o[axis]) / d[axis];
    float b = (hi[axis] - o[axis]) / d[axis];
    if (a > b) {
      const float swap = a;
      a = b;
      b = swap;
    }
    enter = std::fmax(enter, a);
    leave = std::fmin(leave, b);
  }
  *t0 = enter;
  *t1 = leave;
  return enter < leave;
}

// The ray parameter where origin + t * direction leaves the brick holding voxel (i, j, k)
// (at least t).
SLS_HOST_DEVICE inline float brick_exit(const VolumeView& v, Vec3f origin, Vec3f direction, int i, int j, int k,
                                        float t) {
  const float brick_m = static_cast<float>(1 << VolumeView::kBrickShift) * v.voxel_size_m;
  const int b[3] = {i >> VolumeView::kBrickShift, j >> VolumeView::kBrickShift, k >> VolumeView::kBrickShift};
  const float o[3] = {origin.x, origin.y, origin.z};
  const float d[3] = {direction.x, direction.y, direction.z};
  float exit = 3.0e38f;
  for (int axis = 0; axis < 3; ++axis) {
    if (d[axis] == 0.0f) continue;
    const float face = (d[axis] > 0.0f ? static_cast<float>(b[axis] + 1) : static_cast<float>(b[axis])) * brick_m;
    exit = std::fmin(exit, (face - o[axis]) / d[axis]);
  }
  return std::fmax(exit, t);
}

// Guided search (the scan session's raycast for tracking): the surface seen from a pose lies
// near the depth map just integrated from that pose (the guide). A ray searches only the
// guide's depths under its pixel widened by a margin; where the guide has none there (a
// shadow, a rejected pixel), the range of the depths in its 3 × 3 tiles of
// kRaycastGuideTile² pixels; with none there either (the rim, a large hole), the full range.
// Most of an unguided 960³ raycast is the march up to the surface.
constexpr int kRaycastGuideTile = 16;

struct RaycastGuideView {
  const float* depth_m = nullptr;     // the guide, guide_width x guide_height, row-major
  int guide_width = 0;                // >= the raycast's size (e.g. the full live map of a halved raycast)
  int guide_height = 0;
  int width = 0;                      // the raycast's size
  int height = 0;
  const float* tile_min_m = nullptr;  // tiles_x * tiles_y, row-major; +inf where a tile has no depth
  const float* tile_max_m = nullptr;  // 0 where a tile has no depth
  int tiles_x = 0;
  int tiles_y = 0;
  float margin_m = 0.0f;
};

// The guide pixels [*begin, *end) under raycast pixels [first, first + count) along one axis
// (raycast size `size`, guide size `guide_size`).
SLS_HOST_DEVICE inline void guide_span(int first, int count, int size, int guide_size, int* begin, int* end) {
  const long long a = first;
  const long long b = first + count < size ? first + count : size;
  *begin = static_cast<int>(a * guide_size / size);
  *end = static_cast<int>((b * guide_size + size - 1) / size);
  if (*end > guide_size) *end = guide_size;
}

// Narrows p's depth range for pixel (x, y) as described above; unchanged without a guide.
SLS_HOST_DEVICE inline void guided_depth_range(const RaycastGuideView& g, int x, int y, RaycastParams* p) {
  if (g.depth_m == nullptr) return;
  float lo = 3.0e38f, hi = 0.0f;
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  guide_span(x, 1, g.width, g.guide_width, &x0, &x1);
  guide_span(y, 1, g.height, g.guide_height, &y0, &y1);
  for (int gy = y0; gy < y1; ++gy) {
    for (int gx = x0; gx < x1; ++gx) {
      const float depth = g.depth_m[static_cast<long long>(gy) * g.guide_width + gx];
      if (!is_measured_depth(depth)) continue;
      lo = std::fmin(lo, depth);
      hi = std::fmax(hi, depth);
    }
  }
  if (!(hi > 0.0f)) {
    const int tx = x / kRaycastGuideTile, ty = y / kRaycastGuideTile;
    for (int j = (ty > 0 ? ty - 1 : 0); j <= (ty + 1 < g.tiles_y ? ty + 1 : g.tiles_y - 1); ++j) {
      for (int i = (tx > 0 ? tx - 1 : 0); i <= (tx + 1 < g.tiles_x ? tx + 1 : g.tiles_x - 1); ++i) {
        lo = std::fmin(lo, g.tile_min_m[j * g.tiles_x + i]);
        hi = std::fmax(hi, g.tile_max_m[j * g.tiles_x + i]);
      }
    }
    if (!(hi > 0.0f)) return;
  }
  p->min_depth_m = std::fmax(p->min_depth_m, lo - g.margin_m);
  p->max_depth_m = std::fmin(p->max_depth_m, hi + g.margin_m);
}

// One pixel: `ray_camera` is the ray map's direction (z = 1), T_volume_camera the camera in
// the volume. Returns the hit (depth 0 when none).
SLS_HOST_DEVICE inline RaycastHit raycast_pixel(const VolumeView& v, const RaycastParams& p,
                                                const Rigid3f& T_volume_camera, Vec3f ray_camera) {
  RaycastHit hit{0.0f, Vec3f{0.0f, 0.0f, 0.0f}, Vec3f{0.0f, 0.0f, 0.0f}};
  if (!(ray_camera.z > 0.0f)) return hit;
  // March in camera z (t multiplies the z = 1 ray), so t is the depth.
  const Vec3f origin = T_volume_camera.translation;
  const Vec3f direction = rotate_vector(T_volume_camera, ray_camera);
  const float ray_length = norm(ray_camera);  // metres of path per unit of z
  float t0 = p.min_depth_m, t1 = p.max_depth_m;
  if (!clip_to_volume(v, origin, direction, &t0, &t1)) return hit;
  const float min_step = v.voxel_size_m / ray_length;  // one voxel of path
  const float to_grid = 1.0f / v.voxel_size_m;         // sample_u's: one reciprocal, no division a step
  const float skip_per_u = 0.8f * p.truncation_m / ray_length;  // the skip below, per unit of U
  float t = t0;
  float previous = 0.0f, previous_t = 0.0f;
  bool have_previous = false;
  while (t <= t1) {
    const Vec3f point = origin + t * direction;
    // Empty-space skipping: a brick no surface voxel has touched is crossed in one jump.
    const int vi = static_cast<int>(point.x * to_grid);
    const int vj = static_cast<int>(point.y * to_grid);
    const int vk = static_cast<int>(point.z * to_grid);
    if (v.contains(vi, vj, vk) && !v.may_hold_surface(vi, vj, vk)) {
      t = brick_exit(v, origin, direction, vi, vj, vk, t) + 1e-3f * min_step;
      have_previous = false;
      continue;
    }
    float value = 0.0f;
    if (!sample_u(v, point, &value)) {
      have_previous = false;
      t += min_step;
      continue;
    }
    if (have_previous && previous > 0.0f && value <= 0.0f) {
      // Zero crossing between the two samples: regula falsi on the trilinear U along the ray
      // (U is not linear along it, so one interpolation can be off by a few hundredths of a voxel).
      float t_in = previous_t, u_in = previous, t_out = t, u_out = value;
      float z = t;
      for (int refine = 0; refine < 4; ++refine) {
        const float denominator = u_in - u_out;
        z = denominator > 0.0f ? t_in + (t_out - t_in) * u_in / denominator : t_out;
        float u_z = 0.0f;
        if (refine == 3 || !sample_u(v, origin + z * direction, &u_z)) break;
        if (u_z > 0.0f) {
          t_in = z;
          u_in = u_z;
        } else {
          t_out = z;
          u_out = u_z;
        }
      }
      const Vec3f surface_volume = origin + z * direction;
      Vec3f normal_volume;
      if (!surface_normal(v, surface_volume, &normal_volume)) return hit;
      Vec3f normal = rotate_vector(inverse(T_volume_camera), normal_volume);
      // The gradient of U points out of the surface, towards the camera for a front face.
      if (dot(normal, ray_camera) > 0.0f) normal = -normal;
      hit.depth_m = z;
      hit.point_camera = Vec3f{z * ray_camera.x, z * ray_camera.y, z};
      hit.normal_camera = normal;
      return hit;
    }
    if (have_previous && previous < 0.0f && value > 0.0f) return hit;  // left an object from behind: no front face
    previous = value;
    previous_t = t;
    have_previous = true;
    // Far from the surface U says how far it is at least (in δ): skip most of it.
    const float skip = value > 0.0f ? value * skip_per_u : 0.0f;
    t += std::fmax(min_step, skip);
  }
  return hit;
}

// A grey level for pictures: Lambertian shading under a light from the upper left behind the
// camera (a raking light shows relief that a light at the camera flattens), plus ambient.
SLS_HOST_DEVICE inline unsigned char shade(const RaycastHit& hit, Vec3f ray_camera) {
  (void)ray_camera;
  if (!(hit.depth_m > 0.0f)) return 0;
  const Vec3f light_travel{0.6396f, 0.4264f, 0.6396f};  // unit: the light's direction of travel
  const float cosine = -dot(hit.normal_camera, light_travel);
  const float level = 25.0f + 230.0f * std::fmax(0.0f, cosine);
  return static_cast<unsigned char>(level);
}

}  // namespace sls::fusion
