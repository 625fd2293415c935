// The CUDA tracker equals the CPU one (same per-pixel code of track_shared.h; the GPU sums
// each block in float and the blocks in double, the CPU in double): poses within 1e-6 m and
// 1e-5 rad, inliers within a few pixels, the same lost verdicts and degenerate directions.
// track() reads maps where they live: the CUDA raycaster's maps and the live depth map on the
// GPU in place, deterministically (two-stage reductions in a fixed order). The photometric term too
// (photometric_shared.h): the same poses with it on, textures and reference frames from the
// host or on the GPU. Skipped without a GPU.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <string>

#include <gtest/gtest.h>

#include "drivers/sim/scene.h"
#include "fusion/tracker.h"
#include "sdk/core/error.h"
#include "tests/support/test_support.h"
#include "tests/unit/fusion/crease_test_scene.h"
#include "tests/unit/fusion/photometric_test_scenes.h"
#include "tests/unit/fusion/tracker_test_scenes.h"

namespace sls::fusion {
namespace {

using test::kVoxel;
using test::Model;
using test::test_motion;

constexpr double kSurfaceBound = 0.05 * kVoxel;  // as in test_tracker.cpp

double translation_difference(const Pose& a, const Pose& b) { return (a.translation() - b.translation()).norm(); }
double rotation_difference(const Pose& a, const Pose& b) { return (a.inverse() * b).angle_rad(); }

void print(const char* name, const TrackingResult& cpu, const TrackingResult& gpu) {
  std::printf("[tracker-cuda] %s: cpu lost=%d inliers %zu rms %.4f um it %d degenerate %d | cuda lost=%d inliers %zu "
              "rms %.4f um it %d degenerate %d | pose differs %.3g m, %.3g rad\n",
              name, cpu.lost ? 1 : 0, cpu.inliers, cpu.residual_rms_m * 1e6, cpu.iterations,
              cpu.degenerate_directions, gpu.lost ? 1 : 0, gpu.inliers, gpu.residual_rms_m * 1e6, gpu.iterations,
              gpu.degenerate_directions, translation_difference(cpu.T_world_camera, gpu.T_world_camera),
              rotation_difference(cpu.T_world_camera, gpu.T_world_camera));
}

// CPU and CUDA agree on one frame. On the same model maps only float rounding differs (nvcc's
// fused multiply-adds in the projection move a pixel across a rounding border now and then,
// and the per-block float sums): a few inliers. Against a model raycast on the GPU the maps
// themselves differ by float rounding (test_fusion_cuda: up to 0.1 % of the hits):
// `inlier_fraction` and `residual_fraction` widen for that.
void expect_equal(const TrackingResult& cpu, const TrackingResult& gpu, double inlier_fraction = 1e-4,
                  double residual_fraction = 0.02) {
  EXPECT_EQ(cpu.lost, gpu.lost) << cpu.reason << " | " << gpu.reason;
  EXPECT_LT(translation_difference(cpu.T_world_camera, gpu.T_world_camera), 1e-6);
  EXPECT_LT(rotation_difference(cpu.T_world_camera, gpu.T_world_camera), 1e-5);
  // With a model volume, FMAs may move a pixel's point across the box's border too.
  EXPECT_EQ(cpu.live_pixels + cpu.live_pixels_outside_model, gpu.live_pixels + gpu.live_pixels_outside_model);
  const double inside_difference =
      std::fabs(static_cast<double>(cpu.live_pixels) - static_cast<double>(gpu.live_pixels));
  EXPECT_LE(inside_difference, std::max(5.0, inlier_fraction * static_cast<double>(cpu.live_pixels)));
  const double inlier_difference = std::fabs(static_cast<double>(cpu.inliers) - static_cast<double>(gpu.inliers));
  EXPECT_LE(inlier_difference, std::max(5.0, inlier_fraction * static_cast<double>(cpu.live_pixels)));
  const double crease_difference =
      std::fabs(static_cast<double>(cpu.crease_pixels) - static_cast<double>(gpu.crease_pixels));
  EXPECT_LE(crease_difference, std::max(5.0, inlier_fraction * static_cast<double>(cpu.live_pixels)));
  EXPECT_EQ(cpu.degenerate_directions, gpu.degenerate_directions);
  // A level stops when a step falls under the minimum: rounding may take one more step there.
  EXPECT_LE(std::abs(cpu.iterations - gpu.iterations), 3);
  EXPECT_NEAR(cpu.residual_rms_m, gpu.residual_rms_m, residual_fraction * cpu.residual_rms_m + 1e-9);
}

const Model& bumpy_model() {
  static const Model model(test::bumpy_scene());
  return model;
}

TEST(TrackerCuda, EqualsCpuOnEveryCase) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Model& m = bumpy_model();
  Tracker cpu(Device::cpu(), m.camera), gpu(Device::cuda(), m.camera);
  EXPECT_TRUE(gpu.device().is_cuda());
  // A known motion.
  {
    const Pose truth = m.T_world_model * test_motion();
    const Image32f live = test::exact_depth(m.scene, m.camera, truth);
    const TrackingResult a = cpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
    const TrackingResult b = gpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
    print("motion", a, b);
    expect_equal(a, b);
    EXPECT_FALSE(b.lost) << b.reason;
    EXPECT_EQ(b.degenerate_directions, 0);
    const test::SurfaceError e = test::surface_error(live, m.camera, b.T_world_camera, truth);
    std::printf("[tracker-cuda] motion: CUDA surface error RMS %.3f um, max %.3f um\n", e.rms_m * 1e6, e.max_m * 1e6);
    EXPECT_LT(e.rms_m, kSurfaceBound);
    EXPECT_LT(e.max_m, 2.0 * kSurfaceBound);
  }
  // No motion.
  {
    const Image32f live = test::exact_depth(m.scene, m.camera, m.T_world_model);
    const TrackingResult a = cpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
    const TrackingResult b = gpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
    print("still", a, b);
    expect_equal(a, b);
  }
  // Unrelated geometry: lost, the guess returned.
  {
    test::BumpyScene far = test::plane_scene();
    far.plane_z += 20e-3;
    const Image32f live = test::exact_depth(far, m.camera, m.T_world_model * test_motion());
    const TrackingResult a = cpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
    const TrackingResult b = gpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
    print("unrelated", a, b);
    EXPECT_TRUE(b.lost);
    EXPECT_EQ(a.reason, b.reason);
    EXPECT_TRUE(test::same_pose(b.T_world_camera, m.T_world_model));
  }
  // An empty live map.
  {
    const Image32f live(m.camera.width, m.camera.height, 0.0f);
    const TrackingResult b = gpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
    EXPECT_TRUE(b.lost);
    EXPECT_NE(b.reason.find("no valid depth"), std::string::npos) << b.reason;
  }
  // A model volume that holds a small part of the view: the same pixels counted inside it.
  {
    const test::BumpyScene scene = test::bumpy_scene();
    const VolumeGeometry small = test::small_scene_volume(scene);
    const Model sm(scene, test::tracker_camera(), &small);
    const Image32f live = test::exact_depth(sm.scene, sm.camera, sm.T_world_model * test_motion());
    const TrackingResult a =
        cpu.track(live, sm.raycast, sm.T_world_model, sm.T_world_model, nullptr, nullptr, nullptr, &small);
    const TrackingResult b =
        gpu.track(live, sm.raycast, sm.T_world_model, sm.T_world_model, nullptr, nullptr, nullptr, &small);
    print("small volume", a, b);
    expect_equal(a, b);
    EXPECT_FALSE(b.lost) << b.reason;
    EXPECT_GT(b.live_pixels_outside_model, b.live_pixels);
  }
  // Too large a correction.
  {
    TrackingOptions options;
    options.max_correction_m = 0.1e-3;
    Tracker strict(Device::cuda(), m.camera, options);
    const Image32f live = test::exact_depth(m.scene, m.camera, m.T_world_model * test_motion());
    const TrackingResult b = strict.track(live, m.raycast, m.T_world_model, m.T_world_model);
    EXPECT_TRUE(b.lost);
    EXPECT_NE(b.reason.find("moves the view's centre"), std::string::npos) << b.reason;
    EXPECT_TRUE(test::same_pose(b.T_world_camera, m.T_world_model));
  }
}

// The halved live map (max_model_width) on the device equals the CPU's, host and device maps.
TEST(TrackerCuda, HalvedLiveMapEqualsCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Model& m = bumpy_model();
  const Pose truth = m.T_world_model * test_motion();
  const Image32f live = test::exact_depth(m.scene, m.camera, truth);
  TrackingOptions options;
  options.max_model_width = m.camera.width / 2;
  Tracker cpu(Device::cpu(), m.camera, options);
  Tracker gpu(Device::cuda(), m.camera, options);
  Raycaster cpu_raycaster(Device::cpu(), cpu.model_camera(), Model::raycast_options());
  const RaycastResult model = cpu_raycaster.raycast(m.volume, m.T_world_model);
  const TrackingResult a = cpu.track(live, model, m.T_world_model, m.T_world_model);
  const TrackingResult b = gpu.track(live, model, m.T_world_model, m.T_world_model);
  EXPECT_FALSE(a.lost) << a.reason;
  EXPECT_EQ(a.lost, b.lost);
  EXPECT_LT((a.T_world_camera.inverse() * b.T_world_camera).translation().norm(), 1e-6);
  EXPECT_LT((a.T_world_camera.inverse() * b.T_world_camera).angle_rad(), 1e-5);
  EXPECT_NEAR(static_cast<double>(a.inliers), static_cast<double>(b.inliers), 5.0);
  EXPECT_EQ(a.live_pixels, b.live_pixels);
}

TEST(TrackerCuda, PlaneIsDegenerateAsOnTheCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Model m(test::plane_scene());
  const Pose motion = test::camera_motion(Eigen::Vector3d(0.1e-3, 0.05e-3, 0.15e-3), Eigen::Vector3d(1.0, -0.5, 0.2), 0.8);
  const Image32f live = test::exact_depth(m.scene, m.camera, m.T_world_model * motion);
  Tracker cpu(Device::cpu(), m.camera), gpu(Device::cuda(), m.camera);
  const TrackingResult a = cpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
  const TrackingResult b = gpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
  print("plane", a, b);
  EXPECT_FALSE(b.lost) << b.reason;
  EXPECT_EQ(b.degenerate_directions, 3);
  expect_equal(a, b);
}

// More pixels than the reduction's threads (512 blocks x 256): the grid-stride loop.
TEST(TrackerCuda, LargeImageEqualsCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Model m(test::bumpy_scene(), test::tracker_camera(640, 480));
  const Pose truth = m.T_world_model * test_motion();
  const Image32f live = test::exact_depth(m.scene, m.camera, truth);
  Tracker cpu(Device::cpu(), m.camera), gpu(Device::cuda(), m.camera);
  const TrackingResult a = cpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
  const TrackingResult b = gpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
  print("640x480", a, b);
  EXPECT_FALSE(b.lost) << b.reason;
  expect_equal(a, b);
  EXPECT_LT(test::surface_error(live, m.camera, b.T_world_camera, truth).rms_m, kSurfaceBound);
}

// Same bytes (Vec3f has no ==): device maps compared through host copies.
template <typename T>
bool same_pixels(const Image<T>& a, const Image<T>& b) {
  const Image<T> x = a.copy_to(MemoryType::kHost), y = b.copy_to(MemoryType::kHost);
  return x.width() == y.width() && x.height() == y.height() &&
         std::memcmp(x.data(), y.data(), x.size_bytes()) == 0;
}

// The whole frame on the GPU: the volume, its raycast into device maps and the live depth map.
TEST(TrackerCuda, MapsOnTheGpuAreReadInPlace) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Model& m = bumpy_model();
  Volume volume(m.volume.geometry(), VoxelFormat::kFloat32, Device::cuda());
  volume.copy_from(m.volume);
  Raycaster raycaster(Device::cuda(), m.camera, Model::raycast_options());
  RaycastResult model(MemoryType::kDevice);
  raycaster.raycast(volume, m.T_world_model, model);
  const Pose truth = m.T_world_model * test_motion();
  const Image32f live = test::exact_depth(m.scene, m.camera, truth);
  const Image32f live_device = live.copy_to(MemoryType::kDevice);
  raycaster.synchronize();  // another stream than the tracker's
  ASSERT_EQ(model.points_camera.memory_type(), MemoryType::kDevice);
  ASSERT_EQ(model.points_camera.width(), m.camera.width);

