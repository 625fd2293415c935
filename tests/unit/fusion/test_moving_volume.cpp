// The moving, rotating RPV (fusion/moving_volume.h) on the CPU against synthetic ground truth:
// a volume holding the exact truncated SDF of a sphere is moved by a translation and a
// rotation; the resampled voxels must match the SDF at their new centres (trilinear error
// bound), a move by whole voxels must copy voxels bit for bit, the shipped surface must lie on
// the sphere outside the new volume and, with the new volume's surface, cover the old one
// without a gap or an overlap; follow() must move exactly when its rule says; the brick flags
// must let a raycast of the moved volume see what a freshly filled one shows; a GTSDF
// volume's running average must move exactly as its U does.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <unordered_map>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/extract.h"
#include "fusion/moving_volume.h"
#include "fusion/raycaster.h"
#include "fusion/resample_shared.h"
#include "sdk/core/error.h"
#include "tests/support/process_memory.h"
#include "tests/unit/fusion/fusion_test_scenes.h"
#include "tests/unit/fusion/moving_volume_scene.h"

namespace sls::fusion {
namespace {

using test::kCount;
using test::kDelta;
using test::kVoxel;

class MovingVolumeTest : public ::testing::TestWithParam<VoxelFormat> {};

// Half of binary16's spacing just below 1 (2^-11): the rounding of one stored U.
constexpr double kHalfRounding = 1.0 / 4096.0;

double quantisation(VoxelFormat format) {
  // Old U stored, new U stored (compact), plus float arithmetic on centimetre coordinates.
  return (format == VoxelFormat::kCompact ? 2.0 * kHalfRounding : 0.0) + 2e-5;
}

// The move of the accuracy and shipping tests: 1.3 mm, -0.8 mm, 0.5 mm and 10° about a
// skew axis (camera frame): part of the sphere leaves, part of the new volume is new space.
Pose big_move_camera() {
  return test::moved_camera(test::first_camera(), Eigen::Vector3d(1.3e-3, -0.8e-3, 0.5e-3), 10.0,
                            Eigen::Vector3d(0.3, -1.0, 0.5));
}

MovingVolume make_filled(VoxelFormat format, bool band, int weight_cycle) {
  MovingVolume moving(kCount, kCount, kCount, kVoxel, format, Device::cpu(), test::scene_options());
  moving.place(test::first_camera());
  test::fill_sphere(&moving.volume(), test::scene_sphere(), band, weight_cycle);
  return moving;
}

// Every new voxel against the SDF at its centre. Bounds (U in units of δ):
//  - all 8 old corners observed and unclamped (|d| < δ): the trilinear interpolation error of
//    the sphere's SDF, h²/8 · Σ_axes max |∂²d/∂x_a²| / δ <= 3 h² / (8 ρ δ), ρ the distance to the
//    sphere's centre less a cell diagonal (the Hessian of |p - c| has eigenvalues 0, 1/ρ, 1/ρ);
//  - otherwise (clamped corners, or the rim of the old volume where unobserved corners drop
//    out of the renormalised average): U is a weighted mean of corner values clamp(d_c / δ),
//    clamp is 1-Lipschitz and every corner lies within √3 h of the centre, so |ΔU| <= √3 h / δ.
TEST_P(MovingVolumeTest, ResampledVoxelsMatchTheAnalyticSdf) {
  const VoxelFormat format = GetParam();
  MovingVolume moving = make_filled(format, false, 1);
  const test::Sphere sphere = test::scene_sphere();
  const VolumeGeometry old_geometry = moving.volume().geometry();
  const MoveStats stats = moving.move_to(moving.placement(big_move_camera()));
  ASSERT_TRUE(stats.moved);
  const VolumeGeometry& g = moving.volume().geometry();
  const VolumeView v = moving.volume().view();
  const double q = quantisation(format);
  std::size_t inner = 0, rim = 0, unobserved = 0, outside = 0, tight = 0;
  double worst_tight = 0.0, worst_tight_ratio = 0.0, worst_loose = 0.0;
  for (int k = 0; k < g.nz; ++k) {
    for (int j = 0; j < g.ny; ++j) {
      for (int i = 0; i < g.nx; ++i) {
        const std::size_t index = v.index(i, j, k);
        const Eigen::Vector3d p = test::voxel_world(g, i, j, k);
        const Eigen::Vector3d old_grid = test::grid_of(old_geometry, p);
        const double d = sphere(p);
        const double truth = std::clamp(d / kDelta, -1.0, 1.0);
        if (!test::in_sample_box(old_geometry, old_grid, 0.5 + 1e-4)) {
          ++outside;  // the old volume never reached here
          ASSERT_EQ(v.w(index), 0.0f) << "voxel " << i << " " << j << " " << k << " outside the old volume";
          continue;
        }
        if (!(v.w(index) > 0.0f)) {
          ++unobserved;
          // Only at the old volume's rim (the support rule drops corners beyond its box).
          ASSERT_FALSE(test::in_sample_box(old_geometry, old_grid, -1e-4)) << i << " " << j << " " << k;
          continue;
        }
        ASSERT_EQ(v.w(index), 1.0f);  // every old voxel had weight 1
        const double error = std::fabs(static_cast<double>(v.u(index)) - truth);
        const bool full = test::in_sample_box(old_geometry, old_grid, -1e-4);
        const double rho = (p - sphere.centre).norm() - std::sqrt(3.0) * kVoxel;
        const bool unclamped = std::fabs(d) + std::sqrt(3.0) * kVoxel < kDelta;
        if (full) ++inner; else ++rim;
        if (full && unclamped) {
          ++tight;
          const double bound = 3.0 * kVoxel * kVoxel / (8.0 * rho * kDelta) + q;
          worst_tight = std::max(worst_tight, error);
          worst_tight_ratio = std::max(worst_tight_ratio, error / bound);
          ASSERT_LE(error, bound) << "voxel " << i << " " << j << " " << k;
        } else {
          worst_loose = std::max(worst_loose, error);
          ASSERT_LE(error, std::sqrt(3.0) * kVoxel / kDelta + q) << "voxel " << i << " " << j << " " << k;
        }
      }
    }
  }
  std::printf("[moving] %s resample: %.2f mm %.1f deg in %.1f ms; %zu full-support voxels (%zu unclamped: worst "
              "|dU| %.2e = %.2f of the bound), %zu rim voxels, worst clamped/rim |dU| %.3f, %zu unobserved at the "
              "rim, %zu new space\n",
              voxel_format_name(format), stats.translation_m * 1e3, stats.rotation_deg, stats.resample_ms, inner,
              tight, worst_tight, worst_tight_ratio, rim, worst_loose, unobserved, outside);
  EXPECT_GT(tight, 10000u);
  EXPECT_GT(outside, 10000u);
  EXPECT_NEAR(stats.rotation_deg, 10.0, 1e-6);
}

// A move by whole voxels without rotation: every voxel is the old one shifted, bit for bit,
// weights included; new space unobserved; brick flags exactly what the voxels call for.
TEST_P(MovingVolumeTest, WholeVoxelTranslationCopiesVoxelsExactly) {
  const VoxelFormat format = GetParam();
  MovingVolume moving = make_filled(format, true, 9);
  const Volume before = moving.volume().to_host();
  const Pose T_old = before.geometry().T_world_volume;
  const int shift[3] = {5, -3, 7};
  moving.move_to(T_old * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(shift[0], shift[1], shift[2]) * kVoxel));
  const VolumeView a = before.view(), b = moving.volume().view();
  std::size_t copied = 0, fresh = 0, mismatched = 0;
  for (int k = 0; k < kCount; ++k) {
    for (int j = 0; j < kCount; ++j) {
      for (int i = 0; i < kCount; ++i) {
        const std::size_t to = b.index(i, j, k);
        const int oi = i + shift[0], oj = j + shift[1], ok = k + shift[2];
        if (!a.contains(oi, oj, ok) || !(a.w(a.index(oi, oj, ok)) > 0.0f)) {
          fresh += a.contains(oi, oj, ok) ? 0u : 1u;
          mismatched += b.w(to) != 0.0f ? 1u : 0u;
          continue;
        }
        ++copied;
        const std::size_t from = a.index(oi, oj, ok);
        const bool same = format == VoxelFormat::kFloat32
                              ? std::memcmp(&a.u32[from], &b.u32[to], sizeof(float)) == 0 && a.w32[from] == b.w32[to]
                              : a.u16[from] == b.u16[to] && a.w8[from] == b.w8[to];
        mismatched += same ? 0u : 1u;
      }
    }
  }
  std::printf("[moving] %s whole-voxel move: %zu observed voxels copied, %zu new, %zu differ\n",
              voxel_format_name(format), copied, fresh, mismatched);
  EXPECT_GT(copied, 50000u);
  EXPECT_GT(fresh, 100000u);
  EXPECT_EQ(mismatched, 0u);
  const std::vector<std::uint8_t> expected = test::expected_bricks(b);
  EXPECT_TRUE(std::equal(expected.begin(), expected.end(), b.surface_bricks));
}

// A GTSDF volume's running average A moves with it, resampled exactly as U is: A holds the
// SDF of a sphere δ/2 larger than U's, and after the big move (rotation included) it equals,
// bit for bit, the U of a plain volume that held that larger sphere and made the same move.
TEST_P(MovingVolumeTest, RunningAverageMovesExactlyAsUDoes) {
  const VoxelFormat format = GetParam();
  MovingVolume gtsdf(kCount, kCount, kCount, kVoxel, format, Device::cpu(), test::scene_options(),
                     AverageStorage::kSeparate);
  MovingVolume reference(kCount, kCount, kCount, kVoxel, format, Device::cpu(), test::scene_options());
  gtsdf.place(test::first_camera());
  reference.place(test::first_camera());
  test::Sphere larger = test::scene_sphere();
  larger.radius += 0.5 * kDelta;
  test::fill_sphere(&gtsdf.volume(), test::scene_sphere(), true, 3);
  test::fill_sphere(&reference.volume(), larger, true, 3);
  {
    // The band of the larger sphere differs: observed where either is; A from the larger one.
    const VolumeView g = gtsdf.volume().view(), r = reference.volume().view();
    for (std::size_t i = 0; i < g.voxel_count(); ++i) {
      if (!(g.w(i) > 0.0f) || !(r.w(i) > 0.0f)) {
        g.set_w(i, 0.0f);
        r.set_w(i, 0.0f);
      }
      g.set_average(i, r.u(i));
    }
  }
  ASSERT_TRUE(gtsdf.move_to(gtsdf.placement(big_move_camera())).moved);
  ASSERT_TRUE(reference.move_to(reference.placement(big_move_camera())).moved);
  ASSERT_TRUE(gtsdf.volume().view().keeps_average());
  ASSERT_FALSE(reference.volume().view().keeps_average());
  const test::AverageComparison c = test::compare_average(gtsdf.volume().view(), reference.volume().view());
  std::printf("[moving] %s running average: %zu observed voxels after the move, %zu differ from the reference "
              "volume's U, %zu from their own U, %zu weights differ\n",
              voxel_format_name(format), c.observed, c.average_differs, c.differs_from_own_u, c.weight_differs);
  EXPECT_GT(c.observed, 50000u);
  EXPECT_EQ(c.weight_differs, 0u);
  EXPECT_EQ(c.average_differs, 0u);
  EXPECT_GT(c.differs_from_own_u, c.observed / 2);  // A was not overwritten by U
}

// A spatial hash of points in cells of one voxel, for "is there a point within r <= 1 voxel".
class PointIndex {
 public:
  explicit PointIndex(double cell) : cell_(cell) {}
  void add(const Eigen::Vector3d& p) {
    points_.push_back(p);
    cells_[key(p, 0, 0, 0)].push_back(points_.size() - 1);
  }
  double nearest(const Eigen::Vector3d& p) const {
    double best = std::numeric_limits<double>::infinity();
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const auto found = cells_.find(key(p, dx, dy, dz));
          if (found == cells_.end()) continue;
          for (const std::size_t n : found->second) best = std::min(best, (points_[n] - p).norm());
        }
      }
    }
    return best;  // exact when below one cell
  }

 private:
  std::int64_t key(const Eigen::Vector3d& p, int dx, int dy, int dz) const {
    const auto x = static_cast<std::int64_t>(std::floor(p.x() / cell_)) + dx + (1 << 20);
    const auto y = static_cast<std::int64_t>(std::floor(p.y() / cell_)) + dy + (1 << 20);
    const auto z = static_cast<std::int64_t>(std::floor(p.z() / cell_)) + dz + (1 << 20);
    return (x << 42) | (y << 21) | z;
  }
  double cell_;
  std::vector<Eigen::Vector3d> points_;
  std::unordered_map<std::int64_t, std::vector<std::size_t>> cells_;
};

