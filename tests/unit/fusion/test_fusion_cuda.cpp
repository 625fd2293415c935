// The CUDA integrator and raycaster equal the CPU ones (same per-voxel code): identical
// weights and active-voxel counts; U and GTSDF's running average A within float rounding
// (binary16: half an ulp) for all but the voxels whose centre projects within rounding of a
// pixel border, where nvcc's fused multiply-adds pick the neighbouring pixel (a different
// noisy depth); raycast depth
// within a thousandth of a voxel where those voxels are not involved. Skipped without a GPU.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "fusion/integrator.h"
#include "fusion/raycaster.h"
#include "sdk/core/cuda/device_buffer.h"
#include "tests/support/test_support.h"
#include "tests/unit/fusion/fusion_test_scenes.h"

namespace sls::fusion {
namespace {

TEST(FusionCuda, IntegrationAndRaycastEqualCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  CameraIntrinsics camera = test::small_camera(320, 240);
  camera.fx = camera.fy = 6400.0;
  const double apex = 0.1;
  const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d(0.0, 0.0, apex + 2e-3), 96, 80, 64, 62.5e-6);
  for (const VoxelFormat format : {VoxelFormat::kFloat32, VoxelFormat::kCompact}) {
    for (const bool gtsdf : {false, true}) {
      const IntegrationOptions options = gtsdf ? IntegrationOptions::gtsdf() : IntegrationOptions::tsdf();
      Volume cpu_volume(geometry, format, Device::cpu(), options.average_storage());
      Volume gpu_volume(geometry, format, Device::cuda(), options.average_storage());
      Integrator cpu(Device::cpu(), options), gpu(Device::cuda(), options);
      for (std::uint32_t n = 0; n < 3; ++n) {
        const Image32f depth = test::ridge_depth(camera, apex, 20e-6, 7 + n);
        // A slightly different pose per frame, as a turntable gives.
        const Pose T_world_camera = Pose::exp((Eigen::Matrix<double, 6, 1>() << 1e-4 * n, 0, 0, 0, 0.01 * n, 0).finished());
        const IntegrationStats a = cpu.integrate(cpu_volume, depth, camera, T_world_camera);
        const IntegrationStats b = gpu.integrate(gpu_volume, depth, camera, T_world_camera);
        EXPECT_EQ(a.active_voxels, b.active_voxels);
        EXPECT_EQ(a.overflow, 0u);
      }
      const Volume gpu_on_host = gpu_volume.to_host();
      const VolumeView x = cpu_volume.view(), y = gpu_on_host.view();
      const double tolerance = format == VoxelFormat::kFloat32 ? 1e-5 : 5e-4;
      double worst_u = 0.0;
      std::size_t weight_differences = 0, observed = 0, beyond = 0;
      for (std::size_t i = 0; i < x.voxel_count(); ++i) {
        if (x.w(i) != y.w(i)) ++weight_differences;
        if (!(x.w(i) > 0.0f)) continue;
        ++observed;
        // U and (GTSDF) the running average A kept apart from it.
        const double difference = std::max(std::fabs(static_cast<double>(x.u(i) - y.u(i))),
                                           std::fabs(static_cast<double>(x.average(i) - y.average(i))));
        worst_u = std::max(worst_u, difference);
        beyond += difference > tolerance ? 1u : 0u;
      }
      RaycastOptions raycast_options;
      Raycaster cpu_raycaster(Device::cpu(), camera, raycast_options), gpu_raycaster(Device::cuda(), camera, raycast_options);
      const RaycastResult p = cpu_raycaster.raycast(cpu_volume, Pose());
      const RaycastResult q = gpu_raycaster.raycast(gpu_volume, Pose());
      double worst_depth = 0.0;
      std::size_t hit_differences = 0, hits = 0, depth_beyond = 0;
      for (std::size_t i = 0; i < p.depth_m.pixel_count(); ++i) {
        const bool hp = p.depth_m.data()[i] > 0.0f, hq = q.depth_m.data()[i] > 0.0f;
        if (hp != hq) ++hit_differences;
        if (!hp || !hq) continue;
        ++hits;
        const double difference = std::fabs(static_cast<double>(p.depth_m.data()[i] - q.depth_m.data()[i]));
        worst_depth = std::max(worst_depth, difference);
        depth_beyond += difference > 1e-3 * geometry.voxel_size_m ? 1u : 0u;
      }
      std::printf("[fusion-cuda] %s %s: %zu voxels observed, %zu with |dU| > %.0e (max %.2e), %zu weight differences; "
                  "raycast %zu hits, %zu differ, %zu beyond 1e-3 voxel (max %.2e voxels)\n",
                  voxel_format_name(format), gtsdf ? "gtsdf" : "tsdf", observed, beyond, tolerance, worst_u,
                  weight_differences, hits, hit_differences, depth_beyond, worst_depth / geometry.voxel_size_m);
      EXPECT_GT(observed, 100000u);
      EXPECT_EQ(weight_differences, 0u);
      EXPECT_LE(beyond, observed / 100);  // 0.2 % measured on the H200
      EXPECT_LT(worst_u, 0.2);  // a neighbouring pixel's depth: 20 um noise over δ = 250 um, a few sigma
      EXPECT_GT(hits, 20000u);
      EXPECT_LE(hit_differences, hits / 1000);
      EXPECT_LE(depth_beyond, hits / 100);
      EXPECT_LT(worst_depth, 0.1 * geometry.voxel_size_m);
    }
  }
}

// The guided raycast (the session's tracking raycast) on the GPU equals the CPU's: the same
// volume (fused on the CPU, copied over), a guide with a hole, full and half size.
TEST(FusionCuda, GuidedRaycastEqualsCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const test::GuidedRaycastScene scene = test::guided_raycast_scene();
  const Volume& cpu_volume = scene.volume;
  const Image32f& guide = scene.guide;
  const VolumeGeometry& geometry = scene.geometry;
  Volume gpu_volume(geometry, VoxelFormat::kCompact, Device::cuda(), cpu_volume.average_storage());
  gpu_volume.copy_from(cpu_volume);
  const Pose T_world_camera = Pose::exp((Eigen::Matrix<double, 6, 1>() << 2e-5, 0, 0, 0, 0.002, 0).finished());
  for (const CameraIntrinsics& raycast_camera : {scene.camera, scene.half}) {
    Raycaster cpu_raycaster(Device::cpu(), raycast_camera, RaycastOptions{});
    Raycaster gpu_raycaster(Device::cuda(), raycast_camera, RaycastOptions{});
    const RaycastResult p = cpu_raycaster.raycast(cpu_volume, T_world_camera, guide);
    const RaycastResult q = gpu_raycaster.raycast(gpu_volume, T_world_camera, guide);
    std::size_t hits = 0, differ = 0, beyond = 0;
    double worst = 0.0;
    for (std::size_t i = 0; i < p.depth_m.pixel_count(); ++i) {
      const bool hp = p.depth_m.data()[i] > 0.0f, hq = q.depth_m.data()[i] > 0.0f;
      if (hp != hq) ++differ;
      if (!hp || !hq) continue;
      ++hits;
      const double difference = std::fabs(static_cast<double>(p.depth_m.data()[i] - q.depth_m.data()[i]));
      worst = std::max(worst, difference);
      beyond += difference > 1e-3 * geometry.voxel_size_m ? 1u : 0u;
    }
    std::printf("[fusion-cuda] guided raycast %dx%d: %zu hits, %zu differ, %zu beyond 1e-3 voxel (max %.2e voxels)\n",
                raycast_camera.width, raycast_camera.height, hits, differ, beyond, worst / geometry.voxel_size_m);
    EXPECT_GT(hits, p.depth_m.pixel_count() / 2);
    EXPECT_LE(differ, hits / 1000);
    EXPECT_LE(beyond, hits / 100);
    EXPECT_LT(worst, 0.1 * geometry.voxel_size_m);
  }
}

// A depth map summarised where it lives (what a GPU scan does instead of downloading it):
// the valid pixels and the integration band equal the host's count and integration_depth_band,
// for a map with outliers (quantiles), one with under 1000 sampled pixels (the whole range),
// and one with nothing valid.
TEST(FusionCuda, DepthMapSummaryOnTheGpuEqualsTheHosts) {
  SLS_REQUIRE_CUDA_DEVICE();
  Integrator integrator(Device::cuda(), IntegrationOptions{});
  const auto check = [&integrator](const Image32f& depth, const char* what) {
    SCOPED_TRACE(what);
    const Image32f on_device = depth.copy_to(MemoryType::kDevice);
    const DepthMapSummary summary = integrator.summarize(on_device);
    const DepthMapSummary on_host = integrator.summarize(depth);  // the same call, the map on the host
    EXPECT_EQ(on_host.valid_pixels, summary.valid_pixels);
    EXPECT_EQ(on_host.near_m, summary.near_m);
    EXPECT_EQ(on_host.far_m, summary.far_m);
    std::size_t valid = 0;
    for (std::size_t i = 0; i < depth.pixel_count(); ++i) valid += depth.data()[i] > 0.0f && std::isfinite(depth.data()[i]);
    const auto [near_m, far_m] = integration_depth_band(depth);
    EXPECT_EQ(summary.valid_pixels, valid);
    EXPECT_EQ(summary.near_m, near_m);
    EXPECT_EQ(summary.far_m, far_m);
    return summary;
  };
  Image32f depth(1201, 997);  // not a multiple of the stride or of a block
  for (int y = 0; y < depth.height(); ++y) {
    for (int x = 0; x < depth.width(); ++x) {
      const int n = y * depth.width() + x;
      depth(x, y) = n % 7 == 0 ? 0.0f : n % 11 == 0 ? std::nanf("") : 0.1f + 1e-6f * static_cast<float>(n % 9973);
    }
  }
  depth(5, 5) = 40.0f;  // outliers metres off: outside the band
  depth(6, 900) = 1e-4f;
  const DepthMapSummary many = check(depth, "quantiles");
  EXPECT_LT(many.far_m, 1.0);
  Image32f sparse(640, 480, 0.0f);  // 12 valid pixels, two on the sampled grid
  for (int k = 0; k < 12; ++k) sparse(3 + 50 * k, 7 + 30 * k) = 0.2f + 0.01f * static_cast<float>(k);
  sparse.data()[0] = 0.15f;
  sparse.data()[127 * 3] = 0.45f;
  const DepthMapSummary few = check(sparse, "whole range");
  EXPECT_FLOAT_EQ(static_cast<float>(few.near_m), 0.15f);
  EXPECT_FLOAT_EQ(static_cast<float>(few.far_m), 0.45f);
  const DepthMapSummary none = check(Image32f(320, 240, 0.0f), "nothing valid");
  EXPECT_EQ(none.valid_pixels, 0u);
  EXPECT_EQ(none.far_m, 0.0);
}

TEST(FusionCuda, VolumeThatDoesNotFitIsAClearError) {
  SLS_REQUIRE_CUDA_DEVICE();
  // 4 billion float32 voxels (32 GB) twice over: more than any one GPU's memory left free.
  const VolumeGeometry geometry = VolumeGeometry::centred(Eigen::Vector3d::Zero(), 2000, 2000, 1000, 1e-5);
  Volume first(VolumeGeometry::centred(Eigen::Vector3d::Zero(), 64, 64, 64, 1e-5), VoxelFormat::kFloat32, Device::cuda());
  std::vector<Volume> volumes;
  try {
    for (int n = 0; n < 8; ++n) volumes.emplace_back(geometry, VoxelFormat::kFloat32, Device::cuda());
    FAIL() << "8 volumes of 32 GB fitted";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kOutOfMemory);
    EXPECT_NE(std::string(error.what()).find("GPU memory"), std::string::npos) << error.what();
    std::printf("[fusion-cuda] after %zu volumes of 32 GB: %s\n", volumes.size(), error.what());
  }
}

}  // namespace
}  // namespace sls::fusion