  Tracker gpu(Device::cuda(), m.camera), cpu(Device::cpu(), m.camera);
  const TrackingResult a = cpu.track(live, m.raycast, m.T_world_model, m.T_world_model);
  const TrackingResult b = gpu.track(live_device, model, m.T_world_model, m.T_world_model);
  print("maps on the GPU", a, b);
  EXPECT_FALSE(b.lost) << b.reason;
  // The GPU raycast differs from the CPU one by float rounding (test_fusion_cuda: < 1e-3
  // voxel almost everywhere), far below what moves the pose by 1e-6 m.
  expect_equal(a, b, 1e-3, 0.1);
  const test::SurfaceError e = test::surface_error(live, m.camera, b.T_world_camera, truth);
  std::printf("[tracker-cuda] maps on the GPU: surface error RMS %.3f um, max %.3f um\n", e.rms_m * 1e6,
              e.max_m * 1e6);
  EXPECT_LT(e.rms_m, kSurfaceBound);
  // Deterministic: the same frame again gives the same bits; raycast again into the same maps
  // keeps their memory (no allocation per frame).
  const Vec3f* points = model.points_camera.data();
  for (int n = 0; n < 3; ++n) {
    raycaster.raycast(volume, m.T_world_model, model);
    raycaster.synchronize();
    EXPECT_EQ(model.points_camera.data(), points);
    const TrackingResult again = gpu.track(live_device, model, m.T_world_model, m.T_world_model);
    EXPECT_TRUE(test::same_pose(again.T_world_camera, b.T_world_camera)) << n;
    EXPECT_EQ(again.inliers, b.inliers);
    EXPECT_EQ(again.iterations, b.iterations);
    EXPECT_EQ(again.residual_rms_m, b.residual_rms_m);
  }
  // The same maps raycast into host memory give the same bits, and the same result uploaded.
  const RaycastResult downloaded = raycaster.raycast(volume, m.T_world_model);
  EXPECT_EQ(downloaded.memory_type(), MemoryType::kHost);
  EXPECT_TRUE(same_pixels(downloaded.depth_m, model.depth_m));
  EXPECT_TRUE(same_pixels(downloaded.points_camera, model.points_camera));
  EXPECT_TRUE(same_pixels(downloaded.normals_camera, model.normals_camera));
  EXPECT_TRUE(same_pixels(downloaded.shaded, model.shaded));
  const TrackingResult c = gpu.track(live, downloaded, m.T_world_model, m.T_world_model);
  EXPECT_TRUE(c.T_world_camera.is_approx(b.T_world_camera, 1e-12));
  EXPECT_EQ(c.inliers, b.inliers);
  // Guided by a map on the GPU or by the same map on the host: the same maps.
  RaycastResult guided_by_device(MemoryType::kDevice);
  raycaster.raycast(volume, m.T_world_model, guided_by_device, &live_device);
  const RaycastResult guided_by_host = raycaster.raycast(volume, m.T_world_model, live);
  EXPECT_TRUE(same_pixels(guided_by_host.depth_m, guided_by_device.depth_m));
  EXPECT_TRUE(same_pixels(guided_by_host.points_camera, guided_by_device.points_camera));
}

