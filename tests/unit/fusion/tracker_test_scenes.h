// Exact scenes for the tracker tests (nvblox style): a base plane facing the camera with
// spherical caps of several sizes standing out of it (the plane fixes depth and tilt, the
// caps' flanks the lateral shifts and the roll about the optical axis: all 6 DoF). The model
// Volume holds the closed-form truncated distance of the union; live depth maps are exact
// ray casts of the same analytic shape through the camera's ray map (so with its distortion).
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/raycaster.h"
#include "fusion/volume.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/error.h"
#include "sdk/core/image.h"
#include "sdk/core/pose.h"
#include "sdk/core/ray_map.h"

namespace sls::fusion::test {

// The same pose bit for bit (Pose::is_approx with tolerance 0 is not: the angle of a⁻¹·a can
// round to a few 1e-8 rad).
inline bool same_pose(const Pose& a, const Pose& b) {
  return a.translation() == b.translation() && a.rotation() == b.rotation();
}

// `call` throws sls::Error(kInvalidArgument) whose message holds `fragment`.
inline void expect_invalid(const std::function<void()>& call, const std::string& fragment) {
  try {
    call();
    ADD_FAILURE() << "no error; expected one mentioning '" << fragment << "'";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument) << error.what();
    EXPECT_NE(std::string(error.what()).find(fragment), std::string::npos) << error.what();
  }
}

constexpr double kWorkingDistance = 0.1;  // m, the scanner's
constexpr double kVoxel = 50e-6;          // m: 1.35 pixel footprints at 0.1 m with fx = 2700
constexpr double kTruncationVoxels = 4.0;  // δ of the fill and of RaycastOptions

// 320x240, fx = 2700: 37 um pixels at 0.1 m, a 11.9 x 8.9 mm field, a little distortion.
inline CameraIntrinsics tracker_camera(int width = 320, int height = 240) {
  CameraIntrinsics c;
  c.width = width;
  c.height = height;
  c.fx = c.fy = 2700.0 * width / 320.0;
  c.cx = 0.5 * (width - 1) + 0.7;
  c.cy = 0.5 * (height - 1) - 0.4;
  c.k1 = -0.05;
  c.k2 = 0.02;
  c.p1 = 1e-4;
  c.p2 = -5e-5;
  return c;
}

struct Cap {
  Eigen::Vector3d centre;  // world
  double radius;
};

// The union of the half-space z >= plane_z (world) and the balls; the camera looks along +z.
struct BumpyScene {
  double plane_z = kWorkingDistance + 0.6e-3;
  std::vector<Cap> caps;
  bool with_caps = true;

  // Positive outside (towards the camera), metres; exact outside, a bound inside.
  double sdf(const Eigen::Vector3d& p) const {
    double d = plane_z - p.z();
    if (with_caps) {
      for (const Cap& cap : caps) d = std::min(d, (p - cap.centre).norm() - cap.radius);
    }
    return d;
  }
  // The first surface point along origin + t * direction (t > 0), or infinity.
  double first_hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) const {
    double best = std::numeric_limits<double>::infinity();
    if (direction.z() > 0.0) best = (plane_z - origin.z()) / direction.z();
    if (!with_caps) return best > 0.0 ? best : std::numeric_limits<double>::infinity();
    const double a = direction.squaredNorm();
    for (const Cap& cap : caps) {
      const Eigen::Vector3d oc = origin - cap.centre;
      const double b = oc.dot(direction);
      const double c = oc.squaredNorm() - cap.radius * cap.radius;
      const double discriminant = b * b - a * c;
      if (discriminant < 0.0) continue;
      const double t = (-b - std::sqrt(discriminant)) / a;
      if (t > 0.0) best = std::min(best, t);
    }
    return best;
  }
};

