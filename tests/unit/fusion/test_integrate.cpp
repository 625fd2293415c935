// TSDF / GTSDF integration against closed form (DESIGN.md section 3): the running average of
// f = clamp(d / δ, -1, 1) voxel by voxel, η and the weight cap, α = 0 is exactly TSDF, the
// binary16 storage, GTSDF's anisotropic sweeps reducing noise on a plane while keeping a 90°
// crease, over a few frames and over a revolution's worth of them, and its running average
// being TSDF's bit for bit. Raycasting the fused plane finds it where it is.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/integrate_shared.h"
#include "fusion/integrator.h"
#include "fusion/raycaster.h"
#include "sdk/core/error.h"
#include "tests/unit/fusion/fusion_test_scenes.h"

namespace sls::fusion {
namespace {

constexpr double kVoxel = 0.5e-3;
constexpr double kPlaneZ = 0.1;

// 48³ voxels of 0.5 mm centred on the optical axis at the plane.
VolumeGeometry plane_volume() { return VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, kPlaneZ), 48, 48, 48, kVoxel); }

TEST(HalfFloat, RoundTripsAndRoundsToNearestEven) {
  for (const float value : {0.0f, -0.0f, 1.0f, -1.0f, 0.5f, 0.333251953125f, 65504.0f, 6.103515625e-05f,
                            5.9604644775390625e-08f}) {
    EXPECT_EQ(half_to_float(float_to_half(value)), value) << value;
  }
  // Every half converts to a float and back to itself (NaNs aside).
  for (std::uint32_t h = 0; h < 0x10000u; ++h) {
    const auto half = static_cast<std::uint16_t>(h);
    if ((half & 0x7c00u) == 0x7c00u && (half & 0x3ffu) != 0u) continue;
    ASSERT_EQ(float_to_half(half_to_float(half)), half) << h;
  }
  // Ties go to even: 1 + 2^-11 is halfway between 1 and 1 + 2^-10.
  EXPECT_EQ(float_to_half(1.0f + 0.00048828125f), float_to_half(1.0f));
  EXPECT_EQ(float_to_half(1.0f + 3.0f * 0.00048828125f), float_to_half(1.0f + 4.0f * 0.00048828125f));
  // The largest rounding error over [-1, 1] is half an ulp (2^-12 near 1).
  float worst = 0.0f;
  for (int n = -100000; n <= 100000; ++n) {
    const float value = static_cast<float>(n) / 100000.0f;
    worst = std::max(worst, std::fabs(half_to_float(float_to_half(value)) - value));
  }
  EXPECT_LE(worst, 0.000244140625f);
}