// Confidence weights (TrackingOptions::weight_by_confidence): a biased band of low
// confidence and varied confidence elsewhere, so every pyramid level's block means matter.
// The same poses on the host path, with the live map halved on the device, and with the
// depth and confidence maps on the GPU.
TEST(TrackerCuda, ConfidenceWeightsEqualCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Model& m = bumpy_model();
  const Pose truth = m.T_world_model * test_motion();
  const test::BiasedBand band =
      test::biased_band(test::exact_depth(m.scene, m.camera, truth), 20e-6f, 0.01f, /*vary=*/true);
  {
    Tracker cpu(Device::cpu(), m.camera), gpu(Device::cuda(), m.camera);
    const TrackingResult a = cpu.track(band.live, m.raycast, m.T_world_model, m.T_world_model, nullptr, &band.confidence);
    const TrackingResult b = gpu.track(band.live, m.raycast, m.T_world_model, m.T_world_model, nullptr, &band.confidence);
    print("confidence", a, b);
    EXPECT_FALSE(b.lost) << b.reason;
    expect_equal(a, b);
    EXPECT_LT(test::surface_error(band.trusted, m.camera, b.T_world_camera, truth).rms_m, kSurfaceBound);
    // Unweighted, the band pulls the pose off (test_tracker.cpp has the CPU figures).
    const TrackingResult equal = gpu.track(band.live, m.raycast, m.T_world_model, m.T_world_model);
    EXPECT_GT(test::surface_error(band.trusted, m.camera, equal.T_world_camera, truth).rms_m, 3e-6);

    Volume volume(m.volume.geometry(), VoxelFormat::kFloat32, Device::cuda());
    volume.copy_from(m.volume);
    Raycaster raycaster(Device::cuda(), m.camera, Model::raycast_options());
    RaycastResult model(MemoryType::kDevice);
    raycaster.raycast(volume, m.T_world_model, model);
    const Image32f live_device = band.live.copy_to(MemoryType::kDevice);
    const Image32f confidence_device = band.confidence.copy_to(MemoryType::kDevice);
    raycaster.synchronize();
    const TrackingResult c =
        gpu.track(live_device, model, m.T_world_model, m.T_world_model, nullptr, &confidence_device);
    print("confidence, maps on the GPU", a, c);
    expect_equal(a, c, 1e-3, 0.1);
  }
  {
    TrackingOptions options;
    options.max_model_width = m.camera.width / 2;
    Tracker cpu(Device::cpu(), m.camera, options), gpu(Device::cuda(), m.camera, options);
    Raycaster cpu_raycaster(Device::cpu(), cpu.model_camera(), Model::raycast_options());
    const RaycastResult model = cpu_raycaster.raycast(m.volume, m.T_world_model);
    const TrackingResult a = cpu.track(band.live, model, m.T_world_model, m.T_world_model, nullptr, &band.confidence);
    const TrackingResult b = gpu.track(band.live, model, m.T_world_model, m.T_world_model, nullptr, &band.confidence);
    print("confidence, halved", a, b);
    EXPECT_FALSE(b.lost) << b.reason;
    expect_equal(a, b);
  }
}

