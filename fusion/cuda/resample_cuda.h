// Internal: the CUDA launchers of the moving volume (fusion/moving_volume.h): resampling one
// buffer into the other (resample_shared.h) and finding the surface that leaves
// (extract_shared.h), the code the CPU loops run. Only built and included with SLS_HAVE_CUDA.
#pragma once

#include <cstdint>

#include <cuda_runtime_api.h>

#include "fusion/extract_shared.h"
#include "fusion/resample_shared.h"

namespace sls::fusion::detail {

// Every voxel of `to` from `from` (resample_voxel); clears `to`'s surface-brick flags first.
void launch_resample_cuda(const VolumeView& from, const VolumeView& to, const Rigid3f& grid_from_to,
                          cudaStream_t stream);

// The crossings of `volume` the region keeps, and those on edges around a cell the region
// keeps (the vertices of its triangles), appended in no order to out[0, capacity) through
// *count (which may end above capacity: call again with more room). *count must be 0 first.
void launch_region_crossings_cuda(const VolumeView& volume, const RegionFilter& region, float min_weight,
                                  EdgeCrossing* out, std::uint32_t capacity, std::uint32_t* count,
                                  cudaStream_t stream);

// The cells the region keeps (by centre) whose case is 1..254 (all corners usable), appended
// likewise.
void launch_region_cells_cuda(const VolumeView& volume, const RegionFilter& region, float min_weight, CellCase* out,
                              std::uint32_t capacity, std::uint32_t* count, cudaStream_t stream);

}  // namespace sls::fusion::detail