TEST_P(MovingVolumeTest, ShippedSurfaceLeavesAndCoversTheOldOneWithoutGapOrOverlap) {
  const VoxelFormat format = GetParam();
  MovingVolume moving = make_filled(format, true, 1);
  const test::Sphere sphere = test::scene_sphere();
  const PointCloud old_cloud = extract_points(moving.volume());
  const MoveStats stats = moving.move_to(moving.placement(big_move_camera()));
  const VolumeGeometry& g = moving.volume().geometry();
  const PointCloud& shipped = moving.shipped_cloud();
  const PointCloud live = extract_points(moving.volume());
  ASSERT_EQ(stats.shipped_points, shipped.size());
  ASSERT_GT(shipped.size(), 500u);
  ASSERT_EQ(shipped.normals.size(), shipped.size());
  ASSERT_NE(shipped.find_property("weight"), nullptr);
  double worst_distance = 0.0, worst_normal = 0.0;
  for (std::size_t n = 0; n < shipped.size(); ++n) {
    const Eigen::Vector3d p = shipped.positions[n].cast<double>();
    worst_distance = std::max(worst_distance, std::fabs(sphere(p)));
    worst_normal = std::max(worst_normal, 1.0 - shipped.normals[n].cast<double>().dot((p - sphere.centre).normalized()));
    // Outside the new volume's sample box (a float decision: allow 1e-3 voxel).
    ASSERT_FALSE(test::in_sample_box(g, test::grid_of(g, p), -1e-3)) << "shipped point " << n << " inside";
  }
  for (const Eigen::Vector3f& p : live.positions) {
    ASSERT_TRUE(test::in_sample_box(g, test::grid_of(g, p.cast<double>()), 1e-3)) << "live point outside";
  }
  // Union covers the old surface: every old crossing has a union point within one voxel.
  PointIndex index(kVoxel);
  for (const Eigen::Vector3f& p : shipped.positions) index.add(p.cast<double>());
  for (const Eigen::Vector3f& p : live.positions) index.add(p.cast<double>());
  double worst_gap = 0.0;
  std::size_t beyond_half = 0;
  for (const Eigen::Vector3f& p : old_cloud.positions) {
    const double gap = index.nearest(p.cast<double>());
    worst_gap = std::max(worst_gap, gap);
    beyond_half += gap > 0.5 * kVoxel ? 1u : 0u;
  }
  const double ratio = static_cast<double>(shipped.size() + live.size()) / static_cast<double>(old_cloud.size());
  // The mesh of the leaving part: on the sphere, counter-clockwise from outside, its cells
  // (centres) outside the new box, so its triangles lie at most a cell diagonal inside it.
  const TriangleMesh& mesh = moving.shipped_mesh();
  ASSERT_EQ(stats.shipped_triangles, mesh.faces.size());
  ASSERT_GT(mesh.faces.size(), 500u);
  mesh.validate();
  double worst_vertex = 0.0;
  std::size_t inward = 0;
  for (const Eigen::Vector3f& p : mesh.vertices.positions) worst_vertex = std::max(worst_vertex, std::fabs(sphere(p.cast<double>())));
  for (const auto& f : mesh.faces) {
    const Eigen::Vector3d a = mesh.vertices.positions[static_cast<std::size_t>(f[0])].cast<double>();
    const Eigen::Vector3d b = mesh.vertices.positions[static_cast<std::size_t>(f[1])].cast<double>();
    const Eigen::Vector3d c = mesh.vertices.positions[static_cast<std::size_t>(f[2])].cast<double>();
    const Eigen::Vector3d centroid = (a + b + c) / 3.0;
    if ((b - a).cross(c - a).dot(centroid - sphere.centre) < 0.0) ++inward;
    ASSERT_FALSE(test::in_sample_box(g, test::grid_of(g, centroid), -1.0)) << "a shipped triangle deep inside";
  }
  std::printf("[moving] %s ship: %zu points + %zu live vs %zu old crossings (ratio %.3f); shipped on the sphere "
              "within %.4f voxel, normals within %.2e (1 - cos); worst gap %.3f voxel, %zu old crossings beyond "
              "half a voxel; mesh %zu triangles, vertices within %.4f voxel; ship %.1f ms, resample %.1f ms\n",
              voxel_format_name(format), shipped.size(), live.size(), old_cloud.size(), ratio,
              worst_distance / kVoxel, worst_normal, worst_gap / kVoxel, beyond_half, mesh.faces.size(),
              worst_vertex / kVoxel, stats.ship_ms, stats.resample_ms);
  EXPECT_LE(worst_distance, 0.05 * kVoxel);
  EXPECT_LE(worst_normal, 1e-3);
  EXPECT_LE(worst_gap, 1.0 * kVoxel);
  EXPECT_GT(ratio, 0.93);
  EXPECT_LT(ratio, 1.07);
  EXPECT_LE(worst_vertex, 0.05 * kVoxel);
  EXPECT_EQ(inward, 0u);

  // The model: shipped + live, meshes concatenated with offset indices.
  const ExtractedSurface model = moving.final_surface();
  const ExtractedSurface live_surface = extract_surface(moving.volume());
  EXPECT_EQ(model.cloud.size(), shipped.size() + live.size());
  EXPECT_EQ(model.mesh.faces.size(), mesh.faces.size() + live_surface.mesh.faces.size());
  EXPECT_EQ(model.mesh.vertices.size(), mesh.vertices.size() + live_surface.mesh.vertices.size());
  model.cloud.validate();
  model.mesh.validate();
  EXPECT_EQ(model.mesh.faces.back()[0],
            live_surface.mesh.faces.back()[0] + static_cast<std::int32_t>(mesh.vertices.size()));
}