// The crease test (model-side marks, matches set aside) on the knurled screw with a decoder's
// groove errors: the same poses and counts on the host path and with the maps on the GPU.
TEST(TrackerCuda, CreaseTestEqualsCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const test::GroovedScrew screw;
  Tracker cpu(Device::cpu(), screw.camera), gpu(Device::cuda(), screw.camera);
  const TrackingResult a = cpu.track(screw.biased, screw.model.raycast, screw.model_pose, screw.model_pose);
  const TrackingResult b = gpu.track(screw.biased, screw.model.raycast, screw.model_pose, screw.model_pose);
  print("grooved screw", a, b);
  std::printf("[tracker-cuda] crease pixels: cpu %zu cuda %zu\n", a.crease_pixels, b.crease_pixels);
  EXPECT_FALSE(b.lost) << b.reason;
  EXPECT_GT(a.crease_pixels, screw.lines);
  expect_equal(a, b);

  Volume volume(screw.model.volume.geometry(), VoxelFormat::kFloat32, Device::cuda());
  volume.copy_from(screw.model.volume);
  RaycastOptions options;
  options.truncation_voxels = IntegrationOptions::tsdf().truncation_voxels;
  options.min_depth_m = 1e-3;
  Raycaster raycaster(Device::cuda(), screw.camera, options);
  RaycastResult model(MemoryType::kDevice);
  raycaster.raycast(volume, screw.model_pose, model);
  const Image32f live_device = screw.biased.copy_to(MemoryType::kDevice);
  raycaster.synchronize();
  const TrackingResult c = gpu.track(live_device, model, screw.model_pose, screw.model_pose);
  print("grooved screw, maps on the GPU", a, c);
  expect_equal(a, c, 1e-3, 0.1);  // the GPU's own raycast of the model
}

