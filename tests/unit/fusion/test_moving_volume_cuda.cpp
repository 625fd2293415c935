// The CUDA moving volume equals the CPU one: the same voxels after every move (the kernels
// run resample_shared.h's code, built without fused multiply-adds: bit for bit is expected,
// one binary16 ulp / 1e-6 float is the bound), the same brick flags, the same shipped points
// in the same order (edge-id order) with the same normals and weights, the same shipped mesh
// and the same final surface. Moves: a translation with a rotation (part of the sphere
// leaves), a whole-voxel translation, a follow() that turns, and a move clear of the old
// place (every crossing ships: more than the device buffers first hold). The volumes keep
// GTSDF's running average A (a field other than U), which must move the same way on both.
// Skipped without a GPU.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/extract.h"
#include "fusion/moving_volume.h"
#include "fusion/raycaster.h"
#include "tests/support/test_support.h"
#include "tests/unit/fusion/moving_volume_scene.h"

namespace sls::fusion {
namespace {

using test::kCount;
using test::kVoxel;

struct VoxelComparison {
  std::size_t bit_differences = 0;   // U or A bits or W differ
  std::size_t beyond = 0;            // |dU| beyond one binary16 ulp (compact) / 1e-6 (float), or W differs
  double worst_u = 0.0;
  std::size_t brick_differences = 0;
  std::size_t observed = 0;
};

VoxelComparison compare_voxels(const Volume& cpu, const Volume& gpu) {
  const Volume host = gpu.to_host();
  const VolumeView a = cpu.view(), b = host.view();
  VoxelComparison c;
  for (std::size_t n = 0; n < a.voxel_count(); ++n) {
    const bool same_bits = a.format == VoxelFormat::kFloat32
                               ? (a.u32[n] == b.u32[n] || (std::isnan(a.u32[n]) && std::isnan(b.u32[n]))) &&
                                     a.w32[n] == b.w32[n]
                               : a.u16[n] == b.u16[n] && a.w8[n] == b.w8[n];
    const bool same_average = !a.keeps_average() || (a.format == VoxelFormat::kFloat32
                                                         ? a.a32[n] == b.a32[n] || (std::isnan(a.a32[n]) && std::isnan(b.a32[n]))
                                                         : a.a16[n] == b.a16[n]);
    c.observed += a.w(n) > 0.0f ? 1u : 0u;
    if (same_bits && same_average) continue;
    ++c.bit_differences;
    const double du = std::max(std::fabs(static_cast<double>(a.u(n)) - static_cast<double>(b.u(n))),
                               std::fabs(static_cast<double>(a.average(n)) - static_cast<double>(b.average(n))));
    c.worst_u = std::max(c.worst_u, du);
    // One binary16 ulp at |U| < 1 is at most 2^-11.
    const double tolerance = a.format == VoxelFormat::kCompact ? 1.0 / 2048.0 : 1e-6;
    if (du > tolerance || a.w(n) != b.w(n)) ++c.beyond;
  }
  for (std::size_t n = 0; n < a.brick_count(); ++n) c.brick_differences += a.surface_bricks[n] != b.surface_bricks[n];
  return c;
}

struct CloudComparison {
  bool same_size = false;
  std::size_t position_differences = 0;  // beyond 1e-9 m
  double worst_position = 0.0, worst_normal = 0.0, worst_weight = 0.0;
};

CloudComparison compare_clouds(const PointCloud& a, const PointCloud& b) {
  CloudComparison c;
  c.same_size = a.size() == b.size() && a.normals.size() == b.normals.size();
  if (!c.same_size) return c;
  const PointProperty* wa = a.find_property("weight");
  const PointProperty* wb = b.find_property("weight");
  for (std::size_t n = 0; n < a.size(); ++n) {
    const double dp = (a.positions[n] - b.positions[n]).cast<double>().norm();
    c.worst_position = std::max(c.worst_position, dp);
    c.position_differences += dp > 1e-9 ? 1u : 0u;
    c.worst_normal = std::max(c.worst_normal, (a.normals[n] - b.normals[n]).cast<double>().norm());
    if (wa != nullptr && wb != nullptr) {
      c.worst_weight = std::max(c.worst_weight, std::fabs(static_cast<double>(wa->values[n] - wb->values[n])));
    }
  }
  return c;
}

// Both models at the end, shipped parts plus the live volume (extracted where each lives):
// the same points and triangles. Returns the CPU's.
ExtractedSurface expect_same_final_surface(const MovingVolume& cpu, const MovingVolume& gpu) {
  ExtractedSurface a = cpu.final_surface();
  const ExtractedSurface b = gpu.final_surface();
  const CloudComparison c = compare_clouds(a.cloud, b.cloud);
  EXPECT_TRUE(c.same_size);
  EXPECT_EQ(c.position_differences, 0u);
  EXPECT_EQ(a.mesh.faces, b.mesh.faces);
  return a;
}

void expect_same_state(const MovingVolume& cpu, const MovingVolume& gpu, const MoveStats& sc, const MoveStats& sg,
                       const std::string& what) {
  SCOPED_TRACE(what);
  EXPECT_EQ(sc.moved, sg.moved);
  EXPECT_EQ(sc.shipped_points, sg.shipped_points);
  EXPECT_EQ(sc.shipped_triangles, sg.shipped_triangles);
  EXPECT_EQ(cpu.moves(), gpu.moves());
  EXPECT_TRUE(cpu.volume().geometry().T_world_volume.is_approx(gpu.volume().geometry().T_world_volume, 1e-15));
  const VoxelComparison v = compare_voxels(cpu.volume(), gpu.volume());
  const CloudComparison c = compare_clouds(cpu.shipped_cloud(), gpu.shipped_cloud());
  const CloudComparison m = compare_clouds(cpu.shipped_mesh().vertices, gpu.shipped_mesh().vertices);
  std::printf("[moving-cuda] %s %s: %zu observed voxels, %zu differ in bits (%zu beyond 1 ulp, worst |dU| %.2e), %zu "
              "brick flags differ; moved %d, shipped %zu / %zu points (%zu positions differ, worst %.2e m, normal "
              "%.2e, weight %.1e), %zu / %zu triangles (%zu vertices differ); CPU resample %.1f ms ship %.1f ms, "
              "CUDA resample %.2f ms ship %.2f ms\n",
              voxel_format_name(cpu.volume().format()), what.c_str(), v.observed, v.bit_differences, v.beyond,
              v.worst_u, v.brick_differences, sg.moved ? 1 : 0, cpu.shipped_cloud().size(),
              gpu.shipped_cloud().size(), c.position_differences, c.worst_position, c.worst_normal, c.worst_weight,
              cpu.shipped_mesh().faces.size(), gpu.shipped_mesh().faces.size(), m.position_differences, sc.resample_ms,
              sc.ship_ms, sg.resample_ms, sg.ship_ms);
  EXPECT_EQ(v.beyond, 0u);
  EXPECT_LE(v.bit_differences, v.observed / 1000);  // bit for bit expected (no FMA in the kernels)
  EXPECT_EQ(v.brick_differences, 0u);
  ASSERT_TRUE(c.same_size);
  EXPECT_EQ(c.position_differences, 0u);
  EXPECT_LE(c.worst_normal, 1e-5);
  EXPECT_EQ(c.worst_weight, 0.0);
  ASSERT_TRUE(m.same_size);
  EXPECT_EQ(m.position_differences, 0u);
  EXPECT_EQ(cpu.shipped_mesh().faces, gpu.shipped_mesh().faces);
}

class MovingVolumeCuda : public ::testing::TestWithParam<VoxelFormat> {};

TEST_P(MovingVolumeCuda, MovesEqualTheCpuOnes) {
  SLS_REQUIRE_CUDA_DEVICE();
  const VoxelFormat format = GetParam();
  const MovingVolumeOptions options = test::scene_options();
  MovingVolume cpu(kCount, kCount, kCount, kVoxel, format, Device::cpu(), options, AverageStorage::kSeparate);
  MovingVolume gpu(kCount, kCount, kCount, kVoxel, format, Device::cuda(), options, AverageStorage::kSeparate);
  const Pose start = test::first_camera();
  cpu.place(start);
  gpu.place(start);
  EXPECT_EQ(gpu.volume().device(), Device::cuda());
  test::fill_sphere(&cpu.volume(), test::scene_sphere(), true, 9);
  const VolumeView filled = cpu.volume().view();
  for (std::size_t n = 0; n < filled.voxel_count(); ++n) filled.set_average(n, 0.75f * filled.u(n));
  gpu.volume().copy_from(cpu.volume());
  MoveStats none;
  expect_same_state(cpu, gpu, none, none, "filled");

  // 1. Translation and rotation: part of the sphere leaves.
  const Pose turned = test::moved_camera(start, Eigen::Vector3d(1.3e-3, -0.8e-3, 0.5e-3), 10.0,
                                         Eigen::Vector3d(0.3, -1.0, 0.5));
  MoveStats sc = cpu.move_to(cpu.placement(turned));
  MoveStats sg = gpu.move_to(gpu.placement(turned));
  EXPECT_GT(sg.shipped_points, 500u);
  expect_same_state(cpu, gpu, sc, sg, "move 1 (1.6 mm, 10 deg)");

  // 2. Whole voxels, no rotation.
  const Pose shifted =
      cpu.volume().geometry().T_world_volume * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(20, -12, 15) * kVoxel);
  sc = cpu.move_to(shifted);
  sg = gpu.move_to(shifted);
  EXPECT_GT(sg.shipped_points, 0u);
  expect_same_state(cpu, gpu, sc, sg, "move 2 (whole voxels)");