// Moving the volume clear of its old place ships the whole surface: the cloud and mesh a
// full extraction gives (random field: every kind of cell; more crossings than the
// shipping buffers start with on a GPU). The new volume is all new space, no brick flagged.
TEST_P(MovingVolumeTest, MovingEverythingOutShipsTheWholeSurface) {
  const VoxelFormat format = GetParam();
  MovingVolume moving(48, 40, 32, kVoxel, format, Device::cpu(), test::scene_options());
  moving.place(test::first_camera());
  test::fill_random_field(moving.volume().view(), 777u);
  const Volume before = moving.volume().to_host();
  moving.move_to(before.geometry().T_world_volume * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.01, 0.0, 0.0)));
  const ExtractedSurface all = extract_surface(before);
  ASSERT_GT(all.cloud.size(), 50000u);
  EXPECT_EQ(moving.shipped_cloud().positions, all.cloud.positions);
  EXPECT_EQ(moving.shipped_cloud().normals, all.cloud.normals);
  EXPECT_EQ(moving.shipped_cloud().find_property("weight")->values, all.cloud.find_property("weight")->values);
  EXPECT_EQ(moving.shipped_mesh().faces, all.mesh.faces);
  EXPECT_EQ(moving.shipped_mesh().vertices.positions, all.mesh.vertices.positions);
  const VolumeView after = moving.volume().view();
  std::size_t observed = 0, flagged = 0;
  for (std::size_t n = 0; n < after.voxel_count(); ++n) observed += after.w(n) > 0.0f ? 1u : 0u;
  for (std::size_t n = 0; n < after.brick_count(); ++n) flagged += after.surface_bricks[n];
  EXPECT_EQ(observed, 0u);
  EXPECT_EQ(flagged, 0u);
  EXPECT_TRUE(extract_points(moving.volume()).empty());
  EXPECT_EQ(moving.final_surface().cloud.positions, all.cloud.positions);
}