TEST(TrackerCuda, BadInputIsAClearError) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Model& m = bumpy_model();
  Tracker gpu(Device::cuda(), m.camera);
  test::expect_invalid([&] { gpu.track(Image32f(100, 80), m.raycast, m.T_world_model, m.T_world_model); },
                 "live depth map is 100x80");
  // Maps on the GPU are checked as host ones are.
  const Image32f small_device = Image32f(100, 80).copy_to(MemoryType::kDevice);
  test::expect_invalid([&] { gpu.track(small_device, m.raycast, m.T_world_model, m.T_world_model); },
                       "live depth map is 100x80");
  Raycaster other(Device::cuda(), test::tracker_camera(160, 120), Model::raycast_options());
  RaycastResult other_model(MemoryType::kDevice);
  Volume volume(m.volume.geometry(), VoxelFormat::kFloat32, Device::cuda());
  volume.copy_from(m.volume);
  other.raycast(volume, m.T_world_model, other_model);
  test::expect_invalid([&] { gpu.track(m.raycast.depth_m, other_model, m.T_world_model, m.T_world_model); },
                       "model maps are 160x120");
  // A CPU tracker and a CPU raycaster read and write host maps only, and say which map is not.
  Tracker cpu(Device::cpu(), m.camera);
  const Image32f live_device = m.raycast.depth_m.copy_to(MemoryType::kDevice);
  test::expect_invalid([&] { cpu.track(live_device, m.raycast, m.T_world_model, m.T_world_model); },
                       "live depth map is on a GPU");
  RaycastResult device_model = m.raycast;
  device_model.normals_camera = m.raycast.normals_camera.copy_to(MemoryType::kDevice);
  test::expect_invalid([&] { cpu.track(m.raycast.depth_m, device_model, m.T_world_model, m.T_world_model); },
                       "model's normal map is on a GPU");
  Raycaster cpu_raycaster(Device::cpu(), m.camera, Model::raycast_options());
  RaycastResult into_device(MemoryType::kDevice), into_host;
  test::expect_invalid([&] { cpu_raycaster.raycast(m.volume, m.T_world_model, into_device); }, "maps on a GPU");
  test::expect_invalid([&] { cpu_raycaster.raycast(m.volume, m.T_world_model, into_host, &live_device); },
                       "a guide depth map on a GPU");
}

