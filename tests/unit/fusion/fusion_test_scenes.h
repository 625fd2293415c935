// Synthetic depth frames with exact geometry for the fusion tests (nvblox style): a small
// pinhole camera with a little distortion looking down +z at a plane or a 90° ridge.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include "fusion/integrator.h"
#include "fusion/volume.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/image.h"
#include "sdk/core/ray_map.h"

namespace sls::fusion::test {

// Floats in [0, 1) from a linear congruential generator: the same sequence on every platform
// and compiler (std's distributions are not), for volumes filled at random.
class UnitRandom {
 public:
  explicit UnitRandom(std::uint32_t seed) : state_(seed) {}
  float operator()() {
    state_ = state_ * 1664525u + 1013904223u;
    return static_cast<float>(state_ >> 8) / 16777216.0f;
  }

 private:
  std::uint32_t state_;
};

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

// The guided-raycast scene: a compact CPU volume with three noisy frames of a ridge fused
// from the origin, the last frame as the guide with a hole three tiles wide (a shadow), and
// the camera at full and half size.
struct GuidedRaycastScene {
  CameraIntrinsics camera;
  CameraIntrinsics half;
  VolumeGeometry geometry;
  Volume volume;
  Image32f guide;
};

inline GuidedRaycastScene guided_raycast_scene() {
  CameraIntrinsics camera = small_camera(320, 240);
  camera.fx = camera.fy = 6400.0;
  CameraIntrinsics half = camera;
  half.width /= 2;
  half.height /= 2;
  half.fx /= 2.0;
  half.fy /= 2.0;
  half.cx = 0.5 * (half.width - 1);
  half.cy = 0.5 * (half.height - 1);
  const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, 0.102), 96, 80, 96, 62.5e-6);
  GuidedRaycastScene scene{camera, half, geometry, Volume(geometry, VoxelFormat::kCompact, Device::cpu(), AverageStorage::kSeparate), Image32f()};
  Integrator integrator(Device::cpu(), IntegrationOptions::gtsdf());
  for (std::uint32_t n = 0; n < 3; ++n) {
    scene.guide = ridge_depth(camera, 0.1, 20e-6, 11 + n);
    integrator.integrate(scene.volume, scene.guide, camera, Pose());
  }
  for (int y = 100; y < 140; ++y) {
    for (int x = 40; x < 90; ++x) scene.guide(x, y) = 0.0f;
  }
  return scene;
}

// A GTSDF volume's running average A against a reference volume's U (e.g. TSDF's), voxel by
// voxel: weights must be equal everywhere; over the observed voxels, how many A differ from
// the reference's U (bits, through float) and how many from the volume's own U.
struct AverageComparison {
  std::size_t observed = 0, weight_differs = 0, average_differs = 0, differs_from_own_u = 0;
};

inline AverageComparison compare_average(const VolumeView& with_average, const VolumeView& reference) {
  AverageComparison c;
  for (std::size_t i = 0; i < with_average.voxel_count(); ++i) {
    c.weight_differs += with_average.w(i) != reference.w(i) ? 1u : 0u;
    if (!(with_average.w(i) > 0.0f)) continue;
    ++c.observed;
    c.average_differs += with_average.average(i) != reference.u(i) ? 1u : 0u;
    c.differs_from_own_u += with_average.u(i) != with_average.average(i) ? 1u : 0u;
  }
  return c;
}

}  // namespace sls::fusion::test
