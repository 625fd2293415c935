// The fusion stage at the paper's size: a 960³ volume (10 mm cube of 10.4 um voxels, the
// paper's voxel count) and 4000 x 3000 depth maps of the simulated knurled screw (paper
// preset, depth-only mode: the decoder's noise model). TSDF integration, GTSDF with 3
// iterations, raycasting, each timed with CUDA events after a warm-up, beside the
// device-to-device copy bandwidth measured in the same run (the memory-bound floor).
// Argument: voxel format (0 float32, 1 compact).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <limits>
#include <utility>
#include <memory>
#include <vector>

#include "drivers/sim/renderer.h"
#include "fusion/integrator.h"
#include "fusion/raycaster.h"
#include "sdk/core/device.h"

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>

#include "sdk/core/cuda/device_buffer.h"
#endif

namespace sls {
namespace {

struct Frames {
  sim::SimRig rig;
  std::vector<Image32f> depth;  // frames 0, 1, 2 of the revolution, camera frame
  std::vector<Pose> T_object_camera;
  double focus_z = 0.0;
};

const Frames& paper_frames() {
  static const std::unique_ptr<Frames> frames = [] {
    auto f = std::make_unique<Frames>();
    sim::RigOptions options;
    options.preset = "paper";
    const sim::Scene scene = sim::make_scene("knurled-screw");
    f->rig = sim::make_rig(options, scene);
    sim::Renderer renderer(f->rig, scene, default_device());
    for (int frame = 0; frame < 3; ++frame) {
      renderer.set_frame(frame);
      f->depth.push_back(renderer.render_depth());
      f->T_object_camera.push_back(f->rig.T_object_camera(frame));
    }
    std::vector<float> valid;
    for (std::size_t i = 0; i < f->depth[0].pixel_count(); i += 97) {
      if (f->depth[0].data()[i] > 0.0f) valid.push_back(f->depth[0].data()[i]);
    }
    std::nth_element(valid.begin(), valid.begin() + static_cast<std::ptrdiff_t>(valid.size() / 2), valid.end());
    f->focus_z = static_cast<double>(valid[valid.size() / 2]);
    return f;
  }();
  return *frames;
}

#if defined(SLS_HAVE_CUDA)
// The volume in the object frame around the first view's focus point.
fusion::VolumeGeometry paper_volume(const Frames& f) {
  const Eigen::Vector3d focus_object = f.T_object_camera[0] * Eigen::Vector3d(0.0, 0.0, f.focus_z);
  return fusion::VolumeGeometry::centred(focus_object, 960, 960, 960, 10e-3 / 960);
}

class Events {
 public:
  Events() {
    SLS_CUDA_CHECK(cudaEventCreate(&start_));
    SLS_CUDA_CHECK(cudaEventCreate(&stop_));
  }
  ~Events() {
    (void)cudaEventDestroy(start_);
    (void)cudaEventDestroy(stop_);
  }
  void start() { SLS_CUDA_CHECK(cudaEventRecord(start_, nullptr)); }
  double stop_s() {
    SLS_CUDA_CHECK(cudaEventRecord(stop_, nullptr));
    SLS_CUDA_CHECK(cudaEventSynchronize(stop_));
    float ms = 0.0f;
    SLS_CUDA_CHECK(cudaEventElapsedTime(&ms, start_, stop_));
    return 1e-3 * static_cast<double>(ms);
  }