// Two moves (the second buffer holds stale flags from before the first): the flags are
// exactly what the voxels call for (float32; compact may flag a voxel whose U rounds to ±1 in
// binary16), and a raycast of the moved volume sees what one of the sphere filled afresh at
// the new pose shows.
TEST_P(MovingVolumeTest, BrickFlagsAfterMovesLetRaycastsSeeTheSurface) {
  const VoxelFormat format = GetParam();
  MovingVolume moving = make_filled(format, true, 1);
  const Pose first = test::moved_camera(test::first_camera(), Eigen::Vector3d(0.2e-3, -0.15e-3, 0.1e-3), 6.0,
                                        Eigen::Vector3d(1.0, 0.2, -0.4));
  const Pose second = test::moved_camera(first, Eigen::Vector3d(-0.1e-3, 0.2e-3, -0.1e-3), 5.0,
                                         Eigen::Vector3d(-0.2, 1.0, 0.3));
  moving.move_to(moving.placement(first));
  moving.move_to(moving.placement(second));
  ASSERT_EQ(moving.moves(), 2u);
  EXPECT_EQ(moving.shipped_cloud().size(), 0u) << "the sphere stays inside";
  const VolumeView v = moving.volume().view();
  const std::vector<std::uint8_t> expected = test::expected_bricks(v);
  std::size_t missing = 0, extra = 0, set = 0;
  for (std::size_t n = 0; n < expected.size(); ++n) {
    missing += expected[n] != 0u && v.surface_bricks[n] == 0u ? 1u : 0u;
    extra += expected[n] == 0u && v.surface_bricks[n] != 0u ? 1u : 0u;
    set += expected[n];
  }
  EXPECT_EQ(missing, 0u);
  if (format == VoxelFormat::kFloat32) {
    EXPECT_EQ(extra, 0u);
  } else {
    EXPECT_LE(extra, set / 50);
  }
  EXPECT_LT(set, expected.size() / 2) << "most bricks are empty";

  Volume fresh(moving.volume().geometry(), format, Device::cpu());
  test::fill_sphere(&fresh, test::scene_sphere(), true);
  CameraIntrinsics camera;
  camera.width = 160;
  camera.height = 120;
  camera.fx = camera.fy = 2000.0;  // 4 mm across at the focus: the sphere fills most of it
  camera.cx = 79.5;
  camera.cy = 59.5;
  RaycastOptions options;
  options.min_depth_m = 0.04;
  options.max_depth_m = 0.06;
  Raycaster raycaster(Device::cpu(), camera, options);
  const RaycastResult a = raycaster.raycast(moving.volume(), second);
  const RaycastResult b = raycaster.raycast(fresh, second);
  // Hits against the sphere: the distance of each hit point from the analytic surface (depth
  // differences would blow up at the grazing limb), for the moved and the fresh volume alike.
  const test::Sphere sphere = test::scene_sphere();
  std::vector<double> error_moved, error_fresh;
  std::size_t differ = 0;
  for (std::size_t n = 0; n < a.depth_m.pixel_count(); ++n) {
    const bool ha = a.depth_m.data()[n] > 0.0f, hb = b.depth_m.data()[n] > 0.0f;
    differ += ha != hb ? 1u : 0u;
    auto distance = [&](const Vec3f& p) {
      return std::fabs(sphere(second * Eigen::Vector3d(static_cast<double>(p.x), static_cast<double>(p.y),
                                                       static_cast<double>(p.z)))) / kVoxel;
    };
    if (ha) error_moved.push_back(distance(a.points_camera.data()[n]));
    if (hb) error_fresh.push_back(distance(b.points_camera.data()[n]));
  }
  ASSERT_GT(error_moved.size(), 5000u);
  ASSERT_GT(error_fresh.size(), 5000u);
  auto percentile = [](std::vector<double> values, double p) {
    std::sort(values.begin(), values.end());
    return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
  };
  const double p50_moved = percentile(error_moved, 0.5), p50_fresh = percentile(error_fresh, 0.5);
  const double p99_moved = percentile(error_moved, 0.99), p99_fresh = percentile(error_fresh, 0.99);
  const double max_moved = percentile(error_moved, 1.0), max_fresh = percentile(error_fresh, 1.0);
  std::printf("[moving] %s flags: %zu of %zu bricks, %zu missing, %zu extra; raycast hits %zu moved / %zu fresh "
              "(%zu pixels differ), distance to the sphere (voxels) median %.4f / %.4f, p99 %.4f / %.4f, max %.3f / "
              "%.3f\n",
              voxel_format_name(format), set, expected.size(), missing, extra, error_moved.size(), error_fresh.size(),
              differ, p50_moved, p50_fresh, p99_moved, p99_fresh, max_moved, max_fresh);
  // Each resampling is a trilinear interpolation of a convex field: it overestimates d by up to
  // 3 h² / (8 ρ) (the bound of ResampledVoxelsMatchTheAnalyticSdf), moving the surface inwards
  // by that much: two moves, at most 2 * 3 h / (8 (r - √3 h)) voxels more than the fresh volume.
  const double bias = 2.0 * 3.0 * kVoxel / (8.0 * (sphere.radius - std::sqrt(3.0) * kVoxel));
  EXPECT_LE(differ, error_fresh.size() / 200);
  EXPECT_LE(p50_moved, p50_fresh + bias);
  EXPECT_LE(p99_moved, p99_fresh + bias);
  EXPECT_LE(max_moved, max_fresh + bias + 0.01);
}