// The chessboard sliding in its plane (test_tracker.cpp's TexturedPlaneSlidingInItselfIsRecovered),
// with the photometric term on both backends: host images, and the whole frame on the GPU
// (track() and set_reference_frame() read it in place); also with ICP on the
// live map halved (the texture pyramid's halvings on the device).
TEST(TrackerCuda, PhotometricEqualsCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  const sim::Scene scene = sim::make_chessboard_scene();
  const sim::SimRig rig = test::textured_rig(scene);
  const test::TexturedFrame reference = test::render_textured_frame(rig, scene, 0);
  const test::TexturedFrame live =
      test::render_textured_frame(test::moved_rig(rig, test::chessboard_slide(), rig.noise_seed + 1), scene, 0);
  const CameraIntrinsics& camera = rig.camera;
  const Pose& model_pose = reference.T_world_camera;
  for (const int max_model_width : {camera.width, camera.width / 2}) {
    TrackingOptions options;
    options.photometric_weight = 0.1;
    options.max_model_width = max_model_width;
    Tracker cpu(Device::cpu(), camera, options), gpu(Device::cuda(), camera, options);
    const test::TexturedModel model(test::chessboard_volume(), reference, camera, cpu.model_camera());
    cpu.set_reference_frame(reference.depth_m, reference.texture, model_pose);
    gpu.set_reference_frame(reference.depth_m, reference.texture, model_pose);
    EXPECT_TRUE(gpu.has_reference_frame());
    const TrackingResult a = cpu.track(live.depth_m, model.raycast, model_pose, model_pose, &live.texture);
    const TrackingResult b = gpu.track(live.depth_m, model.raycast, model_pose, model_pose, &live.texture);
    print(max_model_width == camera.width ? "photometric" : "photometric, halved", a, b);
    std::printf("[tracker-cuda] photometric: cpu %zu px rms %.5f gain %.5f | cuda %zu px rms %.5f gain %.5f\n",
                a.photometric_pixels, a.photometric_rms, a.photometric_gain, b.photometric_pixels, b.photometric_rms,
                b.photometric_gain);
    EXPECT_FALSE(b.lost) << b.reason;
    EXPECT_TRUE(a.photometric) << a.photometric_skipped;
    EXPECT_TRUE(b.photometric) << b.photometric_skipped;
    expect_equal(a, b);
    EXPECT_NEAR(static_cast<double>(a.photometric_pixels), static_cast<double>(b.photometric_pixels),
                std::max(5.0, 1e-3 * static_cast<double>(a.photometric_pixels)));
    EXPECT_NEAR(a.photometric_rms, b.photometric_rms, 0.01 * a.photometric_rms);
    EXPECT_NEAR(a.photometric_gain, b.photometric_gain, 1e-4);
    const double pixel_m = 0.1 / camera.fx;
    EXPECT_LT(test::surface_error(live.depth_m, camera, b.T_world_camera, live.T_world_camera).rms_m, 0.1 * pixel_m);
  }

  // Everything on the GPU: the model raycast there, depth maps and textures uploaded once.
  TrackingOptions options;
  options.photometric_weight = 0.1;
  Tracker cpu(Device::cpu(), camera, options), gpu(Device::cuda(), camera, options);
  const test::TexturedModel model(test::chessboard_volume(), reference, camera, camera);
  Volume volume(model.volume.geometry(), VoxelFormat::kFloat32, Device::cuda());
  volume.copy_from(model.volume);
  RaycastOptions raycast_options;
  raycast_options.truncation_voxels = IntegrationOptions::tsdf().truncation_voxels;
  raycast_options.min_depth_m = 1e-3;
  Raycaster raycaster(Device::cuda(), camera, raycast_options);
  RaycastResult device_model(MemoryType::kDevice);
  raycaster.raycast(volume, model_pose, device_model);
  const Image32f ref_depth = reference.depth_m.copy_to(MemoryType::kDevice);
  const Image32f ref_texture = reference.texture.copy_to(MemoryType::kDevice);
  const Image32f live_depth = live.depth_m.copy_to(MemoryType::kDevice);
  const Image32f live_texture = live.texture.copy_to(MemoryType::kDevice);
  raycaster.synchronize();
  cpu.set_reference_frame(reference.depth_m, reference.texture, model_pose);
  const TrackingResult a = cpu.track(live.depth_m, model.raycast, model_pose, model_pose, &live.texture);
  TrackingResult first;
  for (int n = 0; n < 3; ++n) {
    gpu.set_reference_frame(ref_depth, ref_texture, model_pose);
    const TrackingResult b = gpu.track(live_depth, device_model, model_pose, model_pose, &live_texture);
    if (n == 0) {
      print("photometric, maps on the GPU", a, b);
      EXPECT_TRUE(b.photometric) << b.photometric_skipped;
      // The GPU raycast differs from the CPU one by float rounding (MapsOnTheGpuAreReadInPlace).
      expect_equal(a, b, 1e-3, 0.1);
      first = b;
    } else {
      // Deterministic: the same bits again.
      EXPECT_TRUE(test::same_pose(b.T_world_camera, first.T_world_camera)) << n;
      EXPECT_EQ(b.photometric_pixels, first.photometric_pixels);
      EXPECT_EQ(b.photometric_rms, first.photometric_rms);
    }
  }
  // Without a texture the term is off, as on the CPU.
  const TrackingResult c = gpu.track(live_depth, device_model, model_pose, model_pose);
  EXPECT_FALSE(c.photometric);
  EXPECT_EQ(c.photometric_skipped, "no live texture");
}

