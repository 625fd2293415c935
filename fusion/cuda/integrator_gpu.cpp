// The integrator's GPU half (fusion/integrator_gpu.h): host code over the launchers of
// integrate.cu, built with CUDA only.
#include "fusion/integrator_gpu.h"

#include <cmath>
#include <cstdint>

#include <cuda_runtime_api.h>

#include "fusion/cuda/integrate_cuda.h"
#include "fusion/integrator_internal.h"
#include "sdk/core/cuda/cuda_stream.h"
#include "sdk/core/cuda/device_buffer.h"

namespace sls::fusion::detail {

struct IntegratorGpu::State {
  Device device;
  cudaStream_t stream = nullptr;  // the session's, or the integrator's own
  DeviceBuffer<float> depth;      // a host map's upload
  DeviceBuffer<ActiveVoxel> active[2];
  DeviceBuffer<std::uint32_t> counters;
  std::uint32_t capacity = 0;
  void* sort_scratch = nullptr;  // cub's temporary storage and the sorted copy, grown as needed
  std::size_t sort_scratch_bytes = 0;
  ActiveVoxel* sorted = nullptr;
  std::size_t sorted_capacity = 0;
  // summarize's sample, sorted, and its figures.
  DeviceBuffer<float> summary_sample;
  DeviceBuffer<float> summary_sorted;
  DeviceBuffer<DepthSummaryDevice> summary;

  ~State() {
    if (sort_scratch != nullptr) {
      (void)cudaFree(sort_scratch);
      note_gpu_allocation(-static_cast<std::ptrdiff_t>(sort_scratch_bytes));
    }
    if (sorted != nullptr) {
      (void)cudaFree(sorted);
      note_gpu_allocation(-static_cast<std::ptrdiff_t>(sorted_capacity * sizeof(ActiveVoxel)));
    }
  }
};

IntegratorGpu::IntegratorGpu(const Device& device, const GpuStream& stream) : state_(std::make_unique<State>()) {
  require_device(device);
  state_->device = device;
  state_->stream = cuda_stream(stream);
  state_->counters.allocate(2);
}

IntegratorGpu::~IntegratorGpu() = default;

const float* IntegratorGpu::on_device(const Image32f& depth_m) {
  if (depth_m.memory_type() == MemoryType::kDevice) return depth_m.data();
  State& s = *state_;
  require_device(s.device);
  const std::size_t pixels = depth_m.pixel_count();
  if (s.depth.size() < pixels) s.depth.allocate(pixels);
  s.depth.upload(depth_m.data(), pixels, s.stream);
  return s.depth.data();
}

DepthMapSummary IntegratorGpu::summarize(const float* depth_device, std::size_t pixels) {
  State& s = *state_;
  require_device(s.device);
  const std::size_t samples = depth_band_samples(pixels);
  if (s.summary_sample.size() < samples) {
    s.summary_sample.allocate(samples);
    s.summary_sorted.allocate(samples);
  }
  if (s.summary.size() == 0) s.summary.allocate(1);
  // Only the figures come down: the band's quantiles are picked on the GPU from the sorted
  // sample (the host's nth_element over 94 000 samples took ~1 ms a frame).
  launch_depth_summary_cuda(depth_device, pixels, s.summary_sample.data(), s.summary_sorted.data(), s.summary.data(),
                            &s.sort_scratch, &s.sort_scratch_bytes, s.stream);
  DepthSummaryDevice figures{};
  s.summary.download(&figures, 1, s.stream);
  SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
  DepthMapSummary summary;
  summary.valid_pixels = static_cast<std::size_t>(figures.valid_pixels);
  summary.near_m = figures.near_m;
  summary.far_m = figures.far_m;
  return summary;
}

IntegrationStats IntegratorGpu::integrate(Volume& volume, const float* depth_device, const CameraIntrinsics& camera,
                                          const Pose& T_world_camera, const DepthBand& band,
                                          const IntegrationOptions& options) {
  State& s = *state_;
  require_device(s.device);
  const double min_depth_m = band.near_m, max_depth_m = band.far_m;
  const VolumeView view = volume.view();
  const IntegrationParams params = options.params(volume.geometry().voxel_size_m);
  const DepthFrameView frame = make_depth_frame_view(depth_device, camera, T_world_camera, volume.geometry());
  const bool sweeps = params.alpha > 0.0f && options.iterations > 0;
  const std::uint32_t wanted = static_cast<std::uint32_t>(active_capacity(options, volume.geometry().voxel_count()));
  if (sweeps && s.capacity < wanted) {
    s.active[0].allocate(wanted);
    s.active[1].allocate(wanted);
    s.capacity = wanted;
  }
  SLS_CUDA_CHECK(cudaMemsetAsync(s.counters.data(), 0, 2 * sizeof(std::uint32_t), s.stream));
  ActiveVoxel* const lists[2] = {s.active[0].data(), s.active[1].data()};
  const VoxelBox box = std::isfinite(max_depth_m)
                            ? band_box(volume.geometry(), camera, T_world_camera, min_depth_m, max_depth_m, options)
                            : frustum_voxel_box(volume.geometry(), camera, T_world_camera, 0.0, max_depth_m);
  const int first[3] = {box.i0, box.j0, box.k0};
  const int extent[3] = {box.i1 - box.i0, box.j1 - box.j0, box.k1 - box.k0};
  launch_integrate_cuda(view, params, frame, first, extent, lists, s.counters.data(), sweeps ? wanted : 0u, s.stream);
  IntegrationStats stats;
  stats.voxels_visited = box.count();
  if (!sweeps) {
    SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
    return stats;
  }
  std::uint32_t counts[2] = {0, 0};
  SLS_CUDA_CHECK(cudaMemcpyAsync(counts, s.counters.data(), sizeof counts, cudaMemcpyDeviceToHost, s.stream));
  SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
  stats.active_voxels = std::size_t{counts[0]} + counts[1];
  for (int parity = 0; parity < 2; ++parity) {
    if (counts[parity] > wanted) {
      stats.overflow += counts[parity] - wanted;
      counts[parity] = wanted;
    }
  }
  for (int parity = 0; parity < 2; ++parity) {
    sort_active_cuda(s.active[parity].data(), counts[parity], &s.sort_scratch, &s.sort_scratch_bytes, &s.sorted,
                     &s.sorted_capacity, s.stream);
  }
  for (int t = 0; t < options.iterations; ++t) {
    for (int parity = 0; parity < 2; ++parity) {
      launch_relax_cuda(view, params, s.active[parity].data(), counts[parity], s.stream);
    }
  }
  SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
  return stats;
}

}  // namespace sls::fusion::detail