// Six caps of 0.7..2 mm radius standing 0.35..0.9 mm out of the plane, placed irregularly.
inline BumpyScene bumpy_scene() {
  BumpyScene scene;
  const double z = scene.plane_z;
  struct Spec {
    double x_mm, y_mm, radius_mm, height_mm;
  };
  for (const Spec& s : {Spec{-3.5, -2.0, 1.2, 0.6}, Spec{2.8, -2.5, 1.6, 0.9}, Spec{0.5, 1.8, 2.0, 0.7},
                        Spec{-2.2, 2.6, 0.9, 0.5}, Spec{4.0, 2.2, 1.1, 0.8}, Spec{-0.8, -0.6, 0.7, 0.35}}) {
    scene.caps.push_back(Cap{Eigen::Vector3d(s.x_mm * 1e-3, s.y_mm * 1e-3, z + (s.radius_mm - s.height_mm) * 1e-3),
                             s.radius_mm * 1e-3});
  }
  return scene;
}

inline BumpyScene plane_scene() {
  BumpyScene scene;
  scene.with_caps = false;
  return scene;
}

// 16 x 12.8 x 2.4 mm around the scene (320 x 256 x 48 voxels of 50 um).
inline VolumeGeometry scene_volume(const BumpyScene& scene) {
  return VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, scene.plane_z - 0.6e-3), 320, 256, 48, kVoxel);
}

// A volume that holds a small part of the view (4.8 x 4 x 2.4 mm: 18 % of the live pixels
// see into it): a GPU memory budget's small volume.
inline VolumeGeometry small_scene_volume(const BumpyScene& scene) {
  return VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, scene.plane_z - 0.6e-3), 96, 80, 48, kVoxel);
}

// The model volume: U = clamp(sdf / δ, -1, 1), W = 1 everywhere, bricks flagged where |U| < 1.
inline void fill_volume(Volume* volume, const BumpyScene& scene) {
  const VolumeGeometry& g = volume->geometry();
  const VolumeView view = volume->view();
  const double delta = kTruncationVoxels * g.voxel_size_m;
  for (int k = 0; k < g.nz; ++k) {
    for (int j = 0; j < g.ny; ++j) {
      for (int i = 0; i < g.nx; ++i) {
        const Eigen::Vector3d p = g.T_world_volume * (Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) * g.voxel_size_m);
        const double u = std::clamp(scene.sdf(p) / delta, -1.0, 1.0);
        const std::size_t index = view.index(i, j, k);
        view.set_u(index, static_cast<float>(u));
        view.set_w(index, 1.0f);
        if (std::fabs(u) < 1.0) view.mark_surface(i, j, k);
      }
    }
  }
}

// The exact depth map of the scene seen from T_world_camera (camera-frame z; 0 = no hit or
// beyond max_depth), through the camera's ray map.
inline Image32f exact_depth(const BumpyScene& scene, const CameraIntrinsics& camera, const Pose& T_world_camera,
                            double max_depth_m = 1.0) {
  const RayMap rays = compute_ray_map(camera);
  Image32f depth(camera.width, camera.height, 0.0f);
  const Eigen::Matrix3d r = T_world_camera.rotation();
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      if (!rays.is_valid(x, y)) continue;
      const Vec3f ray = rays.ray(x, y);
      const Eigen::Vector3d direction = r * Eigen::Vector3d(ray.x, ray.y, ray.z);
      const double t = scene.first_hit(T_world_camera.translation(), direction);
      if (t < max_depth_m) depth(x, y) = static_cast<float>(t);  // ray.z = 1: t is the depth
    }
  }
  return depth;
}

// The model camera: near the scene's axis, a little turned, so no frame is the identity.
inline Pose model_pose() {
  Vector6d twist;
  twist << 0.2e-3, -0.15e-3, 0.0, 0.004, -0.006, 0.1;
  return Pose::exp(twist);
}

// A motion of the camera in its own frame by `rotation_deg` about `axis` through the point
// `pivot_m` ahead on the optical axis (the scanner turns about what it looks at), plus
// `translation`: T_world_live = T_world_model · motion.
inline Pose camera_motion(const Eigen::Vector3d& translation, const Eigen::Vector3d& axis, double rotation_deg,
                          double pivot_m = kWorkingDistance) {
  const Pose pivot(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, pivot_m));
  const Pose turn(Eigen::Quaterniond(Eigen::AngleAxisd(rotation_deg * M_PI / 180.0, axis.normalized())),
                  Eigen::Vector3d::Zero());
  return Pose(Eigen::Quaterniond::Identity(), translation) * pivot * turn * pivot.inverse();
}

