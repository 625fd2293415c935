// The per-pixel ray map: the CPU backend equals direct unprojection, CUDA equals CPU, the
// shared map is made once per camera and device (its device copy equal to its host map), and
// the error cases are clear.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/ray_map.h"
#include "tests/support/test_support.h"

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>
#endif

namespace sls {
namespace {

// The 4000x3000 high-resolution camera of the paper's setup, with a realistic lens.
CameraIntrinsics high_resolution_camera() {
  CameraIntrinsics c;
  c.width = 4000;
  c.height = 3000;
  c.fx = 13012.5;
  c.fy = 13008.25;
  c.cx = 2011.3;
  c.cy = 1489.6;
  c.k1 = -0.112;
  c.k2 = 0.53;
  c.k3 = -1.9;
  c.p1 = 4.1e-4;
  c.p2 = -2.7e-4;
  return c;
}

CameraIntrinsics wide_camera() {
  CameraIntrinsics c;
  c.width = 640;
  c.height = 480;
  c.fx = 420.0;
  c.fy = 421.0;
  c.cx = 319.5;
  c.cy = 240.5;
  c.k1 = -0.3;
  c.k2 = 0.1;
  c.k3 = -0.015;
  c.p1 = 1e-3;
  c.p2 = -1e-3;
  return c;
}

// A lens that folds inside the image: r_d = r (1 − 0.5 r²) reaches at most ≈ 0.544, so the
// outer pixels have no ray.
CameraIntrinsics folding_camera() {
  CameraIntrinsics c;
  c.width = 400;
  c.height = 300;
  c.fx = 200.0;
  c.fy = 200.0;
  c.cx = 199.5;
  c.cy = 149.5;
  c.k1 = -0.5;
  return c;
}

void expect_matches_direct_unproject(const CameraIntrinsics& c, const RayMap& map) {
  ASSERT_EQ(map.width, c.width);
  ASSERT_EQ(map.height, c.height);
  ASSERT_EQ(map.rays.size(), static_cast<std::size_t>(c.width) * static_cast<std::size_t>(c.height));
  ASSERT_EQ(map.valid.size(), map.rays.size());
  int mismatches = 0;
  for (int y = 0; y < c.height; ++y) {
    for (int x = 0; x < c.width; ++x) {
      Vec3d ray;
      const bool ok = unproject(c, Vec2d{static_cast<double>(x), static_cast<double>(y)}, &ray);
      const Vec3f& stored = map.ray(x, y);
      if (ok != map.is_valid(x, y)) {
        ++mismatches;
      } else if (ok) {
        // The stored float is the double ray, correctly rounded.
        if (stored.x != static_cast<float>(ray.x) || stored.y != static_cast<float>(ray.y) || stored.z != 1.0f) {
          ++mismatches;
        }
      } else if (stored.x != 0.0f || stored.y != 0.0f || stored.z != 0.0f) {
        ++mismatches;
      }
    }
  }
  EXPECT_EQ(mismatches, 0);
}

TEST(RayMap, CpuEqualsDirectUnprojection) {
  const CameraIntrinsics c = wide_camera();
  const RayMap map = compute_ray_map(c, Device::cpu());
  expect_matches_direct_unproject(c, map);
  EXPECT_EQ(map.valid_count(), map.rays.size());
}

TEST(RayMap, PixelsWithoutARayAreMarkedInvalid) {
  const CameraIntrinsics c = folding_camera();
  const RayMap map = compute_ray_map(c);
  expect_matches_direct_unproject(c, map);
  EXPECT_TRUE(map.is_valid(200, 150));  // the centre always has a ray
  EXPECT_FALSE(map.is_valid(0, 0));     // r_d ≈ 0.9 in the corner: past the fold
  EXPECT_GT(map.valid_count(), 0u);
  EXPECT_LT(map.valid_count(), map.rays.size());
}

TEST(RayMap, RaysProjectBackToTheirPixels) {
  const CameraIntrinsics c = high_resolution_camera();
  const RayMap map = compute_ray_map(c);
  double max_error = 0.0;
  for (int y = 0; y < c.height; y += 7) {
    for (int x = 0; x < c.width; x += 7) {
      ASSERT_TRUE(map.is_valid(x, y));
      const Vec3f& r = map.ray(x, y);
      Vec2d pixel;
      ASSERT_TRUE(project(c, Vec3d{r.x, r.y, r.z}, &pixel));
      max_error = std::max({max_error, std::fabs(pixel.x - x), std::fabs(pixel.y - y)});
    }
  }
  // Float storage: half an ulp of a normalized coordinate (≈ 1.5e-8 at 0.15) times f = 13000.
  EXPECT_LE(max_error, 1e-3);
  std::printf("ray map reprojection: max |error| = %.3g px\n", max_error);
  EXPECT_EQ(map.valid_count(), map.rays.size());  // 4000x3000, every pixel (its speed: bench_core_io)
}

TEST(RayMap, InvalidIntrinsicsAreRejected) {
  CameraIntrinsics c = wide_camera();
  c.width = 0;
  EXPECT_THROW(compute_ray_map(c), Error);
  c = wide_camera();
  c.fx = -1.0;
  try {
    compute_ray_map(c);
    FAIL() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
  }
}

TEST(RayMap, CudaWithoutCudaBuildIsUnsupported) {
  if (cuda_compiled()) GTEST_SKIP() << "this build has CUDA";
  try {
    compute_ray_map(wide_camera(), Device::cuda(0));
    FAIL() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kUnsupported);
  }
}

TEST(RayMap, CudaWithoutGpuIsADeviceError) {
  if (!cuda_compiled() || test::has_cuda_device()) GTEST_SKIP() << "needs a CUDA build on a machine with no GPU";
  try {
    compute_ray_map(wide_camera(), Device::cuda(0));
    FAIL() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kDevice);
  }
}