// The random field in two moving volumes: one ships before move_to() returns, the other in
// the background (MovingVolumeOptions::ship_in_background).
struct ShippingTwins {
  MovingVolume now;
  MovingVolume background;
};
ShippingTwins shipping_twins(VoxelFormat format) {
  MovingVolumeOptions background_options = test::scene_options();
  background_options.ship_in_background = true;
  ShippingTwins twins{MovingVolume(64, 56, 48, kVoxel, format, Device::cpu(), test::scene_options()),
                      MovingVolume(64, 56, 48, kVoxel, format, Device::cpu(), background_options)};
  test::place_random_field(&twins.now, {&twins.background});
  return twins;
}

// Shipping in the background (MovingVolumeOptions::ship_in_background; the scan session's
// mode on a GPU, where MovingVolumeCuda tests it too): move_to() returns before the surface is
// shipped, finish_shipping() gives the ship's figures once, and what reads the shipped surface
// and the next move wait for it. The surface is the one shipped before returning, point for
// point, in the same order.
TEST_P(MovingVolumeTest, ShippingInTheBackgroundShipsTheSameSurface) {
  ShippingTwins twins = shipping_twins(GetParam());
  MovingVolume& now = twins.now;
  MovingVolume& background = twins.background;

  const Pose partial = test::partial_move_camera();
  const MoveStats shipped_now = now.move_to(now.placement(partial));
  EXPECT_FALSE(shipped_now.shipping);
  EXPECT_FALSE(now.shipping());
  EXPECT_FALSE(now.finish_shipping().moved);  // nothing pending
  const MoveStats started = background.move_to(background.placement(partial));
  EXPECT_TRUE(started.moved);
  EXPECT_TRUE(started.shipping);
  EXPECT_EQ(started.shipped_points, 0u);  // not known yet
  EXPECT_TRUE(background.shipping());
  const MoveStats shipped = background.finish_shipping();
  EXPECT_TRUE(shipped.moved);
  EXPECT_FALSE(shipped.shipping);
  EXPECT_FALSE(background.shipping());
  EXPECT_FALSE(background.finish_shipping().moved);  // given once
  EXPECT_EQ(shipped.shipped_points, shipped_now.shipped_points);
  EXPECT_EQ(shipped.shipped_triangles, shipped_now.shipped_triangles);
  EXPECT_GT(shipped.shipped_points, 10000u);
  EXPECT_EQ(shipped.translation_m, shipped_now.translation_m);
  EXPECT_EQ(background.shipped_cloud().positions, now.shipped_cloud().positions);
  EXPECT_EQ(background.shipped_mesh().faces, now.shipped_mesh().faces);

  // A second move before the first ship is collected: the move waits for it, the shipped
  // surface read while the second ships is waited for and holds both parts in order.
  const Pose away =
      now.volume().geometry().T_world_volume * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.0, 0.02, 0.0));
  const MoveStats away_now = now.move_to(away);
  EXPECT_TRUE(background.move_to(away).shipping);
  EXPECT_EQ(background.shipped_cloud().positions, now.shipped_cloud().positions);
  EXPECT_EQ(background.shipped_cloud().normals, now.shipped_cloud().normals);
  EXPECT_EQ(background.shipped_mesh().faces, now.shipped_mesh().faces);
  EXPECT_TRUE(background.shipping());  // waited for, not yet collected
  EXPECT_EQ(background.finish_shipping().shipped_points, away_now.shipped_points);
  const ExtractedSurface a = now.final_surface();
  const ExtractedSurface b = background.final_surface();
  EXPECT_EQ(a.cloud.positions, b.cloud.positions);
  EXPECT_EQ(a.mesh.faces, b.mesh.faces);

  // A ship still running when the volume is placed anew or destroyed is waited for.
  EXPECT_TRUE(background.move_to(background.placement(partial)).shipping);
  background.place(test::first_camera());
  EXPECT_FALSE(background.shipping());
  EXPECT_TRUE(background.shipped_cloud().empty());
  EXPECT_TRUE(background.move_to(background.placement(partial)).shipping);
}

