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

// Depth (camera-frame z) of the point on camera ray `ray` (z = 1) whose projector coordinate
// along `axis` is `coordinate`. Returns false (depth 0) when the ray is parallel to the
// column's sheet, Newton does not converge, the point is behind either device, outside
// [min_depth_m, max_depth_m], or seen under less than the minimum triangulation angle.
SLS_HOST_DEVICE inline bool triangulate_coordinate(const TriangulationParams& p, Vec3f ray, float coordinate,
                                                   int axis, float* depth) {
  *depth = 0.0f;
  if (!(ray.z > 0.0f) || !(coordinate == coordinate)) return false;
  const Vec3f d = rotate_vector(p.T_projector_camera, ray);
  const Vec3f& t = p.T_projector_camera.translation;
  // Start: the pinhole plane of the coordinate, a * z_p = x_p (or y_p), intersected with the ray.
  float z;
  if (axis == 0) {
    const float a = (coordinate - p.projector.cx) / p.projector.fx;
    const float denominator = d.x - a * d.z;
    if (!(std::fabs(denominator) > 1e-12f)) return false;
    z = (a * t.z - t.x) / denominator;
  } else {
    const float a = (coordinate - p.projector.cy) / p.projector.fy;
    const float denominator = d.y - a * d.z;
    if (!(std::fabs(denominator) > 1e-12f)) return false;
    z = (a * t.z - t.y) / denominator;
  }
  if (!(z > 0.0f)) return false;
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
  if (!(z >= p.min_depth_m && z <= p.max_depth_m)) return false;
  // Triangulation angle between the camera ray and the projector's ray to the point: the
  // depth error grows as 1 / sin of it.
  const Vec3f point{z * ray.x, z * ray.y, z};
  const Vec3f from_projector = point - p.projector_centre_camera;
  const float ray_length = norm(ray);
  const float projector_length = norm(from_projector);
  if (!(projector_length > 0.0f)) return false;
  const float sin_angle = norm(cross(ray, from_projector)) / (ray_length * projector_length);
  if (!(sin_angle >= p.min_sin_angle)) return false;
  // In front of the projector (the start could land on the far sheet of a degenerate setup).
  const Vec3f point_projector = transform_point(p.T_projector_camera, point);
  if (!(point_projector.z > 0.0f)) return false;
  *depth = z;
  return true;
}

// The per-pixel step both backends run after decode_pixel(): triangulates a decoded pixel
// along its camera ray (from the ray map) and returns the depth, 0 when rejected, in which
// case the pixel's mask becomes kDecodeOutOfRange (its coordinates stay valid).
SLS_HOST_DEVICE inline float triangulate_decoded_pixel(const DecodeLayout& layout, const TriangulationParams& tri,
                                                       PixelDecode* pixel, Vec3f ray, bool ray_valid) {
  if (pixel->mask != kDecodeOk) return 0.0f;
  // Columns are the rig's triangulation axis; a rows-only set triangulates on rows.
  const bool columns = layout.axes[0].extent > 0;
  float depth = 0.0f;
  if (!ray_valid || !triangulate_coordinate(tri, ray, columns ? pixel->u : pixel->v, columns ? 0 : 1, &depth)) {
    pixel->mask = kDecodeOutOfRange;
    return 0.0f;
  }
  return depth;
}

}  // namespace sls
