// CUDA launchers of the integrator: one thread per voxel around integrate_voxel, one thread
// per active voxel around relax_voxel (integrate_shared.h, the code the CPU loops run).
#include "fusion/cuda/integrate_cuda.h"

#include <algorithm>

#include <cub/device/device_radix_sort.cuh>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/device.h"
#include "sdk/core/kernel_profile.h"
#include "sdk/core/parallel_for.h"

namespace sls::fusion::detail {
namespace {

constexpr unsigned kIntegrateBlockX = 64;  // a multiple of 32: the ballots below take a warp as one row
constexpr unsigned kIntegrateBlockY = 4;
constexpr int kSlicesPerThread = 8;  // voxels a thread integrates along z (1: 2.98 ms, 2: 2.65, 4: 2.50, 8: 2.38 at the paper's size)
constexpr unsigned kIntegrateStaged = kIntegrateBlockX * kIntegrateBlockY * kSlicesPerThread;

// The voxels that take part in the GTSDF relaxation are appended to one list per parity. A
// block stages its voxels in shared memory (red from the front, black from the back; a warp's
// lanes take their slots with one shared atomic per parity, from a ballot) and reserves its
// slots in the global lists with one atomicAdd per parity at the end: global atomics on two
// counters, one per warp, were where the kernel's warps waited most (ncu, a fifth of its stall
// samples). Each thread integrates kSlicesPerThread voxels along z, so a block's reservation
// covers 2 048 voxels. The lists' order is not the result's: they are sorted before the sweeps.
__global__ void __launch_bounds__(kIntegrateBlockX* kIntegrateBlockY)
    integrate_kernel(VolumeView volume, IntegrationParams params, DepthFrameView frame, int i0, int j0, int k0,
                     int i1, int j1, int k1, ActiveVoxel* active_red, ActiveVoxel* active_black,
                     std::uint32_t* counters, std::uint32_t capacity) {
  __shared__ ActiveVoxel staged[kIntegrateStaged];
  __shared__ std::uint32_t staged_count[2];
  __shared__ std::uint32_t reserved[2];
  const unsigned thread = threadIdx.y * blockDim.x + threadIdx.x;
  if (thread < 2u) staged_count[thread] = 0u;
  __syncthreads();
  const int i = i0 + static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int j = j0 + static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  const bool inside = i < i1 && j < j1;
  const unsigned lane = threadIdx.x % 32u;
  const unsigned lanes_before = (1u << lane) - 1u;
  // Every lane runs every slice to the ballots (none leaves the loop early).
  for (int slice = 0; slice < kSlicesPerThread; ++slice) {
    const int k = k0 + static_cast<int>(blockIdx.z) * kSlicesPerThread + slice;
    float average = 0.0f;
    const bool append =
        inside && k < k1 && integrate_voxel(volume, params, frame, i, j, k, &average) && params.alpha > 0.0f;
    const int parity = append ? voxel_parity(i, j, k) : 0;
    for (int p = 0; p < 2; ++p) {
      const unsigned want = __ballot_sync(0xffffffffu, append && parity == p);
      if (want == 0u) continue;
      const int leader = __ffs(static_cast<int>(want)) - 1;
      std::uint32_t first = 0;
      if (static_cast<int>(lane) == leader) first = atomicAdd(&staged_count[p], static_cast<std::uint32_t>(__popc(want)));
      first = __shfl_sync(0xffffffffu, first, leader);
      if (append && parity == p) {
        const std::uint32_t n = first + static_cast<std::uint32_t>(__popc(want & lanes_before));
        staged[p == 0 ? n : kIntegrateStaged - 1u - n] =
            ActiveVoxel{static_cast<std::uint32_t>(volume.index(i, j, k)), average};
      }
    }
  }
  __syncthreads();
  if (thread < 2u) {
    reserved[thread] = staged_count[thread] > 0u ? atomicAdd(&counters[thread], staged_count[thread]) : 0u;
  }
  __syncthreads();
  const std::uint32_t red = staged_count[0], total = red + staged_count[1];
  for (std::uint32_t n = thread; n < total; n += kIntegrateBlockX * kIntegrateBlockY) {
    const bool is_red = n < red;
    const std::uint32_t local = is_red ? n : n - red;
    const std::uint32_t slot = reserved[is_red ? 0 : 1] + local;
    if (slot < capacity) {
      (is_red ? active_red : active_black)[slot] = staged[is_red ? n : kIntegrateStaged - 1u - local];
    }
  }
}

}  // namespace

void launch_integrate_cuda(const VolumeView& volume, const IntegrationParams& params, const DepthFrameView& frame,
                           const int first[3], const int extent[3], ActiveVoxel* const active[2],
                           std::uint32_t* counters, std::uint32_t capacity, cudaStream_t stream) {
  if (extent[0] <= 0 || extent[1] <= 0 || extent[2] <= 0) return;
  // An estimate: the map read, and each voxel of the frustum's box once (a voxel in front of
  // the surface is read and written, one behind it neither; the split depends on the view).
  const double box_voxels = static_cast<double>(extent[0]) * extent[1] * extent[2];
  const KernelTimer timer("integrate",
                          box_voxels * static_cast<double>(volume.bytes_per_voxel()) +
                              4.0 * static_cast<double>(frame.width) * frame.height,
                          stream);
  const dim3 block(kIntegrateBlockX, kIntegrateBlockY, 1);
  const dim3 grid((static_cast<unsigned>(extent[0]) + block.x - 1) / block.x,
                  (static_cast<unsigned>(extent[1]) + block.y - 1) / block.y,
                  (static_cast<unsigned>(extent[2]) + kSlicesPerThread - 1) / kSlicesPerThread);
  integrate_kernel<<<grid, block, 0, stream>>>(volume, params, frame, first[0], first[1], first[2],
                                               first[0] + extent[0], first[1] + extent[1], first[2] + extent[2],
                                               active[0], active[1], counters, capacity);
  SLS_CUDA_CHECK_LAUNCH();
}

namespace {

// CUB's temporary storage, grown to `needed` bytes (its contents are not kept).
void grow_scratch(std::size_t needed, void** scratch, std::size_t* scratch_bytes) {
  if (*scratch_bytes >= needed) return;
  if (*scratch != nullptr) {
    SLS_CUDA_CHECK(cudaFree(*scratch));
    note_gpu_allocation(-static_cast<std::ptrdiff_t>(*scratch_bytes));
  }
  *scratch = nullptr;
  *scratch_bytes = 0;
  SLS_CUDA_CHECK(cudaMalloc(scratch, needed));
  *scratch_bytes = needed;
  note_gpu_allocation(static_cast<std::ptrdiff_t>(needed));
}

}  // namespace

void sort_active_cuda(ActiveVoxel* active, std::uint32_t count, void** scratch, std::size_t* scratch_bytes,
                      ActiveVoxel** sorted, std::size_t* sorted_capacity, cudaStream_t stream) {
  if (count < 2) return;
  // An ActiveVoxel is 8 bytes, index in the low word: sort it as a 64-bit key on bits 0..31.
  static_assert(sizeof(ActiveVoxel) == sizeof(unsigned long long), "ActiveVoxel packs into 64 bits");
  const auto* keys_in = reinterpret_cast<const unsigned long long*>(active);
  if (*sorted_capacity < count) {
    if (*sorted != nullptr) {
      SLS_CUDA_CHECK(cudaFree(*sorted));
      note_gpu_allocation(-static_cast<std::ptrdiff_t>(*sorted_capacity * sizeof(ActiveVoxel)));
    }
    *sorted = nullptr;
    *sorted_capacity = 0;
    SLS_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(sorted), count * sizeof(ActiveVoxel)));
    *sorted_capacity = count;
    note_gpu_allocation(static_cast<std::ptrdiff_t>(count * sizeof(ActiveVoxel)));
  }
  auto* keys_out = reinterpret_cast<unsigned long long*>(*sorted);
  std::size_t needed = 0;
  SLS_CUDA_CHECK(cub::DeviceRadixSort::SortKeys(nullptr, needed, keys_in, keys_out, static_cast<int>(count), 0, 32,
                                                stream));
  grow_scratch(needed, scratch, scratch_bytes);
  SLS_CUDA_CHECK(cub::DeviceRadixSort::SortKeys(*scratch, needed, keys_in, keys_out, static_cast<int>(count), 0, 32,
                                                stream));
  SLS_CUDA_CHECK(cudaMemcpyAsync(active, *sorted, count * sizeof(ActiveVoxel), cudaMemcpyDeviceToDevice, stream));
}