// The final surface prepared beside the caller (prepare_final_surface(): the scan session's
// loop closure on a GPU): final_surface() takes it, the same model bit for bit as one found
// when asked; a volume changed, moved or placed after preparing drops it, and the model is the
// changed volume's.
TEST_P(MovingVolumeTest, AFinalSurfacePreparedBesideTheCallerIsTheSameModelUnlessTheVolumeChanges) {
  ShippingTwins twins = shipping_twins(GetParam());
  MovingVolume& now = twins.now;
  MovingVolume& background = twins.background;
  const auto expect_same_model = [&](bool prepared) {
    FinalSurfaceTimes times;
    const ExtractedSurface a = now.final_surface();
    const ExtractedSurface b = background.final_surface(&times);
    EXPECT_EQ(times.prepared, prepared);
    if (!prepared) {
      EXPECT_EQ(times.wait_prepared_ms, 0.0);
    }
    EXPECT_GT(times.extract_ms, 0.0);
    EXPECT_GT(a.cloud.size(), 10000u);
    EXPECT_EQ(a.cloud.positions, b.cloud.positions);
    EXPECT_EQ(a.cloud.normals, b.cloud.normals);
    EXPECT_EQ(a.mesh.vertices.positions, b.mesh.vertices.positions);
    EXPECT_EQ(a.mesh.faces, b.mesh.faces);
  };

  // Prepared while a move's ship still runs (it waits behind it on the worker): taken once.
  const Pose partial = test::partial_move_camera();
  now.move_to(now.placement(partial));
  EXPECT_TRUE(background.move_to(background.placement(partial)).shipping);
  background.prepare_final_surface();
  background.prepare_final_surface();  // one is prepared already: nothing
  expect_same_model(true);
  expect_same_model(false);  // taken: found again when asked again

  // The volume written after preparing: dropped, the model is the written volume's.
  background.prepare_final_surface();
  test::fill_random_field(background.volume().view(), 77u);
  test::fill_random_field(now.volume().view(), 77u);
  expect_same_model(false);

  // Moved after preparing: dropped.
  background.prepare_final_surface();
  const Pose away =
      now.volume().geometry().T_world_volume * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.0, 0.01, 0.0));
  now.move_to(away);
  background.move_to(away);
  expect_same_model(false);

  // Placed anew, or destroyed, with one being prepared: waited for and dropped.
  background.prepare_final_surface();
  background.place(test::first_camera());
  EXPECT_TRUE(background.shipped_cloud().empty());
  background.prepare_final_surface();
}

INSTANTIATE_TEST_SUITE_P(Formats, MovingVolumeTest, ::testing::Values(VoxelFormat::kFloat32, VoxelFormat::kCompact),
                         [](const ::testing::TestParamInfo<VoxelFormat>& format) {
                           return std::string(voxel_format_name(format.param));
                         });

// follow(): the focus may wander within the central 1 - 2 margin of each extent and the
// camera may turn up to max_rotation_deg; beyond either, the volume moves to the camera.
TEST(MovingVolumeFollow, MovesOnlyWhenTheFocusLeavesTheMarginOrTheCameraTurns) {
  // 32 voxels of 100 µm: 3.2 mm, margin 0.15: the focus may go 1.12 mm from the centre.
  MovingVolumeOptions options = test::scene_options();
  MovingVolume moving(32, 32, 32, 1e-4, VoxelFormat::kCompact, Device::cpu(), options);
  const Pose start = test::first_camera();
  moving.place(start);
  EXPECT_TRUE(moving.volume().geometry().T_world_volume.is_approx(moving.placement(start), 1e-15));
  const Eigen::Vector3d centre = moving.volume().geometry().T_world_volume * Eigen::Vector3d::Constant(1.6e-3);
  EXPECT_LT((centre - start * Eigen::Vector3d(0.0, 0.0, test::kFocus)).norm(), 1e-12);
  const Eigen::Vector3d y(0.0, 1.0, 0.0), z(0.0, 0.0, 1.0);

  for (const Eigen::Vector3d& step : {Eigen::Vector3d(1.0e-3, 0.0, 0.0), Eigen::Vector3d(0.0, -1.1e-3, 0.0),
                                      Eigen::Vector3d(0.0, 0.0, 1.1e-3), Eigen::Vector3d(0.7e-3, 0.7e-3, -0.7e-3)}) {
    EXPECT_FALSE(moving.follow(test::moved_camera(start, step, 0.0, z)).moved) << step.transpose();
  }
  // Turning about the optical axis keeps the focus: only the rotation rule applies.
  const double limit_deg = options.max_rotation_deg;
  EXPECT_FALSE(moving.follow(test::moved_camera(start, Eigen::Vector3d::Zero(), limit_deg - 0.1, z)).moved);
  EXPECT_EQ(moving.moves(), 0u);

  const Pose out = test::moved_camera(start, Eigen::Vector3d(1.2e-3, 0.0, 0.0), 0.0, z);
  MoveStats stats = moving.follow(out);
  EXPECT_TRUE(stats.moved);
  EXPECT_NEAR(stats.translation_m, 1.2e-3, 1e-12);
  EXPECT_NEAR(stats.rotation_deg, 0.0, 1e-6);
  EXPECT_TRUE(moving.volume().geometry().T_world_volume.is_approx(moving.placement(out), 1e-15));
  EXPECT_EQ(moving.moves(), 1u);
  EXPECT_FALSE(moving.follow(out).moved) << "centred again";

  const Pose turned = test::moved_camera(out, Eigen::Vector3d::Zero(), limit_deg + 0.5, z);
  stats = moving.follow(turned);
  EXPECT_TRUE(stats.moved);
  EXPECT_NEAR(stats.rotation_deg, limit_deg + 0.5, 1e-6);
  EXPECT_NEAR(stats.translation_m, 0.0, 1e-12);
  EXPECT_EQ(moving.moves(), 2u);

  // Forward along the optical axis past the margin.
  const Pose forward = test::moved_camera(turned, Eigen::Vector3d(0.0, 0.0, 1.2e-3), 0.0, z);
  EXPECT_TRUE(moving.follow(forward).moved);
  // A small turn about the focus is no move; the same turn about the camera centre swings the
  // focus sideways (a 5 cm lever): 2 degrees take it 1.7 mm away.
  EXPECT_FALSE(moving.follow(test::moved_camera(forward, Eigen::Vector3d::Zero(), 2.0, y)).moved);
  stats = moving.follow(forward * Pose(Eigen::AngleAxisd(2.0 * 3.14159265358979323846 / 180.0, y).toRotationMatrix(),
                                       Eigen::Vector3d::Zero()));
  EXPECT_TRUE(stats.moved);
  EXPECT_NEAR(stats.rotation_deg, 2.0, 1e-6);
  EXPECT_NEAR(stats.translation_m, 2.0 * test::kFocus * std::sin(1.0 * 3.14159265358979323846 / 180.0), 1e-9);
  EXPECT_EQ(moving.moves(), 4u);

  moving.place(start);
  EXPECT_EQ(moving.moves(), 0u);
  EXPECT_TRUE(moving.shipped_cloud().empty());
}

