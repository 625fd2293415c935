// Internal: the CUDA launchers of the integrator (fusion/integrator.h). Only built and
// included when SLS_HAVE_CUDA is defined; free of Eigen so nvcc sees plain structs.
#pragma once

#include <cstddef>
#include <cstdint>

#include <cuda_runtime_api.h>

#include "fusion/depth_band_shared.h"
#include "fusion/integrate_shared.h"

namespace sls::fusion::detail {

// The running-average update of every voxel; active voxels of parity p are appended to
// active[p] (capacity each) through counters[p] (which may exceed capacity: the overflow).
// Over the voxel box [first, first + extent).
void launch_integrate_cuda(const VolumeView& volume, const IntegrationParams& params, const DepthFrameView& frame,
                           const int first[3], const int extent[3], ActiveVoxel* const active[2],
                           std::uint32_t* counters, std::uint32_t capacity, cudaStream_t stream);
// Sorts `count` active voxels by index in place (atomics append them in no order; sorted,
// neighbouring threads read neighbouring voxels). `scratch` grows as needed.
void sort_active_cuda(ActiveVoxel* active, std::uint32_t count, void** scratch, std::size_t* scratch_bytes,
                      ActiveVoxel** sorted, std::size_t* sorted_capacity, cudaStream_t stream);
// One half-sweep over `count` active voxels of one parity.
void launch_relax_cuda(const VolumeView& volume, const IntegrationParams& params, const ActiveVoxel* active,
                       std::uint32_t count, cudaStream_t stream);

// Integrator::summarize's figures of a map on the GPU, computed there.
struct DepthSummaryDevice {
  unsigned long long valid_pixels;   // > 0 and finite
  unsigned long long valid_samples;  // of the every-kDepthBandStride-th pixels sampled
  unsigned min_bits, max_bits;       // the smallest / largest valid depth, as float bits
  double near_m, far_m;              // integration_depth_band's band ({0, 0}: nothing valid)
};
// Into `out`: the map's valid pixels and integration_depth_band's band to the bit. `sample` and
// `sorted` hold depth_band_samples(pixels) floats; `scratch` is CUB's temporary storage, grown
// as needed. Asynchronous on `stream`.
void launch_depth_summary_cuda(const float* depth, std::size_t pixels, float* sample, float* sorted,
                               DepthSummaryDevice* out, void** scratch, std::size_t* scratch_bytes,
                               cudaStream_t stream);

}  // namespace sls::fusion::detail