// One frame of a fronto-parallel plane: every voxel the camera sees within η of the plane
// holds the closed-form clamp((D - z) / δ), weight 1; voxels farther than η behind it are
// untouched, and so is free space farther than η in front (the integrated band).
TEST(Integrate, OneFrameIsTheClosedFormTruncatedDistance) {
  const CameraIntrinsics camera = test::small_camera();
  for (const VoxelFormat format : {VoxelFormat::kFloat32, VoxelFormat::kCompact}) {
    Volume volume(plane_volume(), format, Device::cpu());
    const IntegrationOptions options = IntegrationOptions::tsdf();
    Integrator integrator(Device::cpu(), options);
    integrator.integrate(volume, test::plane_depth(camera, kPlaneZ), camera, Pose());
    const VolumeView v = volume.view();
    const double delta = options.truncation_voxels * kVoxel, eta = options.eta_voxels * kVoxel;
    std::size_t observed = 0, hidden = 0;
    double worst = 0.0;
    for (int k = 0; k < v.nz; ++k) {
      for (int j = 0; j < v.ny; ++j) {
        for (int i = 0; i < v.nx; ++i) {
          const Eigen::Vector3d centre = volume.geometry().T_world_volume *
                                         (Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) * kVoxel);
          const double d = kPlaneZ - centre.z();
          const std::size_t index = v.index(i, j, k);
          // Inside the field of view by a margin (nearest-pixel lookups at the border aside).
          const bool in_view = std::fabs(centre.x() / centre.z()) < 0.2 && std::fabs(centre.y() / centre.z()) < 0.15;
          if (!in_view) continue;
          if (d < -eta - 1e-9) {
            EXPECT_EQ(v.w(index), 0.0f);
            ++hidden;
            continue;
          }
          if (d < -eta + 1e-9) continue;  // on the η boundary: float rounding decides
          if (d > eta + 2 * kVoxel) {     // free space beyond the band: not visited (frustum_voxel_box)
            EXPECT_EQ(v.w(index), 0.0f);
            continue;
          }
          if (d > eta - 2 * kVoxel) continue;  // the band's edge: the box has a voxel of margin
          ASSERT_EQ(v.w(index), 1.0f) << i << "," << j << "," << k;
          worst = std::max(worst, std::fabs(static_cast<double>(v.u(index)) - std::clamp(d / delta, -1.0, 1.0)));
          ++observed;
        }
      }
    }
    std::printf("[fusion] one plane frame (%s): %zu voxels observed, %zu hidden, max |U - closed form| %.2e\n",
                voxel_format_name(format), observed, hidden, worst);
    EXPECT_GT(observed, 10000u);
    EXPECT_GT(hidden, 1000u);
    EXPECT_LT(worst, format == VoxelFormat::kFloat32 ? 2e-5 : 5e-4);  // float geometry; binary16 storage
  }
}

TEST(Integrate, RunningAverageAndWeightCap) {
  const CameraIntrinsics camera = test::small_camera(64, 48);
  Volume volume(plane_volume(), VoxelFormat::kCompact, Device::cpu());
  IntegrationOptions options = IntegrationOptions::tsdf();
  options.weight_max = 5;
  Integrator integrator(Device::cpu(), options);
  const double delta = options.truncation_voxels * kVoxel;
  // Planes at z and z + δ/2 alternately: the average sits δ/4 behind z.
  for (int n = 0; n < 8; ++n) {
    integrator.integrate(volume, test::plane_depth(camera, kPlaneZ + (n % 2 == 0 ? 0.0 : 0.5 * delta)), camera, Pose());
  }
  const VolumeView v = volume.view();
  const int centre = v.nx / 2;
  std::size_t checked = 0;
  for (int k = 0; k < v.nz; ++k) {
    const std::size_t index = v.index(centre, centre, k);
    const double z = volume.geometry().T_world_volume.translation().z() + (k + 0.5) * kVoxel;
    const double f0 = std::clamp((kPlaneZ - z) / delta, -1.0, 1.0);
    const double f1 = std::clamp((kPlaneZ + 0.5 * delta - z) / delta, -1.0, 1.0);
    if (std::fabs(kPlaneZ - z) > delta) continue;  // inside both frames' integrated bands
    ASSERT_EQ(v.w(index), 5.0f) << k;  // 8 observations, capped at 5
    // Capped running average of f0, f1, f0, ...: U_n = (min(n-1, 4) U_{n-1} + f_n) / (min(n-1, 4) + 1).
    double expected = 0.0, weight = 0.0;
    for (int n = 0; n < 8; ++n) {
      expected = (weight * expected + (n % 2 == 0 ? f0 : f1)) / (weight + 1.0);
      weight = std::min(weight + 1.0, 5.0);
    }
    EXPECT_NEAR(v.u(index), expected, 1e-3) << k;
    ++checked;
  }
  EXPECT_GE(checked, 8u);
}