void expect_cuda_equals_cpu(const CameraIntrinsics& c) {
  const RayMap cpu = compute_ray_map(c, Device::cpu());
  const RayMap gpu = compute_ray_map(c, Device::cuda(0));
  ASSERT_EQ(gpu.width, cpu.width);
  ASSERT_EQ(gpu.height, cpu.height);
  ASSERT_EQ(gpu.rays.size(), cpu.rays.size());
  double max_difference = 0.0;
  std::size_t valid_mismatches = 0;
  for (std::size_t i = 0; i < cpu.rays.size(); ++i) {
    if (cpu.valid[i] != gpu.valid[i]) {
      ++valid_mismatches;
      continue;
    }
    const Vec3f a = cpu.rays[i], b = gpu.rays[i];
    max_difference = std::max({max_difference, std::fabs(static_cast<double>(a.x) - static_cast<double>(b.x)),
                               std::fabs(static_cast<double>(a.y) - static_cast<double>(b.y)),
                               std::fabs(static_cast<double>(a.z) - static_cast<double>(b.z))});
  }
  // The fold's edge may land either side in a handful of pixels (FMA on the GPU).
  EXPECT_LE(valid_mismatches, cpu.rays.size() / 10000);
  EXPECT_LE(max_difference, 1e-6);
  std::printf("CPU vs CUDA: max difference %.3g, valid mismatches %zu\n", max_difference, valid_mismatches);
}

TEST(RayMapCuda, EqualsCpuFullResolution) {
  SLS_REQUIRE_CUDA_DEVICE();
  expect_cuda_equals_cpu(high_resolution_camera());
}

TEST(RayMapCuda, EqualsCpuWithInvalidPixels) {
  SLS_REQUIRE_CUDA_DEVICE();
  expect_cuda_equals_cpu(folding_camera());
  expect_cuda_equals_cpu(wide_camera());
}

TEST(SharedRayMap, OneMapPerCameraWhileHeld) {
  const CameraIntrinsics camera = folding_camera();
  std::weak_ptr<const SharedRayMap> released;
  {
    const auto first = shared_ray_map(camera, Device::cpu());
    const auto second = shared_ray_map(camera, Device::cpu());
    EXPECT_EQ(first.get(), second.get());
    CameraIntrinsics other = camera;
    other.cx += 0.5;
    const auto third = shared_ray_map(other, Device::cpu());
    EXPECT_NE(first.get(), third.get());
    EXPECT_EQ(first->rays_device, nullptr);  // a CPU map has no device copy
    const RayMap direct = compute_ray_map(camera, Device::cpu());
    EXPECT_EQ(first->host.rays.size(), direct.rays.size());
    EXPECT_EQ(0, std::memcmp(first->host.rays.data(), direct.rays.data(), direct.rays.size() * sizeof(Vec3f)));
    EXPECT_EQ(first->host.valid, direct.valid);
    released = first;
  }
  EXPECT_TRUE(released.expired());  // nobody holds it: freed, not cached forever
}

TEST(SharedRayMap, BadIntrinsicsAreRejected) {
  CameraIntrinsics camera = folding_camera();
  camera.fx = 0.0;
  EXPECT_THROW(shared_ray_map(camera, Device::cpu()), Error);
}

TEST(SharedRayMapCuda, DeviceCopyEqualsItsHostMap) {
  SLS_REQUIRE_CUDA_DEVICE();
#if defined(SLS_HAVE_CUDA)
  const CameraIntrinsics camera = high_resolution_camera();
  const auto map = shared_ray_map(camera, Device::cuda(0));
  ASSERT_NE(map->rays_device, nullptr);
  ASSERT_NE(map->valid_device, nullptr);
  EXPECT_NE(map.get(), shared_ray_map(camera, Device::cpu()).get());  // one per device
  const std::size_t count = map->host.rays.size();
  std::vector<Vec3f> rays(count);
  std::vector<std::uint8_t> valid(count);
  ASSERT_EQ(cudaMemcpy(rays.data(), map->rays_device, count * sizeof(Vec3f), cudaMemcpyDeviceToHost), cudaSuccess);
  ASSERT_EQ(cudaMemcpy(valid.data(), map->valid_device, count, cudaMemcpyDeviceToHost), cudaSuccess);
  EXPECT_EQ(0, std::memcmp(rays.data(), map->host.rays.data(), count * sizeof(Vec3f)));
  EXPECT_EQ(valid, map->host.valid);
  EXPECT_EQ(map.get(), shared_ray_map(camera, Device::cuda(0)).get());
#endif
}

TEST(RayMapCuda, BadOrdinalIsADeviceError) {
  SLS_REQUIRE_CUDA_DEVICE();
  try {
    compute_ray_map(wide_camera(), Device::cuda(cuda_device_count()));
    FAIL() << "expected an error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kDevice);
  }
}

}  // namespace
}  // namespace sls
