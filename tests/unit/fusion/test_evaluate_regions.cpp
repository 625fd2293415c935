// The paper's Table I measure (sdk/eval/evaluate_regions.h): a model against one view's raw
// scan in the four image quadrants, and against the exact surface, on a plane of known offset.
#include "sdk/eval/evaluate_regions.h"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"

namespace sls::eval {
namespace {

constexpr double kUm = 1e-6;
constexpr double kDepth = 0.1;

CameraIntrinsics test_camera() {
  CameraIntrinsics camera;
  camera.width = 40;
  camera.height = 30;
  camera.fx = camera.fy = 2000.0;  // 50 µm per pixel at 10 cm
  camera.cx = 19.5;
  camera.cy = 14.5;
  return camera;
}

// One model point per pixel: the raw scan's point of that pixel moved along the optical axis
// by offset_m, its normal facing the camera (normal_z = -1) or away (+1).
PointCloud plane_model(const CameraIntrinsics& camera, double offset_m, float normal_z = -1.0f) {
  const RayMap rays = compute_ray_map(camera);
  PointCloud model;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Vec3f& ray = rays.ray(x, y);
      model.positions.emplace_back(ray.x * static_cast<float>(kDepth), ray.y * static_cast<float>(kDepth),
                                   static_cast<float>(kDepth + offset_m));
      model.normals.emplace_back(0.0f, 0.0f, normal_z);
    }
  }
  return model;
}

TEST(ViewRegionErrors, AModelOffsetFromAPlaneIsThatFarFromItsRawScanInEveryQuadrant) {
  const CameraIntrinsics camera = test_camera();
  const Image32f raw(camera.width, camera.height, static_cast<float>(kDepth));
  // The camera looks down -z of the object's plane (z = 0) from 10 cm.
  const Pose T_world_camera;
  const Pose T_object_world(Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal().toDenseMatrix(),
                            Eigen::Vector3d(0.0, 0.0, kDepth));
  const sim::Scene plane = sim::make_plane_scene();
  for (const double offset : {0.0, 5e-6, -12e-6}) {
    SCOPED_TRACE(offset);
    const ViewRegionErrors errors =
        view_region_errors(plane_model(camera, offset), raw, camera, T_world_camera, &plane, T_object_world);
    EXPECT_EQ(errors.model_points, 1200u);
    EXPECT_EQ(errors.visible_points, 1200u);
    const char* names[4] = {"upper-left", "upper-right", "lower-left", "lower-right"};
    for (std::size_t q = 0; q < 4; ++q) {
      EXPECT_EQ(errors.regions[q].name, names[q]);
      EXPECT_EQ(errors.regions[q].to_raw_scan.count, 300u);
      EXPECT_NEAR(errors.regions[q].to_raw_scan.mean_m, std::fabs(offset), 0.01 * kUm);
      EXPECT_EQ(errors.regions[q].to_surface.count, 300u);
      // float positions at 10 cm: ~4 nm resolution.
      EXPECT_NEAR(errors.regions[q].to_surface.mean_m, std::fabs(offset), 0.02 * kUm);
    }
    EXPECT_EQ(errors.all.name, "all");
    EXPECT_NEAR(errors.all.to_raw_scan.max_m, std::fabs(offset), 0.01 * kUm);
  }
}

TEST(ViewRegionErrors, OnlyWhatTheViewSeesCounts) {
  const CameraIntrinsics camera = test_camera();
  Image32f raw(camera.width, camera.height, static_cast<float>(kDepth));
  for (int y = 0; y < 15; ++y) {
    for (int x = 0; x < 20; ++x) raw(x, y) = 0.0f;  // the upper-left quadrant has no raw depth
  }
  // Facing away: none; beyond the gate (1 mm behind the raw surface): none.
  EXPECT_EQ(view_region_errors(plane_model(camera, 0.0, 1.0f), raw, camera, Pose()).visible_points, 0u);
  EXPECT_EQ(view_region_errors(plane_model(camera, 1e-3), raw, camera, Pose()).visible_points, 0u);
  const ViewRegionErrors errors = view_region_errors(plane_model(camera, 20e-6), raw, camera, Pose());
  EXPECT_EQ(errors.regions[0].to_raw_scan.count, 0u);
  EXPECT_EQ(errors.regions[3].to_raw_scan.count, 300u);
  EXPECT_EQ(errors.visible_points, 900u);
  EXPECT_EQ(errors.all.to_surface.count, 0u);  // no scene given
  // Within the gate, a point's distance is not bounded by it: 200 µm off is 200 µm.
  EXPECT_NEAR(view_region_errors(plane_model(camera, 200e-6), raw, camera, Pose()).all.to_raw_scan.mean_m, 200e-6,
              0.01 * kUm);
}

TEST(ViewRegionErrors, TheNearestRawPointMayLieToTheSide) {
  // The raw scan is a plane tilted 45° about y: for a model point off it along the optical axis,
  // the nearest raw point is not on its own pixel (distance = offset · cos 45°, reached three
  // pixels to the side when the pixels are 5 µm apart).
  CameraIntrinsics camera = test_camera();
  camera.fx = camera.fy = 20000.0;
  const RayMap rays = compute_ray_map(camera);
  Image32f raw(camera.width, camera.height);
  PointCloud model;
  const double offset = 30e-6;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Vec3f& ray = rays.ray(x, y);
      // z = kDepth + x_world: along the ray (ray.x * z, ray.y * z, z), z = kDepth / (1 - ray.x).
      const double z = kDepth / (1.0 - static_cast<double>(ray.x));
      raw(x, y) = static_cast<float>(z);
      const double x_m = static_cast<double>(ray.x) * z;
      const double y_m = static_cast<double>(ray.y) * z;
      model.positions.emplace_back(static_cast<float>(x_m), static_cast<float>(y_m), static_cast<float>(z + offset));
      model.normals.emplace_back(std::sqrt(0.5f), 0.0f, -std::sqrt(0.5f));
    }
  }
  const ViewRegionErrors errors = view_region_errors(model, raw, camera, Pose());
  EXPECT_EQ(errors.visible_points, 1200u);
  // (The image's outer three columns lack the neighbour on one side: a little farther.)
  EXPECT_NEAR(errors.all.to_raw_scan.mean_m, offset * std::sqrt(0.5), 0.5 * kUm);
}

TEST(ViewRegionErrors, BadInputIsAClearError) {
  const CameraIntrinsics camera = test_camera();
  PointCloud no_normals = plane_model(camera, 0.0);
  no_normals.normals.clear();
  const Image32f raw(camera.width, camera.height, static_cast<float>(kDepth));
  EXPECT_THROW(view_region_errors(no_normals, raw, camera, Pose()), Error);
  EXPECT_THROW(view_region_errors(plane_model(camera, 0.0), Image32f(10, 10, 0.1f), camera, Pose()), Error);
  RegionOptions options;
  options.visibility_gate_m = 0.0;
  EXPECT_THROW(view_region_errors(plane_model(camera, 0.0), raw, camera, Pose(), nullptr, Pose(), options), Error);
}

}  // namespace
}  // namespace sls::eval
