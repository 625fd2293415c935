// The moving volume tests' scene (test_moving_volume.cpp, test_moving_volume_cuda.cpp): a
// 96³ volume of 50 µm voxels placed by a camera 5 cm away, holding the exact truncated SDF of
// a sphere (U = clamp(d / δ, -1, 1), δ = 4 voxels), and the camera poses it moves to.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <vector>

#include <Eigen/Geometry>

#include "fusion/moving_volume.h"
#include "fusion/volume.h"
#include "sdk/core/pose.h"

namespace sls::fusion::test {

constexpr int kCount = 96;
constexpr double kVoxel = 50e-6;
constexpr double kDelta = 4.0 * kVoxel;  // the truncation δ
constexpr double kFocus = 0.05;

struct Sphere {
  Eigen::Vector3d centre;
  double radius;
  double operator()(const Eigen::Vector3d& p) const { return (p - centre).norm() - radius; }
};

inline MovingVolumeOptions scene_options() {
  MovingVolumeOptions options;
  options.focus_distance_m = kFocus;
  return options;
}

// The first camera: turned and moved off the world axes, so every transform is exercised.
inline Pose first_camera() {
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()).toRotationMatrix();
  return Pose(rotation, Eigen::Vector3d(0.001, -0.002, 0.0005));
}

// A camera turned by `angle_deg` about `axis` through its focus point and moved by
// `translation_m` (both in `from`'s camera frame): the volume it places moves by exactly that.
inline Pose moved_camera(const Pose& from, const Eigen::Vector3d& translation_m, double angle_deg,
                         const Eigen::Vector3d& axis) {
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(angle_deg * 3.14159265358979323846 / 180.0, axis.normalized())
                                   .toRotationMatrix();
  const Eigen::Vector3d focus(0.0, 0.0, kFocus);
  return from * Pose(turn, focus - turn * focus + translation_m);
}

// A sphere of radius 1.3 mm (26 voxels) near the first camera's focus point, off the grid.
inline Sphere scene_sphere() {
  const Eigen::Vector3d focus = first_camera() * Eigen::Vector3d(0.0, 0.0, kFocus);
  return Sphere{focus + Eigen::Vector3d(0.13e-3, -0.21e-3, 0.17e-3), 1.3e-3};
}

inline Eigen::Vector3d voxel_world(const VolumeGeometry& g, int i, int j, int k) {
  return g.T_world_volume * (Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) * g.voxel_size_m);
}

// Fills a CPU volume with the sphere's truncated SDF: every voxel observed (`band` false) or
// only those within δ of the surface (`band` true, as the integrator leaves them). Weights
// 1 + (i + j + k) % weight_cycle. Flags the surface bricks as the integrator would.
inline void fill_sphere(Volume* volume, const Sphere& sphere, bool band, int weight_cycle = 1) {
  const VolumeGeometry& g = volume->geometry();
  const VolumeView view = volume->view();
  std::fill(view.surface_bricks, view.surface_bricks + view.brick_count(), std::uint8_t{0});
  for (int k = 0; k < g.nz; ++k) {
    for (int j = 0; j < g.ny; ++j) {
      for (int i = 0; i < g.nx; ++i) {
        const double d = sphere(voxel_world(g, i, j, k));
        const std::size_t index = view.index(i, j, k);
        const bool observed = !band || std::fabs(d) < kDelta;
        const float u = static_cast<float>(std::clamp(d / kDelta, -1.0, 1.0));
        view.set_u(index, observed ? u : 0.0f);
        view.set_w(index, observed ? static_cast<float>(1 + (i + j + k) % weight_cycle) : 0.0f);
        if (observed && std::fabs(u) < 1.0f) view.mark_surface(i, j, k);
      }
    }
  }
}

// The grid coordinates (voxel centres at integers) of a world point in a volume.
inline Eigen::Vector3d grid_of(const VolumeGeometry& g, const Eigen::Vector3d& world) {
  return g.T_world_volume.inverse() * world / g.voxel_size_m - Eigen::Vector3d::Constant(0.5);
}

// Whether a grid point lies in the hull of the voxel centres (tolerance in voxels).
inline bool in_sample_box(const VolumeGeometry& g, const Eigen::Vector3d& grid, double tolerance) {
  const double counts[3] = {static_cast<double>(g.nx), static_cast<double>(g.ny), static_cast<double>(g.nz)};
  for (int axis = 0; axis < 3; ++axis) {
    if (grid[axis] < -tolerance || grid[axis] > counts[axis] - 1.0 + tolerance) return false;
  }
  return true;
}

// The brick flags the stored voxels call for: bricks within one voxel of an observed voxel
// with |U| < 1.
inline std::vector<std::uint8_t> expected_bricks(const VolumeView& v) {
  std::vector<std::uint8_t> flags(v.brick_count(), 0u);
  VolumeView marker = v;
  marker.surface_bricks = flags.data();
  for (int k = 0; k < v.nz; ++k) {
    for (int j = 0; j < v.ny; ++j) {
      for (int i = 0; i < v.nx; ++i) {
        const std::size_t index = v.index(i, j, k);
        if (v.w(index) > 0.0f && std::fabs(v.u(index)) < 1.0f) marker.mark_surface(i, j, k);
      }
    }
  }
  return flags;
}

// Fills every voxel with a deterministic pseudo-random U in [-1, 1) and W (1 in 8 unobserved):
// a field dense with crossings, for the "move everything out" tests.
inline void fill_random_field(const VolumeView& v, std::uint32_t seed) {
  std::uint32_t state = seed;
  for (std::size_t n = 0; n < v.voxel_count(); ++n) {
    state = state * 1664525u + 1013904223u;
    v.set_u(n, static_cast<float>(state >> 8) / 8388608.0f - 1.0f);
    v.set_w(n, (state & 7u) == 0u ? 0.0f : static_cast<float>(1u + (state >> 28)));
  }
}

// The random field's volume moved part way (0.6 mm and 7 degrees about an oblique axis): every
// kind of cell leaves, rim cells whose vertices lie across the border among them.
inline Pose partial_move_camera() {
  return moved_camera(first_camera(), Eigen::Vector3d(0.6e-3, 0.4e-3, -0.3e-3), 7.0, Eigen::Vector3d(1.0, -0.5, 2.0));
}

// Moving volumes of one random field (seed 4242), placed at first_camera(): the first's filled,
// the others copies of it (of any device).
inline void place_random_field(MovingVolume* first, std::initializer_list<MovingVolume*> copies) {
  first->place(first_camera());
  fill_random_field(first->volume().view(), 4242u);
  for (MovingVolume* copy : copies) {
    copy->place(first_camera());
    copy->volume().copy_from(first->volume());
  }
}

}  // namespace sls::fusion::test