// λ = 0 is standard TSDF bit for bit, whatever the other GTSDF settings.
TEST(Integrate, ZeroAlphaIsExactlyTsdf) {
  const CameraIntrinsics camera = test::small_camera();
  Volume tsdf(plane_volume(), VoxelFormat::kFloat32, Device::cpu());
  Volume zero_alpha(plane_volume(), VoxelFormat::kFloat32, Device::cpu());
  IntegrationOptions options = IntegrationOptions::gtsdf();
  options.lambda = 0.0;
  Integrator a(Device::cpu(), IntegrationOptions::tsdf()), b(Device::cpu(), options);
  for (std::uint32_t n = 0; n < 3; ++n) {
    const Image32f depth = test::plane_depth(camera, kPlaneZ, 50e-6, n + 1);
    a.integrate(tsdf, depth, camera, Pose());
    b.integrate(zero_alpha, depth, camera, Pose());
  }
  const VolumeView x = tsdf.view(), y = zero_alpha.view();
  EXPECT_EQ(std::vector<float>(x.u32, x.u32 + x.voxel_count()), std::vector<float>(y.u32, y.u32 + y.voxel_count()));
  EXPECT_EQ(std::vector<float>(x.w32, x.w32 + x.voxel_count()), std::vector<float>(y.w32, y.w32 + y.voxel_count()));
}

TEST(Raycast, FindsTheFusedPlane) {
  const CameraIntrinsics camera = test::small_camera();
  Volume volume(plane_volume(), VoxelFormat::kFloat32, Device::cpu());
  Integrator integrator(Device::cpu(), IntegrationOptions::tsdf());
  const Image32f depth = test::plane_depth(camera, kPlaneZ);
  integrator.integrate(volume, depth, camera, Pose());
  RaycastOptions raycast_options;
  Raycaster raycaster(Device::cpu(), camera, raycast_options);
  const RaycastResult result = raycaster.raycast(volume, Pose());
  // Pixels whose plane point lies inside the volume by a voxel (trilinear samples exist).
  const RayMap rays = compute_ray_map(camera);
  const double half = 0.5 * 48 * kVoxel - kVoxel;
  std::size_t inside = 0, hits = 0;
  double worst = 0.0, worst_normal = 0.0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Vec3f r = rays.ray(x, y);
      if (std::fabs(static_cast<double>(r.x) * kPlaneZ) > half || std::fabs(static_cast<double>(r.y) * kPlaneZ) > half) {
        continue;
      }
      ++inside;
      if (!(result.depth_m(x, y) > 0.0f)) continue;
      ++hits;
      worst = std::max(worst, std::fabs(static_cast<double>(result.depth_m(x, y)) - kPlaneZ));
      const std::size_t i = rays.index(x, y);
      worst_normal = std::max(worst_normal, std::fabs(static_cast<double>(result.normals_camera.data()[i].z) + 1.0));
    }
  }
  std::printf("[fusion] raycast plane: %zu of %zu pixels inside the volume hit, max depth error %.2e voxels\n", hits,
              inside, worst / kVoxel);
  EXPECT_GT(inside, 1000u);
  EXPECT_EQ(hits, inside);
  EXPECT_LT(worst, 1e-3 * kVoxel);  // a linear field: the crossing is exact up to float rounding
  EXPECT_LT(worst_normal, 1e-4);
  const std::size_t centre = rays.index(camera.width / 2, camera.height / 2);
  EXPECT_NEAR(result.shaded.data()[centre], 172, 1);  // facing the camera: 25 + 230 cos(light, -z)
}