  // 3. follow(): inside the margin nothing; a turn past the threshold moves both.
  const Pose still = test::moved_camera(turned, Eigen::Vector3d(0.2e-3, 0.1e-3, 0.0), 1.0, Eigen::Vector3d(0, 0, 1));
  sc = cpu.follow(still);
  sg = gpu.follow(still);
  EXPECT_EQ(sc.moved, sg.moved);
  const Pose far_turn = test::moved_camera(turned, Eigen::Vector3d(1.8e-3, -1.0e-3, 0.6e-3),
                                           test::scene_options().max_rotation_deg + 5.0,
                                           Eigen::Vector3d(1.0, 1.0, 0.0));
  sc = cpu.follow(far_turn);
  sg = gpu.follow(far_turn);
  EXPECT_TRUE(sg.moved);
  EXPECT_GT(sg.shipped_points, 0u);
  expect_same_state(cpu, gpu, sc, sg, "move 3 (follow, past the turn threshold)");

  const ExtractedSurface a = expect_same_final_surface(cpu, gpu);
  std::printf("[moving-cuda] %s final surface: %zu points, %zu triangles on both\n", voxel_format_name(format),
              a.cloud.size(), a.mesh.faces.size());

  // The brick flags drive the raycast: the GPU raycast of the moved GPU volume matches the
  // CPU raycast of the moved CPU volume.
  CameraIntrinsics camera;
  camera.width = 160;
  camera.height = 120;
  camera.fx = camera.fy = 2000.0;
  camera.cx = 79.5;
  camera.cy = 59.5;
  RaycastOptions raycast_options;
  raycast_options.min_depth_m = 0.04;
  raycast_options.max_depth_m = 0.06;
  Raycaster cpu_raycaster(Device::cpu(), camera, raycast_options), gpu_raycaster(Device::cuda(), camera, raycast_options);
  const RaycastResult p = cpu_raycaster.raycast(cpu.volume(), far_turn);
  const RaycastResult q = gpu_raycaster.raycast(gpu.volume(), far_turn);
  std::size_t hits = 0, differ = 0, beyond = 0;
  for (std::size_t n = 0; n < p.depth_m.pixel_count(); ++n) {
    const bool hp = p.depth_m.data()[n] > 0.0f, hq = q.depth_m.data()[n] > 0.0f;
    differ += hp != hq ? 1u : 0u;
    if (!hp || !hq) continue;
    ++hits;
    beyond += std::fabs(p.depth_m.data()[n] - q.depth_m.data()[n]) > static_cast<float>(1e-3 * kVoxel) ? 1u : 0u;
  }
  std::printf("[moving-cuda] %s raycast after the moves: %zu hits, %zu differ, %zu beyond 1e-3 voxel\n",
              voxel_format_name(format), hits, differ, beyond);
  EXPECT_GT(hits, 200u);  // what is left of the sphere after three moves away from it
  EXPECT_LE(differ, 2 + hits / 100);
  EXPECT_LE(beyond, 2 + hits / 100);
}

// A random field (every kind of cell, about 150 000 crossings: more than the shipping
// buffers first hold, so they grow and the kernels run again) moved clear of its place:
// both backends ship the whole surface, equal to a CPU extraction of the old volume.
TEST_P(MovingVolumeCuda, MovingEverythingOutShipsTheSameWholeSurface) {
  SLS_REQUIRE_CUDA_DEVICE();
  const VoxelFormat format = GetParam();
  MovingVolume cpu(64, 56, 48, kVoxel, format, Device::cpu(), test::scene_options());
  MovingVolume gpu(64, 56, 48, kVoxel, format, Device::cuda(), test::scene_options());
  test::place_random_field(&cpu, {&gpu});
  const ExtractedSurface all = extract_surface(cpu.volume());
  ASSERT_GT(all.cloud.size(), std::size_t{1} << 16);
  const Pose away =
      cpu.volume().geometry().T_world_volume * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.0, 0.02, 0.0));
  const MoveStats sc = cpu.move_to(away);
  const MoveStats sg = gpu.move_to(away);
  EXPECT_EQ(sg.shipped_points, all.cloud.size());
  expect_same_state(cpu, gpu, sc, sg, "everything out");
  const CloudComparison c = compare_clouds(gpu.shipped_cloud(), all.cloud);
  ASSERT_TRUE(c.same_size);
  EXPECT_EQ(c.position_differences, 0u);
  EXPECT_EQ(gpu.shipped_mesh().faces, all.mesh.faces);

  // And a partial move of the same field with a rotation: the leaving part of every kind of
  // cell (rim cells whose vertices lie across the border) agrees too.
  MovingVolume cpu2(64, 56, 48, kVoxel, format, Device::cpu(), test::scene_options());
  MovingVolume gpu2(64, 56, 48, kVoxel, format, Device::cuda(), test::scene_options());
  test::place_random_field(&cpu2, {&gpu2});
  const Pose partial = test::partial_move_camera();
  const MoveStats pc = cpu2.move_to(cpu2.placement(partial));
  const MoveStats pg = gpu2.move_to(gpu2.placement(partial));
  EXPECT_GT(pg.shipped_points, 10000u);
  expect_same_state(cpu2, gpu2, pc, pg, "random field, partial move");
}