// 0.3 mm and 1.5° about an oblique axis through the focus point (the camera centre moves
// 0.97 mm; the surface 0.32 mm RMS, 0.43 mm at most).
inline Pose test_motion() {
  return camera_motion(Eigen::Vector3d(0.18e-3, -0.144e-3, 0.192e-3), Eigen::Vector3d(0.3, -0.2, 0.93), 1.5);
}

// The model of a scene seen from model_pose(): the filled volume (CPU) and its raycast.
struct Model {
  CameraIntrinsics camera;
  BumpyScene scene;
  Pose T_world_model = model_pose();
  Volume volume;
  RaycastResult raycast;

  static RaycastOptions raycast_options() {
    RaycastOptions options;
    options.truncation_voxels = kTruncationVoxels;
    return options;
  }
  explicit Model(const BumpyScene& s, const CameraIntrinsics& c = tracker_camera(),
                 const VolumeGeometry* geometry = nullptr)
      : camera(c), scene(s), volume(geometry != nullptr ? *geometry : scene_volume(s), VoxelFormat::kFloat32,
                                    Device::cpu()) {
    fill_volume(&volume, scene);
    Raycaster raycaster(Device::cpu(), camera, raycast_options());
    raycast = raycaster.raycast(volume, T_world_model);
  }
};

// The bumpy scene's model, made once per test executable.
inline const Model& bumpy_model() {
  static const Model model(bumpy_scene());
  return model;
}

inline double degrees(double radians) { return radians * 180.0 / M_PI; }

// The error of a registration where it matters: how far the live frame's surface points land
// from where they belong (RMS and max over the live depth map, in metres).
struct SurfaceError {
  double rms_m = 0.0;
  double max_m = 0.0;
};
inline SurfaceError surface_error(const Image32f& depth, const CameraIntrinsics& camera, const Pose& estimate,
                                  const Pose& truth) {
  const RayMap rays = compute_ray_map(camera);
  const Pose difference = estimate * truth.inverse();  // identity when exact, applied to world points
  SurfaceError error;
  double sum = 0.0;
  std::size_t n = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const float z = depth(x, y);
      if (!(z > 0.0f)) continue;
      const Vec3f ray = rays.ray(x, y);
      const Eigen::Vector3d p = truth * (Eigen::Vector3d(ray.x, ray.y, ray.z) * static_cast<double>(z));
      const double e = (difference * p - p).norm();
      sum += e * e;
      error.max_m = std::max(error.max_m, e);
      ++n;
    }
  }
  error.rms_m = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
  return error;
}

// A live depth map whose left third carries a systematic error (a decoder's bias where it is
// least sure) with a low confidence there: `live` is `exact` with bias_m added in the band,
// `confidence` is band_confidence in the band and elsewhere 1 (or, with vary, 0.5 .. 1 in a
// fixed pattern, so a pyramid's block means differ from pixel to pixel), `trusted` is
// `exact` without the band (to measure the registration on).
struct BiasedBand {
  Image32f live, confidence, trusted;
};
inline BiasedBand biased_band(const Image32f& exact, float bias_m, float band_confidence, bool vary = false) {
  BiasedBand out{exact, Image32f(exact.width(), exact.height()), exact};
  for (int y = 0; y < exact.height(); ++y) {
    for (int x = 0; x < exact.width(); ++x) {
      const bool band = x < exact.width() / 3;
      if (band && exact(x, y) > 0.0f) out.live(x, y) += bias_m;
      if (band) out.trusted(x, y) = 0.0f;
      const float elsewhere = vary ? 0.5f + 0.5f * static_cast<float>((7 * x + 13 * y) % 11) / 10.0f : 1.0f;
      out.confidence(x, y) = band ? band_confidence : elsewhere;
    }
  }
  return out;
}

}  // namespace sls::fusion::test