// Noisy frames of a 90° ridge: GTSDF's sweeps lower the surface noise on the faces, and the
// crease is not rounded off more than TSDF's (the robust φ stops smoothing across it). With
// κ = 0.1 (the default until full revolutions chose 0.03) the faces' noise falls by over 10 %;
// a Perona-Malik φ with κ = 0.2 lowers the face noise as well but rounds the crease (23.4 um
// against TSDF's 20.1 um, measured when the raycast interpolated its crossing once). The
// default (κ = 0.03, gentler) is no worse than TSDF anywhere here.
TEST(Integrate, GtsdfReducesNoiseAndKeepsTheCrease) {
  const CameraIntrinsics camera = test::small_camera();
  const double apex = 0.1;

  // Pixels of 31 um on the ridge, voxels of 125 um: the scanner's proportions.
  const CameraIntrinsics fine = [&] {
    CameraIntrinsics c = camera;
    c.fx = c.fy = 3200.0;
    return c;
  }();
  const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, apex + 2e-3), 64, 64, 48, 125e-6);
  struct Result {
    double rms_um, crease_rms_um;
  };
  const Image32f truth = test::ridge_depth(fine, apex, 0.0, 0);
  auto run = [&](const IntegrationOptions& options, std::uint32_t frames) {
    Volume volume(geometry, VoxelFormat::kFloat32, Device::cpu(), options.average_storage());
    Integrator integrator(Device::cpu(), options);
    for (std::uint32_t n = 0; n < frames; ++n) {
      integrator.integrate(volume, test::ridge_depth(fine, apex, 40e-6, 100 + n), fine, Pose());
    }
    RaycastOptions raycast_options;
    raycast_options.truncation_voxels = options.truncation_voxels;
    Raycaster raycaster(Device::cpu(), fine, raycast_options);
    const RaycastResult result = raycaster.raycast(volume, Pose());
    const RayMap rays = compute_ray_map(fine);
    double sum = 0.0, crease_sum = 0.0;
    std::size_t count = 0, crease_count = 0;
    for (int y = 0; y < fine.height; ++y) {
      for (int x = 0; x < fine.width; ++x) {
        const float depth = result.depth_m(x, y);
        if (!(depth > 0.0f)) continue;
        const double error = static_cast<double>(depth - truth(x, y));
        // Within 3 voxels of the crease (x = 0 on the object).
        if (std::fabs(static_cast<double>(rays.ray(x, y).x * truth(x, y))) < 3 * 125e-6) {
          crease_sum += error * error;
          ++crease_count;
        } else {
          sum += error * error;
          ++count;
        }
      }
    }
    return Result{1e6 * std::sqrt(sum / static_cast<double>(count)),
                  1e6 * std::sqrt(crease_sum / static_cast<double>(crease_count))};
  };
  IntegrationOptions few_noisy_views = IntegrationOptions::gtsdf();
  few_noisy_views.kappa = 0.1;
  const Result tsdf = run(IntegrationOptions::tsdf(), 6);
  const Result gtsdf = run(few_noisy_views, 6);
  std::printf("[fusion] ridge, 6 frames, 40 um noise, 125 um voxels: TSDF faces %.2f um crease %.2f um; GTSDF faces "
              "%.2f um crease %.2f um\n",
              tsdf.rms_um, tsdf.crease_rms_um, gtsdf.rms_um, gtsdf.crease_rms_um);
  EXPECT_LT(gtsdf.rms_um, 0.9 * tsdf.rms_um);
  EXPECT_LT(gtsdf.crease_rms_um, tsdf.crease_rms_um);
  // ~100 observations a voxel, as a turntable revolution gives: the sweeps smooth the average
  // of the raw frames, not their own output of the frame before, so their rounding of the
  // crease does not pile up and the crease stays as sharp as TSDF's.
  const Result tsdf_many = run(IntegrationOptions::tsdf(), 96);
  const Result gtsdf_many = run(few_noisy_views, 96);
  std::printf("[fusion] ridge, 96 frames: TSDF faces %.2f um crease %.2f um; GTSDF faces %.2f um crease %.2f um\n",
              tsdf_many.rms_um, tsdf_many.crease_rms_um, gtsdf_many.rms_um, gtsdf_many.crease_rms_um);
  EXPECT_LT(gtsdf_many.rms_um, tsdf_many.rms_um);
  EXPECT_LT(gtsdf_many.crease_rms_um, 1.1 * tsdf_many.crease_rms_um);
  // The default: no worse than TSDF on the faces or at the crease, few views or many.
  for (const std::uint32_t frames : {6u, 96u}) {
    const Result plain = frames == 6 ? tsdf : tsdf_many;
    const Result default_gtsdf = run(IntegrationOptions::gtsdf(), frames);
    std::printf("[fusion] ridge, %u frames, default GTSDF: faces %.2f um crease %.2f um\n", frames,
                default_gtsdf.rms_um, default_gtsdf.crease_rms_um);
    EXPECT_LE(default_gtsdf.rms_um, plain.rms_um) << frames;
    EXPECT_LE(default_gtsdf.crease_rms_um, plain.crease_rms_um) << frames;
  }
}

