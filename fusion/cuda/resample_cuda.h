// Internal: the CUDA launchers of the moving volume (fusion/moving_volume.h): resampling one
// buffer into the other (resample_shared.h) and finding the surface that leaves
// (extract_shared.h), the code the CPU loops run. Only built and included with SLS_HAVE_CUDA.
#pragma once

#include <cstdint>

#include <cuda_runtime_api.h>

#include "fusion/extract_shared.h"
#include "fusion/resample_shared.h"
#include "sdk/core/cuda/device_buffer.h"

namespace sls::fusion::detail {

// Every voxel of `to` from `from` (resample_voxel); clears `to`'s surface-brick flags first.
void launch_resample_cuda(const VolumeView& from, const VolumeView& to, const Rigid3f& grid_from_to,
                          cudaStream_t stream);

// The surface a region keeps is searched brick by brick: bricks of 32 x 4 x 4 voxels (a warp
// along a row), only those the region may keep anything of (region_drops_voxels). A move's
// region keeps what leaves the volume, a fraction of it.
std::uint32_t region_brick_count(const VolumeView& volume);
// Lists those bricks, in no order, into bricks[0, region_brick_count) through *count (0 first).
void launch_region_bricks_cuda(const VolumeView& volume, const RegionFilter& region, std::uint32_t* bricks,
                               std::uint32_t* count, cudaStream_t stream);

// The crossings the region keeps in the listed bricks, and those on edges around a cell the
// region keeps (the vertices of its triangles), appended in no order to out[0, capacity)
// through *count (which may end above capacity: call again with more room). *count must be
// 0 first.
void launch_region_crossings_cuda(const VolumeView& volume, const RegionFilter& region, float min_weight,
                                  const std::uint32_t* bricks, std::uint32_t brick_count, EdgeCrossing* out,
                                  std::uint32_t capacity, std::uint32_t* count, cudaStream_t stream);

// The cells of the listed bricks the region keeps (by centre) whose case is 1..254 (all
// corners usable), appended likewise.
void launch_region_cells_cuda(const VolumeView& volume, const RegionFilter& region, float min_weight,
                              const std::uint32_t* bricks, std::uint32_t brick_count, CellCase* out,
                              std::uint32_t capacity, std::uint32_t* count, cudaStream_t stream);

// What sort_region_parts_cuda works in, grown as needed and kept from one move to the next.
struct RegionSortScratch {
  DeviceBuffer<std::uint64_t> keys_in, keys_out;
  DeviceBuffer<std::uint32_t> order_in, order_out;
  DeviceBuffer<unsigned char> temp;
  DeviceBuffer<EdgeCrossing> crossings;
  DeviceBuffer<CellCase> cells;
};

// Puts crossings[0, crossing_count) in edge-id order and cells[0, cell_count) in cell order, in
// place on `stream`: the order the host assembly needs, by a radix sort over the bits the ids
// of a volume of `voxel_count` voxels use (ids are unique: the order is std::sort's). At the
// paper's size a move ships ~0.6 M crossings and ~1.2 M cells, which std::sort on the host
// took ~100 ms to order.
void sort_region_parts_cuda(EdgeCrossing* crossings, std::uint32_t crossing_count, CellCase* cells,
                            std::uint32_t cell_count, std::uint64_t voxel_count, RegionSortScratch* scratch,
                            cudaStream_t stream);

}  // namespace sls::fusion::detail