 private:
  cudaEvent_t start_ = nullptr, stop_ = nullptr;
};

bool have_gpu(benchmark::State& state) {
  if (cuda_device_count() > 0) return true;
  state.SkipWithError("no CUDA device");
  return false;
}

fusion::VoxelFormat format_arg(const benchmark::State& state) {
  return state.range(0) == 0 ? fusion::VoxelFormat::kFloat32 : fusion::VoxelFormat::kCompact;
}

// Device-to-device copy of a buffer the size of the volume: the bandwidth the fractions use.
void BM_DeviceCopy(benchmark::State& state) {
  if (!have_gpu(state)) return;
  const std::size_t bytes = std::size_t{960} * 960 * 960 * fusion::bytes_per_voxel(format_arg(state));
  DeviceBuffer<std::uint8_t> a(bytes), b(bytes);
  SLS_CUDA_CHECK(cudaMemset(a.data(), 1, bytes));
  Events events;
  for (auto _ : state) {
    events.start();
    SLS_CUDA_CHECK(cudaMemcpyAsync(b.data(), a.data(), bytes, cudaMemcpyDeviceToDevice, nullptr));
    state.SetIterationTime(events.stop_s());
  }
  // Read + write.
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(2 * bytes));
}

// Integration of one depth map (the depth already on the GPU, as the decoder leaves it).
// Second argument: 0 visits every voxel; 1 only the frustum band within η of the frame's
// measured depth range (what Integrator::integrate does with a host depth map).
void integrate_benchmark(benchmark::State& state, const fusion::IntegrationOptions& options) {
  if (!have_gpu(state)) return;
  const Frames& f = paper_frames();
  fusion::Volume volume(paper_volume(f), format_arg(state), Device::cuda(), options.average_storage());
  fusion::Integrator integrator(Device::cuda(), options);
  const CameraIntrinsics& camera = f.rig.camera;
  std::vector<Image32f> depth;
  std::vector<fusion::DepthBand> ranges;
  for (const Image32f& d : f.depth) {
    depth.push_back(d.copy_to(MemoryType::kDevice));
    float lo = 1e30f, hi = 0.0f;
    for (std::size_t i = 0; i < d.pixel_count(); ++i) {
      if (d.data()[i] > 0.0f) {
        lo = std::min(lo, d.data()[i]);
        hi = std::max(hi, d.data()[i]);
      }
    }
    ranges.push_back({state.range(1) != 0 ? static_cast<double>(lo) : 0.0,
                      state.range(1) != 0 ? static_cast<double>(hi) : std::numeric_limits<double>::infinity()});
  }
  SLS_CUDA_CHECK(cudaDeviceSynchronize());
  for (std::size_t n = 0; n < depth.size(); ++n) {  // warm-up, and a volume with history
    integrator.integrate(volume, depth[n], camera, f.T_object_camera[n], ranges[n]);
  }
  Events events;
  std::size_t frame = 0, active = 0, visited = 0;
  for (auto _ : state) {
    events.start();
    const fusion::IntegrationStats stats =
        integrator.integrate(volume, depth[frame], camera, f.T_object_camera[frame], ranges[frame]);
    state.SetIterationTime(events.stop_s());
    active = stats.active_voxels;
    visited = stats.voxels_visited;
    frame = (frame + 1) % depth.size();
  }
  state.counters["voxels_M"] = static_cast<double>(volume.geometry().voxel_count()) / 1e6;
  state.counters["bytes_per_voxel"] =
      static_cast<double>(fusion::bytes_per_voxel(volume.format(), volume.average_storage()));
  state.counters["active_voxels_M"] = static_cast<double>(active) / 1e6;
  state.counters["visited_voxels_M"] = static_cast<double>(visited) / 1e6;
  state.counters["Mpixel"] = static_cast<double>(camera.width) * camera.height / 1e6;
}

void BM_IntegrateTsdf(benchmark::State& state) { integrate_benchmark(state, fusion::IntegrationOptions::tsdf()); }
void BM_IntegrateGtsdf(benchmark::State& state) { integrate_benchmark(state, fusion::IntegrationOptions::gtsdf()); }

void BM_Raycast(benchmark::State& state) {
  if (!have_gpu(state)) return;
  const Frames& f = paper_frames();
  fusion::Volume volume(paper_volume(f), format_arg(state), Device::cuda(), fusion::AverageStorage::kSeparate);
  fusion::Integrator integrator(Device::cuda(), fusion::IntegrationOptions::gtsdf());
  for (std::size_t n = 0; n < f.depth.size(); ++n) integrator.integrate(volume, f.depth[n], f.rig.camera, f.T_object_camera[n]);
  fusion::RaycastOptions options;
  options.min_depth_m = 0.05;
  options.max_depth_m = 0.15;
  fusion::Raycaster raycaster(Device::cuda(), f.rig.camera, options);
  // guided: the session's tracking raycast, searching near the depth integrated from that pose.
  const bool guided = state.range(1) != 0;
  const Image32f& guide = f.depth[1];
  const fusion::RaycastResult check =
      guided ? raycaster.raycast(volume, f.T_object_camera[1], guide) : raycaster.raycast(volume, f.T_object_camera[1]);
  std::size_t hits = 0;
  for (std::size_t i = 0; i < check.depth_m.pixel_count(); ++i) hits += check.depth_m.data()[i] > 0.0f ? 1u : 0u;
  // The session's way: the guide and the maps on the GPU.
  const Image32f guide_device = guide.copy_to(MemoryType::kDevice);
  fusion::RaycastResult maps(MemoryType::kDevice);
  raycaster.raycast(volume, f.T_object_camera[1], maps, guided ? &guide_device : nullptr);
  raycaster.synchronize();
  Events events;
  for (auto _ : state) {
    events.start();
    raycaster.raycast(volume, f.T_object_camera[1], maps, guided ? &guide_device : nullptr);
    raycaster.synchronize();
    state.SetIterationTime(events.stop_s());
  }
  state.counters["hit_fraction"] = static_cast<double>(hits) / static_cast<double>(check.depth_m.pixel_count());
  state.counters["Mpixel"] = static_cast<double>(check.depth_m.pixel_count()) / 1e6;
}

BENCHMARK(BM_DeviceCopy)->ArgName("compact")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseManualTime();
BENCHMARK(BM_IntegrateTsdf)->ArgNames({"compact", "band"})->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseManualTime();
BENCHMARK(BM_IntegrateGtsdf)->ArgNames({"compact", "band"})->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseManualTime();
BENCHMARK(BM_Raycast)->ArgNames({"compact", "guided"})->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseManualTime();
#endif

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