// GTSDF keeps the plain running average of the raw frames apart from its smoothed U: its A is
// TSDF's U bit for bit (weights too), in both formats, while its U differs.
TEST(Integrate, GtsdfRunningAverageIsTsdfBitForBit) {
  const CameraIntrinsics camera = test::small_camera();
  for (const VoxelFormat format : {VoxelFormat::kFloat32, VoxelFormat::kCompact}) {
    const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, 0.1), 48, 48, 48, kVoxel);
    Volume tsdf(geometry, format, Device::cpu());
    Volume gtsdf(geometry, format, Device::cpu(), AverageStorage::kSeparate);
    Integrator a(Device::cpu(), IntegrationOptions::tsdf()), b(Device::cpu(), IntegrationOptions::gtsdf());
    for (std::uint32_t n = 0; n < 8; ++n) {
      const Image32f depth = test::ridge_depth(camera, 0.1, 1e-3, 30 + n);
      a.integrate(tsdf, depth, camera, Pose());
      b.integrate(gtsdf, depth, camera, Pose());
    }
    ASSERT_TRUE(gtsdf.view().keeps_average());
    const test::AverageComparison c = test::compare_average(gtsdf.view(), tsdf.view());
    std::printf("[fusion] %s: %zu observed voxels; GTSDF's A differs from TSDF's U in %zu, W in %zu; its U differs "
                "from its A in %zu\n",
                voxel_format_name(format), c.observed, c.average_differs, c.weight_differs, c.differs_from_own_u);
    EXPECT_GT(c.observed, 10000u);
    EXPECT_EQ(c.average_differs, 0u);
    EXPECT_EQ(c.weight_differs, 0u);
    EXPECT_GT(c.differs_from_own_u, 1000u);
  }
}

// One Gauss-Seidel step against its definition (integrate_shared.h): U from A and the observed
// ones of the 6 axis neighbours that the volume holds, found here by (i, j, k) and index(). Every
// voxel of a small odd-sized volume, faces, edges and corners included, bit for bit.
TEST(Integrate, RelaxVoxelIsTheStepOverItsObservedNeighbours) {
  for (const VoxelFormat format : {VoxelFormat::kFloat32, VoxelFormat::kCompact}) {
    Volume volume(VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, 0.1), 7, 5, 3, kVoxel), format, Device::cpu());
    const VolumeView v = volume.view();
    test::UnitRandom next(12345u);
    for (std::size_t n = 0; n < v.voxel_count(); ++n) {
      v.set_u(n, 2.0f * next() - 1.0f);
      v.set_w(n, next() < 0.3f ? 0.0f : 1.0f + std::floor(10.0f * next()));  // a third unobserved
    }
    IntegrationParams params;
    params.alpha = 0.7f;
    params.kappa = 0.05f;
    const int offsets[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
    for (int k = 0; k < v.nz; ++k)
      for (int j = 0; j < v.ny; ++j)
        for (int i = 0; i < v.nx; ++i) {
          const ActiveVoxel voxel{static_cast<std::uint32_t>(v.index(i, j, k)), 0.25f};
          const float u = v.u(voxel.index);
          float numerator = voxel.average, denominator = 1.0f;
          for (const auto& o : offsets) {
            if (!v.contains(i + o[0], j + o[1], k + o[2])) continue;
            const std::size_t neighbour = v.index(i + o[0], j + o[1], k + o[2]);
            if (!(v.w(neighbour) > 0.0f)) continue;
            const float b = params.alpha * penalty_weight(params.penalty, std::fabs(v.u(neighbour) - u), params.kappa);
            numerator += b * v.u(neighbour);
            denominator += b;
          }
          const float expected = numerator / denominator;
          const float got = relax_voxel(v, params, voxel);
          ASSERT_EQ(std::memcmp(&got, &expected, sizeof got), 0)
              << voxel_format_name(format) << " voxel " << i << "," << j << "," << k << ": " << got << " against "
              << expected;
        }
  }
}