TEST(MovingVolumeFollow, BadOptionsAreInvalidArguments) {
  for (int bad = 0; bad < 4; ++bad) {
    MovingVolumeOptions options;
    if (bad == 0) options.margin_fraction = 0.5;
    if (bad == 1) options.focus_distance_m = -1.0;
    if (bad == 2) options.max_rotation_deg = std::numeric_limits<double>::quiet_NaN();
    if (bad == 3) options.extract.full_confidence_weight = 0.0f;
    try {
      MovingVolume moving(8, 8, 8, 1e-4, VoxelFormat::kFloat32, Device::cpu(), options);
      ADD_FAILURE() << "no error for case " << bad;
    } catch (const Error& error) {
      EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument) << error.what();
    }
  }
}

// The support rule on one voxel: half the trilinear weight observed keeps it, less drops it.
TEST(MovingVolumeResample, SupportRuleAndWeightsOnOneVoxel) {
  Volume from(VolumeGeometry::centred(Eigen::Vector3d::Zero(), 4, 4, 4, 1e-4), VoxelFormat::kFloat32, Device::cpu());
  Volume to(from.geometry(), VoxelFormat::kFloat32, Device::cpu());
  const VolumeView a = from.view(), b = to.view();
  a.set_u(a.index(1, 1, 1), 0.5f);
  a.set_w(a.index(1, 1, 1), 4.0f);
  a.set_u(a.index(2, 1, 1), -0.5f);
  a.set_w(a.index(2, 1, 1), 9.0f);
  auto resample_at = [&](float gx) {
    Rigid3f grid{};
    grid.rotation = Mat3T<float>{{1, 0, 0, 0, 1, 0, 0, 0, 1}};
    grid.translation = Vec3f{gx, 0.0f, 0.0f};  // voxel (0, 1, 1) of `to` reads grid (gx, 1, 1)
    resample_voxel(a, b, grid, 0, 1, 1);
    return std::pair<float, float>(b.u(b.index(0, 1, 1)), b.w(b.index(0, 1, 1)));
  };
  EXPECT_EQ(resample_at(1.0f), (std::pair<float, float>(0.5f, 4.0f)));
  EXPECT_EQ(resample_at(1.25f), (std::pair<float, float>(0.25f, 5.0f)));   // 0.75*4 + 0.25*9 = 5.25 -> 5
  EXPECT_EQ(resample_at(1.75f), (std::pair<float, float>(-0.25f, 8.0f)));  // 7.75 -> 8
  EXPECT_EQ(resample_at(0.5f), (std::pair<float, float>(0.5f, 4.0f)));     // half from voxel 0 (unobserved): kept
  EXPECT_EQ(resample_at(0.4f).second, 0.0f);                                // 0.4 of the weight: dropped
  EXPECT_EQ(resample_at(0.4f).first, 1.0f);
  EXPECT_EQ(resample_at(2.6f).second, 0.0f);
  EXPECT_EQ(resample_at(-3.0f).second, 0.0f);
  EXPECT_EQ(resample_at(std::numeric_limits<float>::quiet_NaN()).second, 0.0f);
}