// Shipping in the background (the scan session's mode on a GPU; MovingVolumeTest checks the
// option's contract on the CPU): on its own stream and a worker thread, the GPU ships what a
// CPU volume ships before returning, point for point, and the next move waits for it.
TEST_P(MovingVolumeCuda, ShippingInTheBackgroundShipsWhatTheCpuShips) {
  SLS_REQUIRE_CUDA_DEVICE();
  const VoxelFormat format = GetParam();
  MovingVolumeOptions background_options = test::scene_options();
  background_options.ship_in_background = true;
  MovingVolume cpu(64, 56, 48, kVoxel, format, Device::cpu(), test::scene_options());
  MovingVolume gpu(64, 56, 48, kVoxel, format, Device::cuda(), background_options);
  test::place_random_field(&cpu, {&gpu});

  const Pose partial = test::partial_move_camera();
  const MoveStats sc = cpu.move_to(cpu.placement(partial));
  EXPECT_TRUE(gpu.move_to(gpu.placement(partial)).shipping);
  EXPECT_TRUE(gpu.shipping());
  const MoveStats sg = gpu.finish_shipping();
  EXPECT_FALSE(gpu.shipping());
  EXPECT_GT(sg.shipped_points, 10000u);
  expect_same_state(cpu, gpu, sc, sg, "background, partial move");

  // The next move before this one's ship is collected: it waits for it.
  const Pose away =
      cpu.volume().geometry().T_world_volume * Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.0, 0.02, 0.0));
  const MoveStats away_cpu = cpu.move_to(away);
  EXPECT_TRUE(gpu.move_to(away).shipping);
  const CloudComparison c = compare_clouds(cpu.shipped_cloud(), gpu.shipped_cloud());  // waits for the ship
  ASSERT_TRUE(c.same_size);
  EXPECT_EQ(c.position_differences, 0u);
  EXPECT_EQ(cpu.shipped_mesh().faces, gpu.shipped_mesh().faces);
  const MoveStats away_gpu = gpu.finish_shipping();
  expect_same_state(cpu, gpu, away_cpu, away_gpu, "background, everything out");
  expect_same_final_surface(cpu, gpu);
}

INSTANTIATE_TEST_SUITE_P(Formats, MovingVolumeCuda, ::testing::Values(VoxelFormat::kFloat32, VoxelFormat::kCompact),
                         [](const ::testing::TestParamInfo<VoxelFormat>& format) {
                           return std::string(voxel_format_name(format.param));
                         });

}  // namespace
}  // namespace sls::fusion
