// The moving volume's GPU half (fusion/moving_volume_gpu.h): host code over the launchers of
// resample.cu, built with CUDA only.
#include "fusion/moving_volume_gpu.h"

#include <cstdint>
#include <vector>

#include <cuda_runtime_api.h>

#include "fusion/cuda/resample_cuda.h"
#include "fusion/extract_internal.h"
#include "sdk/core/buffer.h"
#include "sdk/core/cuda/cuda_stream.h"
#include "sdk/core/cuda/device_buffer.h"
#include "sdk/core/stopwatch.h"

namespace sls::fusion::detail {

struct MovingVolumeGpu::State {
  Device device;
  cudaStream_t stream = nullptr;       // resampling's
  cudaStream_t ship_stream = nullptr;  // extraction's
  DeviceBuffer<EdgeCrossing> crossings;
  DeviceBuffer<CellCase> cells;
  DeviceBuffer<std::uint32_t> counters;       // crossings, cells, listed bricks
  DeviceBuffer<std::uint32_t> region_bricks;  // the bricks a ship searches
  RegionSortScratch sort_scratch;
  // Where the found crossings and cells are downloaded: page-locked and kept from ship to ship
  // (grown by half when too small), so a download is a DMA into memory already mapped; fresh
  // pageable arrays were zeroed on one thread, at page-fault speed, before each download.
  Buffer<EdgeCrossing> host_crossings;
  Buffer<CellCase> host_cells;
};

namespace {

template <typename T>
void reserve_pinned(Buffer<T>& buffer, std::size_t count) {
  if (buffer.size() < count) buffer.resize_uninitialized(count + count / 2, MemoryType::kPinned);
}

}  // namespace

MovingVolumeGpu::MovingVolumeGpu(const Device& device, const GpuStream& resample_stream, const GpuStream& ship_stream)
    : state_(std::make_unique<State>()) {
  require_device(device);
  state_->device = device;
  state_->stream = cuda_stream(resample_stream);
  state_->ship_stream = cuda_stream(ship_stream);
  state_->counters.allocate(3);
}

MovingVolumeGpu::~MovingVolumeGpu() = default;

void MovingVolumeGpu::resample(const Volume& from, Volume& to, const Rigid3f& grid_from_to) {
  State& s = *state_;
  require_device(s.device);
  launch_resample_cuda(from.view(), to.view(), grid_from_to, s.stream);
  SLS_CUDA_CHECK(cudaStreamSynchronize(s.stream));
}

ExtractedSurface MovingVolumeGpu::extract_part(const Volume& volume, const OrientedRegion& region,
                                               const ExtractOptions& options, double* assemble_ms) {
  State& s = *state_;
  require_device(s.device);
  const cudaStream_t ship_stream = s.ship_stream;
  const VolumeView view = volume.view();
  const Pose& T_world_volume = volume.geometry().T_world_volume;
  const RegionFilter filter = region_filter(region, T_world_volume);
  const float min_weight = options.min_weight;
  if (s.crossings.size() == 0) s.crossings.allocate(std::size_t{1} << 16);
  if (s.cells.size() == 0) s.cells.allocate(std::size_t{1} << 16);
  // Only the bricks the region may keep anything of: a move's leaving part.
  const std::uint32_t bricks = region_brick_count(view);
  if (s.region_bricks.size() < bricks) s.region_bricks.allocate(bricks);
  std::uint32_t brick_count = 0;
  SLS_CUDA_CHECK(cudaMemsetAsync(s.counters.data() + 2, 0, sizeof(std::uint32_t), ship_stream));
  launch_region_bricks_cuda(view, filter, s.region_bricks.data(), s.counters.data() + 2, ship_stream);
  SLS_CUDA_CHECK(cudaMemcpyAsync(&brick_count, s.counters.data() + 2, sizeof brick_count, cudaMemcpyDeviceToHost,
                                 ship_stream));
  SLS_CUDA_CHECK(cudaStreamSynchronize(ship_stream));
  std::uint32_t counts[2] = {0, 0};
  for (int attempt = 0; attempt < 2; ++attempt) {
    SLS_CUDA_CHECK(cudaMemsetAsync(s.counters.data(), 0, 2 * sizeof(std::uint32_t), ship_stream));
    launch_region_crossings_cuda(view, filter, min_weight, s.region_bricks.data(), brick_count, s.crossings.data(),
                                 static_cast<std::uint32_t>(s.crossings.size()), s.counters.data(), ship_stream);
    launch_region_cells_cuda(view, filter, min_weight, s.region_bricks.data(), brick_count, s.cells.data(),
                             static_cast<std::uint32_t>(s.cells.size()), s.counters.data() + 1, ship_stream);
    SLS_CUDA_CHECK(cudaMemcpyAsync(counts, s.counters.data(), sizeof counts, cudaMemcpyDeviceToHost, ship_stream));
    SLS_CUDA_CHECK(cudaStreamSynchronize(ship_stream));
    const bool fits = counts[0] <= s.crossings.size() && counts[1] <= s.cells.size();
    if (fits) break;
    // Too many for the buffers: grow them to what was counted and run again (once).
    if (counts[0] > s.crossings.size()) s.crossings.allocate(counts[0]);
    if (counts[1] > s.cells.size()) s.cells.allocate(counts[1]);
  }
  // Ordered on the GPU, then downloaded.
  sort_region_parts_cuda(s.crossings.data(), counts[0], s.cells.data(), counts[1],
                         static_cast<std::uint64_t>(volume.geometry().voxel_count()), &s.sort_scratch, ship_stream);
  reserve_pinned(s.host_crossings, counts[0]);
  reserve_pinned(s.host_cells, counts[1]);
  s.crossings.download(s.host_crossings.data(), counts[0], ship_stream);
  s.cells.download(s.host_cells.data(), counts[1], ship_stream);
  SLS_CUDA_CHECK(cudaStreamSynchronize(ship_stream));
  const ConstSpan<EdgeCrossing> found(s.host_crossings.data(), counts[0]);
  const ConstSpan<CellCase> found_cells(s.host_cells.data(), counts[1]);
  const auto assemble_start = SteadyClock::now();
  ExtractedSurface part;
  part.cloud = crossing_cloud(found, T_world_volume, &filter, options);
  part.mesh = cell_mesh(view.nx, view.ny, found, found_cells, T_world_volume, options);
  *assemble_ms = ms_since(assemble_start);
  return part;
}

}  // namespace sls::fusion::detail