TEST(TrackerCuda, PhotometricBadInputIsAClearError) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Model& m = bumpy_model();
  TrackingOptions options;
  options.photometric_weight = 0.1;
  Tracker gpu(Device::cuda(), m.camera, options);
  const Image32f live = test::exact_depth(m.scene, m.camera, m.T_world_model);
  const Image32f small(100, 80, 1.0f);
  test::expect_invalid([&] { gpu.track(live, m.raycast, m.T_world_model, m.T_world_model, &small); },
                       "live texture is 100x80");
  test::expect_invalid([&] { gpu.set_reference_frame(live, small, m.T_world_model); }, "reference texture");
  const Image32f small_device = small.copy_to(MemoryType::kDevice);
  test::expect_invalid([&] { gpu.set_reference_frame(live, small_device, m.T_world_model); }, "reference texture");
  // A CPU tracker reads host maps only.
  Tracker cpu(Device::cpu(), m.camera, options);
  const Image32f texture_device = Image32f(live.width(), live.height(), 1.0f).copy_to(MemoryType::kDevice);
  test::expect_invalid([&] { cpu.set_reference_frame(live, texture_device, m.T_world_model); },
                       "reference texture is on a GPU");
  test::expect_invalid([&] { cpu.track(live, m.raycast, m.T_world_model, m.T_world_model, &texture_device); },
                       "live texture is on a GPU");
}

}  // namespace
}  // namespace sls::fusion