// resample_voxel against its definition (resample_shared.h), written out corner by corner: bit
// for bit on every voxel of an odd-sized volume turned by 7 degrees and shifted by 1.4, -1.6 and
// 0.6 voxels, so that cells inside the old volume, on its border and outside it all occur, in
// both formats, with a separate running average and a third of the voxels unobserved.
TEST(MovingVolumeResample, EveryVoxelIsItsDefinitionBitForBit) {
  for (const VoxelFormat format : {VoxelFormat::kFloat32, VoxelFormat::kCompact}) {
    const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d::Zero(), 9, 7, 5, 1e-4);
    Volume from(geometry, format, Device::cpu(), AverageStorage::kSeparate);
    Volume to(geometry, format, Device::cpu(), AverageStorage::kSeparate);
    const VolumeView a = from.view(), b = to.view();
    test::UnitRandom next(2024u);
    for (std::size_t n = 0; n < a.voxel_count(); ++n) {
      a.set_u(n, 2.0f * next() - 1.0f);
      a.set_average(n, 2.0f * next() - 1.0f);
      a.set_w(n, next() < 0.3f ? 0.0f : 1.0f + std::floor(20.0f * next()));
    }
    const float angle = 7.0f * static_cast<float>(M_PI) / 180.0f;
    Rigid3f grid{};
    grid.rotation = Mat3T<float>{{std::cos(angle), -std::sin(angle), 0, std::sin(angle), std::cos(angle), 0, 0, 0, 1}};
    grid.translation = Vec3f{1.4f, -1.6f, 0.6f};
    // The expected values as the format stores them (half floats, whole uint8 counts).
    Volume expected_volume(VolumeGeometry::centred(Eigen::Vector3d::Zero(), 2, 2, 2, 1e-4), format, Device::cpu(),
                           AverageStorage::kSeparate);
    const VolumeView e = expected_volume.view();
    std::size_t interior = 0, border = 0, outside = 0;
    for (int k = 0; k < b.nz; ++k)
      for (int j = 0; j < b.ny; ++j)
        for (int i = 0; i < b.nx; ++i) {
          const Vec3f g = transform_point(grid, Vec3f{static_cast<float>(i), static_cast<float>(j), static_cast<float>(k)});
          const float gx = snap_to_grid(g.x), gy = snap_to_grid(g.y), gz = snap_to_grid(g.z);
          float u = 1.0f, average = 1.0f, w = 0.0f;
          if (gx > -1.0f && gy > -1.0f && gz > -1.0f && gx < static_cast<float>(a.nx) && gy < static_cast<float>(a.ny) &&
              gz < static_cast<float>(a.nz)) {
            const float fx = std::floor(gx), fy = std::floor(gy), fz = std::floor(gz);
            const int i0 = static_cast<int>(fx), j0 = static_cast<int>(fy), k0 = static_cast<int>(fz);
            const bool inside = a.contains(i0, j0, k0) && a.contains(i0 + 1, j0 + 1, k0 + 1);
            ++(inside ? interior : border);
            const float tx = gx - fx, ty = gy - fy, tz = gz - fz;
            float support = 0.0f, sum_u = 0.0f, sum_a = 0.0f, sum_w = 0.0f;
            for (int c = 0; c < 8; ++c) {
              const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
              const float weight =
                  (dx != 0 ? tx : 1.0f - tx) * (dy != 0 ? ty : 1.0f - ty) * (dz != 0 ? tz : 1.0f - tz);
              if (!(weight > 0.0f) || !a.contains(i0 + dx, j0 + dy, k0 + dz)) continue;
              const std::size_t index = a.index(i0 + dx, j0 + dy, k0 + dz);
              if (!(a.w(index) > 0.0f)) continue;
              support += weight;
              sum_u += weight * a.u(index);
              sum_a += weight * a.average(index);
              sum_w += weight * a.w(index);
            }
            if (support >= kResampleMinSupport) {
              const float inverse_support = 1.0f / support;
              u = std::fmax(-1.0f, std::fmin(1.0f, sum_u * inverse_support));
              average = std::fmax(-1.0f, std::fmin(1.0f, sum_a * inverse_support));
              w = std::fmax(1.0f, std::floor(sum_w * inverse_support + 0.5f));
            }
          } else {
            ++outside;
          }
          resample_voxel(a, b, grid, i, j, k);
          const std::size_t out = b.index(i, j, k);
          e.set_u(0, u);
          e.set_average(0, average);
          e.set_w(0, w);
          const float got[3] = {b.u(out), b.average(out), b.w(out)};
          const float want[3] = {e.u(0), e.average(0), e.w(0)};
          ASSERT_EQ(std::memcmp(got, want, sizeof got), 0)
              << voxel_format_name(format) << " voxel " << i << "," << j << "," << k << ": U " << got[0] << " A "
              << got[1] << " W " << got[2] << " against " << want[0] << " " << want[1] << " " << want[2];
        }
    EXPECT_GT(interior, 50u);
    EXPECT_GT(border, 50u);
    EXPECT_GT(outside, 5u);
  }
}

// --- Host memory admission ------------------------------------------------------------------

#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)  // they need the address space
// In a child limited to its size plus 256 MiB (ulimit -v): a 1 GiB volume and a moving volume
// of two 512 MiB buffers are refused before allocating, naming the limit; a small one fits.
TEST(HostMemoryAdmission, VolumesBeyondUlimitAreRefusedBeforeAllocating) {
  if (!sls::test::address_space_limits_hold()) GTEST_SKIP() << "ulimit -v does not bind here (a user-mode emulator)";
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const auto refused = [](auto&& make) {
      try {
        make();
      } catch (const Error& error) {
        return error.code() == ErrorCode::kOutOfMemory && std::strstr(error.what(), "ulimit -v") != nullptr;
      }
      return false;
    };
    if (!sls::test::limit_address_space(256ull << 20)) _exit(3);
    const bool volume = refused([] {
      Volume big(VolumeGeometry::centred(Eigen::Vector3d::Zero(), 512, 512, 512, 1e-4), VoxelFormat::kFloat32,
                 Device::cpu());
    });
    const bool moving = refused([] {
      MovingVolume big(512, 512, 256, 1e-4, VoxelFormat::kFloat32, Device::cpu(), MovingVolumeOptions{});
    });
    bool small = true;
    try {
      Volume fits(VolumeGeometry::centred(Eigen::Vector3d::Zero(), 64, 64, 64, 1e-4), VoxelFormat::kFloat32,
                  Device::cpu());
    } catch (const Error&) {
      small = false;
    }
    _exit(volume && moving && small ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: a volume beyond the limit was not refused (or a small one was); 3: no limit set";
}
#endif

}  // namespace
}  // namespace sls::fusion