// Empty-space skipping jumps bricks no surface voxel touched: the same surface as marching
// every step (the samples just land elsewhere along the ray), and it visits most bricks empty.
TEST(Raycast, SkippingEmptyBricksFindsTheSameSurface) {
  CameraIntrinsics camera = test::small_camera();
  camera.fx = camera.fy = 3200.0;
  const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, 0.102), 64, 64, 96, 125e-6);
  Volume volume(geometry, VoxelFormat::kFloat32, Device::cpu());
  Integrator integrator(Device::cpu(), IntegrationOptions::tsdf());
  integrator.integrate(volume, test::ridge_depth(camera, 0.1, 20e-6, 3), camera, Pose());
  const VolumeView with_bricks = volume.view();
  VolumeView without_bricks = with_bricks;
  without_bricks.surface_bricks = nullptr;
  std::size_t flagged = 0;
  for (std::size_t b = 0; b < with_bricks.brick_count(); ++b) flagged += with_bricks.surface_bricks[b] != 0 ? 1u : 0u;
  RaycastParams params;
  params.truncation_m = static_cast<float>(4 * geometry.voxel_size_m);
  params.max_depth_m = 1.0f;
  const Rigid3f T_volume_camera = geometry.T_world_volume.inverse().to_rigid3f();
  const RayMap rays = compute_ray_map(camera);
  std::size_t hits = 0, differ = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < rays.rays.size(); ++i) {
    const RaycastHit a = raycast_pixel(with_bricks, params, T_volume_camera, rays.rays[i]);
    const RaycastHit b = raycast_pixel(without_bricks, params, T_volume_camera, rays.rays[i]);
    if ((a.depth_m > 0.0f) != (b.depth_m > 0.0f)) ++differ;
    if (!(a.depth_m > 0.0f) || !(b.depth_m > 0.0f)) continue;
    ++hits;
    worst = std::max(worst, std::fabs(static_cast<double>(a.depth_m - b.depth_m)));
  }
  std::printf("[fusion] brick skipping: %zu of %zu bricks flagged; %zu hits, %zu differ, max |dz| %.2e voxels\n", flagged,
              with_bricks.brick_count(), hits, differ, worst / geometry.voxel_size_m);
  EXPECT_LT(flagged, with_bricks.brick_count() / 2);
  EXPECT_GT(hits, rays.rays.size() / 2);
  EXPECT_EQ(differ, 0u);
  EXPECT_LT(worst, 0.01 * geometry.voxel_size_m);
}

