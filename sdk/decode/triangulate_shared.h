// Per-pixel triangulation of a decoded projector coordinate, shared by the CPU and CUDA
// decoders (DESIGN.md section 6): the camera ray (from the ray map, so the camera's lens
// distortion is already undone) against the set of points the projector lights with one
// column (or row) coordinate.
//
// With projector lens distortion that set is not a plane: a column's light leaves the DMD
// along a straight line of pixels, but distortion bends it into a curved sheet. So the depth
// is found exactly, by Newton's method on f(z) = u_projector(z * ray) - u along the camera ray,
// starting from the pinhole plane's intersection (distortion ignored); the projection and its
// derivative use the full Brown-Conrady model of camera_model_shared.h. The distortion of a
// well-corrected lens moves a coordinate by well under a pixel, so the start is within a
// small fraction of the answer and two or three steps reach float precision.
//
// When both columns and rows are coded, the pixel is triangulated ray against ray: the point
// on the (exact) camera ray whose projection into the projector is nearest the decoded (u, v),
// in projector pixels, by Gauss-Newton over z. The distance left over is the pixel's distance
// from its epipolar curve: a decode that is off its epipolar curve is inconsistent, an
// outlier test a column code alone cannot make.
#pragma once

#include <cmath>

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"
#include "sdk/decode/decode_shared.h"