namespace {

constexpr unsigned kSummaryBlock = 256;     // a multiple of the warp: every lane takes part in the shuffles
constexpr unsigned kSummaryMaxBlocks = 1024;  // each block reduces its share, then one atomic of each kind

__global__ void depth_summary_start_kernel(DepthSummaryDevice* out) {
  *out = DepthSummaryDevice{0ull, 0ull, 0xffffffffu, 0u, 0.0, 0.0};
}

// The valid pixels, their range (positive floats order as their bits do) and the sample. Each
// block adds its totals once: with one atomic per warp, 400 000 warps of a 12-megapixel map
// queued on three addresses for 0.8 ms (an H200).
__global__ void depth_summary_kernel(const float* __restrict__ depth, std::size_t pixels, std::size_t samples,
                                     float* __restrict__ sample, DepthSummaryDevice* out) {
  const std::size_t first = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  const std::size_t step = static_cast<std::size_t>(gridDim.x) * blockDim.x;
  unsigned sampled = 0u, count = 0u, lo = 0xffffffffu, hi = 0u;
  for (std::size_t j = first; j < samples; j += step) {
    const float z = depth[j * kDepthBandStride];
    const bool valid = z > 0.0f && isfinite(z);
    sample[j] = valid ? z : 0.0f;
    sampled += valid ? 1u : 0u;
  }
  for (std::size_t i = first; i < pixels; i += step) {
    const float z = depth[i];
    if (z > 0.0f && isfinite(z)) {
      ++count;
      lo = min(lo, __float_as_uint(z));
      hi = max(hi, __float_as_uint(z));
    }
  }
  for (int offset = 16; offset > 0; offset /= 2) {
    sampled += __shfl_down_sync(0xffffffffu, sampled, offset);
    count += __shfl_down_sync(0xffffffffu, count, offset);
    lo = min(lo, __shfl_down_sync(0xffffffffu, lo, offset));
    hi = max(hi, __shfl_down_sync(0xffffffffu, hi, offset));
  }
  __shared__ unsigned warp_totals[kSummaryBlock / 32][4];
  const unsigned warp = threadIdx.x / 32u;
  if ((threadIdx.x & 31u) == 0u) {
    warp_totals[warp][0] = sampled;
    warp_totals[warp][1] = count;
    warp_totals[warp][2] = lo;
    warp_totals[warp][3] = hi;
  }
  __syncthreads();
  if (threadIdx.x != 0u) return;
  for (unsigned w = 1; w < kSummaryBlock / 32; ++w) {
    sampled += warp_totals[w][0];
    count += warp_totals[w][1];
    lo = min(lo, warp_totals[w][2]);
    hi = max(hi, warp_totals[w][3]);
  }
  if (sampled > 0u) atomicAdd(&out->valid_samples, static_cast<unsigned long long>(sampled));
  if (count > 0u) {
    atomicAdd(&out->valid_pixels, static_cast<unsigned long long>(count));
    atomicMin(&out->min_bits, lo);
    atomicMax(&out->max_bits, hi);
  }
}

// integration_depth_band's rule (fusion/depth_band_shared.h) on the sorted sample, whose invalid
// entries (0) come first: the quantiles nth_element finds on the host are these elements.
__global__ void depth_band_kernel(const float* __restrict__ sorted, std::size_t samples, DepthSummaryDevice* out) {
  const std::size_t n = static_cast<std::size_t>(out->valid_samples);
  if (n < kDepthBandMinSamples) {  // the whole valid range; {0, 0} (as started) with nothing valid
    if (out->valid_pixels > 0ull) {
      out->near_m = static_cast<double>(__uint_as_float(out->min_bits));
      out->far_m = static_cast<double>(__uint_as_float(out->max_bits));
    }
    return;
  }
  const float* valid = sorted + (samples - n);
  depth_band_from_quantiles(static_cast<double>(valid[depth_band_quantile_index(kDepthBandQuantile, n)]),
                            static_cast<double>(valid[depth_band_quantile_index(1.0 - kDepthBandQuantile, n)]),
                            &out->near_m, &out->far_m);
}

}  // namespace