// A guided raycast (the session's tracking raycast) searches only near the depth just
// integrated: where that depth has holes it falls back to its tiles' range, and a raycaster
// at half the size takes the full-size guide. Same surface as the unguided raycast everywhere;
// a guide far from the surface finds nothing, so the range really is narrowed.
TEST(Raycast, GuidedByTheIntegratedDepthFindsTheSameSurface) {
  const test::GuidedRaycastScene scene = test::guided_raycast_scene();
  const Volume& volume = scene.volume;
  const Image32f& guide = scene.guide;
  const VolumeGeometry& geometry = scene.geometry;
  const CameraIntrinsics& camera = scene.camera;
  for (const CameraIntrinsics& raycast_camera : {camera, scene.half}) {
    Raycaster raycaster(Device::cpu(), raycast_camera, RaycastOptions{});
    const RaycastResult full = raycaster.raycast(volume, Pose());
    const RaycastResult guided = raycaster.raycast(volume, Pose(), guide);
    std::size_t hits = 0, differ = 0;
    double worst = 0.0;
    for (std::size_t i = 0; i < full.depth_m.pixel_count(); ++i) {
      const float a = full.depth_m.data()[i], b = guided.depth_m.data()[i];
      if ((a > 0.0f) != (b > 0.0f)) ++differ;
      if (!(a > 0.0f) || !(b > 0.0f)) continue;
      ++hits;
      worst = std::max(worst, std::fabs(static_cast<double>(a - b)));
    }
    std::printf("[fusion] guided raycast %dx%d: %zu hits, %zu differ, max |dz| %.2e voxels\n", raycast_camera.width,
                raycast_camera.height, hits, differ, worst / geometry.voxel_size_m);
    EXPECT_GT(hits, full.depth_m.pixel_count() / 2);
    // A handful of rays graze the edge of the observed region at the frame's rim, where
    // whether a sample lands on observed voxels depends on where the march started (6 of
    // 72 231 measured, either way).
    EXPECT_LE(differ, hits / 5000);
    EXPECT_LT(worst, 0.01 * geometry.voxel_size_m);
  }
  // A guide 6 mm behind the apex (3.4 mm behind the farthest surface): the narrowed search
  // starts behind the surface and finds nothing.
  const Image32f behind = test::plane_depth(camera, 0.106);
  Raycaster raycaster(Device::cpu(), camera, RaycastOptions{});
  const RaycastResult misled = raycaster.raycast(volume, Pose(), behind);
  std::size_t hits = 0;
  for (std::size_t i = 0; i < misled.depth_m.pixel_count(); ++i) hits += misled.depth_m.data()[i] > 0.0f ? 1u : 0u;
  EXPECT_EQ(hits, 0u);
  // A guide smaller than the raycast is a clear error.
  EXPECT_THROW(raycaster.raycast(volume, Pose(), Image32f(camera.width / 2, camera.height, 0.1f)), Error);
}

TEST(Integrate, BadInputIsAClearError) {
  const CameraIntrinsics camera = test::small_camera();
  Volume volume(plane_volume(), VoxelFormat::kCompact, Device::cpu());
  Integrator integrator(Device::cpu(), IntegrationOptions::tsdf());
  EXPECT_THROW(integrator.integrate(volume, Image32f(10, 10, 0.1f), camera, Pose()), Error);
  IntegrationOptions options = IntegrationOptions::tsdf();
  options.weight_max = 1000;  // does not fit the compact format's uint8 weights
  Integrator too_heavy(Device::cpu(), options);
  EXPECT_THROW(too_heavy.integrate(volume, test::plane_depth(camera, kPlaneZ), camera, Pose()), Error);
  // GTSDF into a volume without its own running average.
  Integrator gtsdf(Device::cpu(), IntegrationOptions::gtsdf());
  EXPECT_THROW(gtsdf.integrate(volume, test::plane_depth(camera, kPlaneZ), camera, Pose()), Error);
  options = IntegrationOptions::gtsdf();
  options.beta = 0.5;
  EXPECT_THROW(Integrator(Device::cpu(), options), Error);
  EXPECT_THROW(Volume(VolumeGeometry::centred(Eigen::Vector3d::Zero(), 1, 8, 8, 1e-3), VoxelFormat::kFloat32,
                      Device::cpu()),
               Error);
  EXPECT_THROW(Volume(VolumeGeometry::centred(Eigen::Vector3d::Zero(), 4096, 4096, 4096, 1e-3), VoxelFormat::kCompact,
                      Device::cpu()),
               Error);  // 2^36 voxels
}

}  // namespace
}  // namespace sls::fusion