namespace sls {

struct TriangulationParams {
  CameraIntrinsicsF projector;
  Rigid3f T_projector_camera;      // camera frame -> projector frame
  Vec3f projector_centre_camera;   // the projector's lens centre in the camera frame
  float min_sin_angle = 0.0872f;   // sin of the smallest accepted ray angle (5 degrees)
  float min_depth_m = 0.0f;        // accepted camera-frame z range
  float max_depth_m = 1e30f;
  int iterations = 3;              // Newton steps after the pinhole start
  float max_residual_px = 0.01f;   // convergence: |u_projector(z ray) - u| at the end
  float max_epipolar_px = 1.5f;    // ray-ray: largest distance of (u, v) from the epipolar curve
};

// Projector coordinate along `axis` (0: column, 1: row) of the camera-frame point z * ray, and
// its derivative with respect to z. Returns false behind the projector.
SLS_HOST_DEVICE inline bool projector_coordinate_along_ray(const TriangulationParams& p, Vec3f direction_projector,
                                                           float z, int axis, float* coordinate,
                                                           float* derivative) {
  const Vec3f& t = p.T_projector_camera.translation;
  const Vec3f point = Vec3f{z * direction_projector.x + t.x, z * direction_projector.y + t.y,
                            z * direction_projector.z + t.z};
  if (!(point.z > 0.0f)) return false;
  const float inverse_z = 1.0f / point.z;
  const Vec2f n{point.x * inverse_z, point.y * inverse_z};
  const Vec2f distorted = distort_normalized(p.projector, n);
  float j[4];
  distortion_jacobian(p.projector, n, j);
  // d n / d z for a point moving along the ray (direction d in the projector frame).
  const float dnx = (direction_projector.x - n.x * direction_projector.z) * inverse_z;
  const float dny = (direction_projector.y - n.y * direction_projector.z) * inverse_z;
  if (axis == 0) {
    *coordinate = p.projector.fx * distorted.x + p.projector.cx;
    *derivative = p.projector.fx * (j[0] * dnx + j[1] * dny);
  } else {
    *coordinate = p.projector.fy * distorted.y + p.projector.cy;
    *derivative = p.projector.fy * (j[2] * dnx + j[3] * dny);
  }
  return true;
}

// Depth where the camera ray (direction d in the projector frame) meets the pinhole plane
// (distortion ignored) of `coordinate` along `axis`; false when the ray runs parallel to it.
// |*transversality| grows with the angle between ray and plane (picks the better axis).
SLS_HOST_DEVICE inline bool pinhole_plane_depth(const TriangulationParams& p, Vec3f d, float coordinate, int axis,
                                                float* z, float* transversality) {
  const Vec3f& t = p.T_projector_camera.translation;
  float a, denominator;
  if (axis == 0) {
    a = (coordinate - p.projector.cx) / p.projector.fx;
    denominator = d.x - a * d.z;
    *z = (a * t.z - t.x) / denominator;
  } else {
    a = (coordinate - p.projector.cy) / p.projector.fy;
    denominator = d.y - a * d.z;
    *z = (a * t.z - t.y) / denominator;
  }
  *transversality = std::fabs(denominator);
  return std::fabs(denominator) > 1e-12f && *z > 0.0f;
}

// The checks every triangulated point passes: camera-frame z in [min_depth_m, max_depth_m],
// a triangulation angle (camera ray vs the projector's ray to the point) of at least the
// minimum, since the depth error grows as 1 / sin of it, and in front of the projector.
SLS_HOST_DEVICE inline bool accept_triangulated_depth(const TriangulationParams& p, Vec3f ray, float z) {
  if (!(z >= p.min_depth_m && z <= p.max_depth_m)) return false;
  const Vec3f point{z * ray.x, z * ray.y, z};
  const Vec3f from_projector = point - p.projector_centre_camera;
  const float projector_squared = dot(from_projector, from_projector);
  if (!(projector_squared > 0.0f)) return false;
  // sin = |ray x from_projector| / (|ray| |from_projector|) >= min_sin_angle, compared squared:
  // every decoded pixel passes here, and three square roots and a division cost the GPU ~35
  // instructions.
  if (p.min_sin_angle > 0.0f) {
    const Vec3f normal = cross(ray, from_projector);
    if (!(dot(normal, normal) >= p.min_sin_angle * p.min_sin_angle * dot(ray, ray) * projector_squared)) return false;
  }
  // In front of the projector (the start could land on the far sheet of a degenerate setup).
  const Vec3f point_projector = transform_point(p.T_projector_camera, point);
  return point_projector.z > 0.0f;
}

// Depth (camera-frame z) of the point on camera ray `ray` (z = 1) whose projector coordinate
// along `axis` is `coordinate`. Returns false (depth 0) when the ray is parallel to the
// column's sheet, Newton does not converge, the point is behind either device, outside
// [min_depth_m, max_depth_m], or seen under less than the minimum triangulation angle.
SLS_HOST_DEVICE inline bool triangulate_coordinate(const TriangulationParams& p, Vec3f ray, float coordinate,
                                                   int axis, float* depth) {
  *depth = 0.0f;
  if (!(ray.z > 0.0f) || !(coordinate == coordinate)) return false;
  const Vec3f d = rotate_vector(p.T_projector_camera, ray);
  float z = 0.0f, transversality = 0.0f;
  if (!pinhole_plane_depth(p, d, coordinate, axis, &z, &transversality)) return false;
  float value = 0.0f, slope = 0.0f;
  if (p.projector.has_distortion()) {
    for (int i = 0; i < p.iterations; ++i) {
      if (!projector_coordinate_along_ray(p, d, z, axis, &value, &slope)) return false;
      if (!(std::fabs(slope) > 1e-12f)) return false;
      z -= (value - coordinate) / slope;
    }
    if (!projector_coordinate_along_ray(p, d, z, axis, &value, &slope)) return false;
    if (!(std::fabs(value - coordinate) <= p.max_residual_px)) return false;
  }
  if (!accept_triangulated_depth(p, ray, z)) return false;
  *depth = z;
  return true;
}

// Ray against ray (see the file comment): returns 0 and the depth, or the mask bit that
// rejects the pixel: kDecodeInconsistent when (u, v) lies more than max_epipolar_px from
// the epipolar curve, kDecodeOutOfRange for the geometric checks. *epipolar_px: that distance.
SLS_HOST_DEVICE inline std::uint8_t triangulate_ray_ray(const TriangulationParams& p, Vec3f ray, float u, float v,
                                                        float* depth, float* epipolar_px) {
  *depth = 0.0f;
  *epipolar_px = NAN;
  if (!(ray.z > 0.0f) || !(u == u) || !(v == v)) return kDecodeOutOfRange;
  const Vec3f d = rotate_vector(p.T_projector_camera, ray);
  // Start from the plane of the axis the ray crosses more steeply.
  float z_u = 0.0f, z_v = 0.0f, transversality_u = 0.0f, transversality_v = 0.0f;
  const bool ok_u = pinhole_plane_depth(p, d, u, 0, &z_u, &transversality_u);
  const bool ok_v = pinhole_plane_depth(p, d, v, 1, &z_v, &transversality_v);
  if (!ok_u && !ok_v) return kDecodeOutOfRange;
  float z = ok_u && (!ok_v || transversality_u >= transversality_v) ? z_u : z_v;
  // Gauss-Newton on z: both residuals, each a smooth function of z along the ray. The
  // pinhole start is exact without distortion up to the epipolar offset; two extra steps
  // absorb it.
  float cu = 0.0f, du = 0.0f, cv = 0.0f, dv = 0.0f;
  for (int i = 0; i < p.iterations + 2; ++i) {
    if (!projector_coordinate_along_ray(p, d, z, 0, &cu, &du) || !projector_coordinate_along_ray(p, d, z, 1, &cv, &dv)) {
      return kDecodeOutOfRange;
    }
    const float curvature = du * du + dv * dv;
    if (!(curvature > 1e-24f)) return kDecodeOutOfRange;
    z -= ((cu - u) * du + (cv - v) * dv) / curvature;
  }
  if (!projector_coordinate_along_ray(p, d, z, 0, &cu, &du) || !projector_coordinate_along_ray(p, d, z, 1, &cv, &dv)) {
    return kDecodeOutOfRange;
  }
  // At the optimum the residual is perpendicular to the curve: its length is the distance.
  *epipolar_px = std::sqrt((cu - u) * (cu - u) + (cv - v) * (cv - v));
  if (!(*epipolar_px <= p.max_epipolar_px)) return kDecodeInconsistent;
  if (!accept_triangulated_depth(p, ray, z)) return kDecodeOutOfRange;
  *depth = z;
  return 0u;
}

// The per-pixel step both backends run after decode_pixel(): triangulates a decoded pixel
// along its camera ray (from the ray map) and returns the depth, 0 when rejected, in which
// case the pixel's mask becomes kDecodeOutOfRange, or kDecodeInconsistent when a column +
// row decode is off its epipolar curve (its coordinates become NaN, as for any inconsistent
// decode).
SLS_HOST_DEVICE inline float triangulate_decoded_pixel(const DecodeLayout& layout, const TriangulationParams& tri,
                                                       PixelDecode* pixel, Vec3f ray, bool ray_valid) {
  if (pixel->mask != kDecodeOk) return 0.0f;
  if (!ray_valid) {
    pixel->mask = kDecodeOutOfRange;
    return 0.0f;
  }
  const bool columns = layout.axes[0].extent > 0;
  const bool rows = layout.axes[1].extent > 0;
  float depth = 0.0f;
  if (columns && rows) {
    float epipolar_px = 0.0f;
    const std::uint8_t rejected = triangulate_ray_ray(tri, ray, pixel->u, pixel->v, &depth, &epipolar_px);
    if (rejected != 0u) {
      pixel->mask = rejected;
      if (rejected == kDecodeInconsistent) pixel->u = pixel->v = NAN;  // as any inconsistent decode
      return 0.0f;
    }
    return depth;
  }
  // One axis coded: the ray against that coordinate's sheet.
  if (!triangulate_coordinate(tri, ray, columns ? pixel->u : pixel->v, columns ? 0 : 1, &depth)) {
    pixel->mask = kDecodeOutOfRange;
    return 0.0f;
  }
  return depth;
}

}  // namespace sls