void launch_depth_summary_cuda(const float* depth, std::size_t pixels, float* sample, float* sorted,
                               DepthSummaryDevice* out, void** scratch, std::size_t* scratch_bytes,
                               cudaStream_t stream) {
  depth_summary_start_kernel<<<1, 1, 0, stream>>>(out);
  SLS_CUDA_CHECK_LAUNCH();
  if (pixels == 0) return;
  const std::size_t samples = depth_band_samples(pixels);
  const auto blocks = static_cast<unsigned>(std::min<std::size_t>((pixels + kSummaryBlock - 1) / kSummaryBlock,
                                                                  kSummaryMaxBlocks));
  depth_summary_kernel<<<blocks, kSummaryBlock, 0, stream>>>(depth, pixels, samples, sample, out);
  SLS_CUDA_CHECK_LAUNCH();
  std::size_t needed = 0;
  SLS_CUDA_CHECK(cub::DeviceRadixSort::SortKeys(nullptr, needed, sample, sorted, static_cast<int>(samples), 0, 32,
                                                stream));
  grow_scratch(needed, scratch, scratch_bytes);
  SLS_CUDA_CHECK(cub::DeviceRadixSort::SortKeys(*scratch, needed, sample, sorted, static_cast<int>(samples), 0, 32,
                                                stream));
  depth_band_kernel<<<1, 1, 0, stream>>>(sorted, samples, out);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_relax_cuda(const VolumeView& volume, const IntegrationParams& params, const ActiveVoxel* active,
                       std::uint32_t count, cudaStream_t stream) {
  // Each active voxel's entry read, its voxel read and written (its neighbours are others').
  const double voxel_bytes = static_cast<double>(volume.bytes_per_voxel());
  const KernelTimer timer("gtsdf_sweep", static_cast<double>(count) * (8.0 + 2.0 * voxel_bytes), stream);
  parallel_for(
      count, SLS_LAMBDA(std::size_t n) { relax_active_voxel(volume, params, active, n); }, stream);
}

}  // namespace sls::fusion::detail
