// Synthetic depth frames with exact geometry for the fusion tests (nvblox style): a small
// pinhole camera with a little distortion looking down +z at a plane or a 90° ridge.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include "fusion/volume.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/image.h"
#include "sdk/core/ray_map.h"

namespace sls::fusion::test {

inline CameraIntrinsics small_camera(int width = 160, int height = 120) {
  CameraIntrinsics c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = 2.0 * width;  // a narrow field like the scanner's
  c.cx = 0.5 * (width - 1);
  c.cy = 0.5 * (height - 1);
  c.k1 = -0.05;
  c.p1 = 1e-4;
  return c;
}

// Camera-frame depth of a fronto-parallel plane at z = plane_z, plus Gaussian noise.
inline Image32f plane_depth(const CameraIntrinsics& camera, double plane_z, double noise_sigma_m = 0.0,
                            std::uint32_t seed = 1) {
  Image32f depth(camera.width, camera.height, static_cast<float>(plane_z));
  if (noise_sigma_m > 0.0) {
    std::mt19937 generator(seed);
    std::normal_distribution<double> noise(0.0, noise_sigma_m);
    for (std::size_t i = 0; i < depth.pixel_count(); ++i) {
      depth.data()[i] = static_cast<float>(plane_z + noise(generator));
    }
  }
  return depth;
}

// A ridge along the camera's y axis: z = apex_z + |x| (two faces at 45° to the view, a 90°
// crease), as the knurl's teeth; depth along each pixel's ray, plus noise.
inline Image32f ridge_depth(const CameraIntrinsics& camera, double apex_z, double noise_sigma_m, std::uint32_t seed) {
  const RayMap rays = compute_ray_map(camera);
  Image32f depth(camera.width, camera.height, 0.0f);
  std::mt19937 generator(seed);
  std::normal_distribution<double> noise(0.0, noise_sigma_m > 0.0 ? noise_sigma_m : 1.0);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      if (!rays.is_valid(x, y)) continue;
      const double rx = static_cast<double>(rays.ray(x, y).x);
      // z = apex + |rx z|  ->  z (1 - |rx|) = apex
      const double z = apex_z / (1.0 - std::fabs(rx));
      depth(x, y) = static_cast<float>(z + (noise_sigma_m > 0.0 ? noise(generator) : 0.0));
    }
  }
  return depth;
}

}  // namespace sls::fusion::test
