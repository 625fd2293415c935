// CUDA launchers of the moving volume: one thread per voxel around resample_voxel, one per
// voxel for the crossings on its three edges and one per cell for the marching-cubes cases of
// the leaving part (resample_shared.h, extract_shared.h: the code the CPU loops run). Built
// with -fmad=false (fusion/CMakeLists.txt): no fused multiply-adds, so every float operation
// rounds as on the CPU and both backends produce the same bits.
#include "fusion/cuda/resample_cuda.h"

#include <cub/device/device_radix_sort.cuh>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/kernel_profile.h"
#include "sdk/core/parallel_for.h"

namespace sls::fusion::detail {
namespace {

__global__ void resample_kernel(VolumeView from, VolumeView to, Rigid3f grid_from_to) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int j = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  const int k = static_cast<int>(blockIdx.z);
  if (i >= to.nx || j >= to.ny) return;
  resample_voxel(from, to, grid_from_to, i, j, k);
}

// A region brick's voxels: 32 along a row (a warp), 4 rows, 4 layers.
constexpr int kRegionBrickX = 32, kRegionBrickY = 4, kRegionBrickZ = 4;  // scalars: usable in device code

struct RegionBricks {
  int x = 0, y = 0, z = 0;  // bricks along each axis
  explicit RegionBricks(const VolumeView& v)
      : x((v.nx + kRegionBrickX - 1) / kRegionBrickX),
        y((v.ny + kRegionBrickY - 1) / kRegionBrickY),
        z((v.nz + kRegionBrickZ - 1) / kRegionBrickZ) {}
  SLS_HOST_DEVICE std::uint32_t count() const {
    return static_cast<std::uint32_t>(x) * static_cast<std::uint32_t>(y) * static_cast<std::uint32_t>(z);
  }
  // Brick b's first voxel.
  SLS_HOST_DEVICE void first(std::uint32_t b, int voxel[3]) const {
    const auto bx = static_cast<std::uint32_t>(x), by = static_cast<std::uint32_t>(y);
    voxel[0] = static_cast<int>(b % bx) * kRegionBrickX;
    voxel[1] = static_cast<int>((b / bx) % by) * kRegionBrickY;
    voxel[2] = static_cast<int>(b / (bx * by)) * kRegionBrickZ;
  }
};

// Each listed brick's voxels read once (the neighbours they read are mostly the brick's own).
double region_bytes(const VolumeView& volume, std::uint32_t brick_count) {
  return static_cast<double>(brick_count) * kRegionBrickX * kRegionBrickY * kRegionBrickZ *
         static_cast<double>(volume.bytes_per_voxel());
}

dim3 region_block() { return dim3(kRegionBrickX, kRegionBrickY, kRegionBrickZ); }

__global__ void region_bricks_kernel(VolumeView volume, RegionFilter region, RegionBricks bricks, std::uint32_t* out,
                                     std::uint32_t* count) {
  const std::uint32_t b = blockIdx.x * blockDim.x + threadIdx.x;
  bool keep = false;
  if (b < bricks.count()) {
    int first[3], last[3];
    bricks.first(b, first);
    last[0] = min(first[0] + kRegionBrickX, volume.nx) - 1;
    last[1] = min(first[1] + kRegionBrickY, volume.ny) - 1;
    last[2] = min(first[2] + kRegionBrickZ, volume.nz) - 1;
    keep = !region_drops_voxels(region, volume.voxel_size_m, first, last);
  }
  // One atomic per warp (blockDim.x is a multiple of 32, so no lane has left).
  const unsigned want = __ballot_sync(0xffffffffu, keep);
  if (want == 0u) return;
  const unsigned lane = threadIdx.x % 32u;
  const int leader = __ffs(static_cast<int>(want)) - 1;
  std::uint32_t base = 0;
  if (static_cast<int>(lane) == leader) base = atomicAdd(count, static_cast<std::uint32_t>(__popc(want)));
  base = __shfl_sync(0xffffffffu, base, leader);
  if (keep) out[base + static_cast<std::uint32_t>(__popc(want & ((1u << lane) - 1u)))] = b;
}

// The voxel of this thread in its block's brick; false past the volume's end.
__device__ bool region_voxel(const VolumeView& volume, const RegionBricks& bricks, const std::uint32_t* listed, int* i,
                             int* j, int* k) {
  int first[3];
  bricks.first(listed[blockIdx.x], first);
  *i = first[0] + static_cast<int>(threadIdx.x);
  *j = first[1] + static_cast<int>(threadIdx.y);
  *k = first[2] + static_cast<int>(threadIdx.z);
  return *i < volume.nx && *j < volume.ny && *k < volume.nz;
}

// The format known when compiled (extract_shared.h's *_as<F>): no test of it at each read.
template <VoxelFormat F>
__global__ void region_crossings_kernel(VolumeView volume, RegionFilter region, float min_weight, RegionBricks bricks,
                                        const std::uint32_t* listed, EdgeCrossing* out, std::uint32_t capacity,
                                        std::uint32_t* count) {
  int i = 0, j = 0, k = 0;
  if (!region_voxel(volume, bricks, listed, &i, &j, &k)) return;
  if (!voxel_usable_as<F>(volume, volume.index(i, j, k), min_weight)) return;
  for (int axis = 0; axis < 3; ++axis) {
    // Place first: the normal's gradient only for the crossings the region keeps (most of the
    // volume's surface stays in it; computing every normal first took 24 ms at 960³).
    EdgeZero zero;
    if (!edge_zero_as<F>(volume, i, j, k, axis, min_weight, &zero)) continue;
    if (!region_keeps(region, zero.point_volume) && !edge_has_region_cell(volume, region, i, j, k, axis)) continue;
    EdgeCrossing found;
    found.crossing = edge_zero_crossing_as<F>(volume, i, j, k, axis, zero);
    found.edge_id = grid_edge_id(volume, i, j, k, axis);
    const std::uint32_t slot = atomicAdd(count, 1u);
    if (slot < capacity) out[slot] = found;
  }
}

template <VoxelFormat F>
__global__ void region_cells_kernel(VolumeView volume, RegionFilter region, float min_weight, RegionBricks bricks,
                                    const std::uint32_t* listed, CellCase* out, std::uint32_t capacity,
                                    std::uint32_t* count) {
  int i = 0, j = 0, k = 0;
  if (!region_voxel(volume, bricks, listed, &i, &j, &k)) return;
  if (i + 1 >= volume.nx || j + 1 >= volume.ny || k + 1 >= volume.nz) return;
  if (!voxel_usable_as<F>(volume, volume.index(i, j, k), min_weight)) return;  // cheap reject of the unobserved bulk
  const int cube_case = cell_case_as<F>(volume, i, j, k, min_weight);
  if (cube_case <= 0 || cube_case == 255) return;
  if (!region_keeps(region, cell_centre(volume, i, j, k))) return;
  const std::uint32_t slot = atomicAdd(count, 1u);
  if (slot < capacity) out[slot] = CellCase{static_cast<std::uint64_t>(volume.index(i, j, k)), cube_case};
}

SLS_HOST_DEVICE std::uint64_t sort_key(const EdgeCrossing& crossing) { return crossing.edge_id; }
SLS_HOST_DEVICE std::uint64_t sort_key(const CellCase& cell) { return cell.cell; }

template <typename T>
void grow(DeviceBuffer<T>& buffer, std::size_t count) {
  if (buffer.size() < count) buffer.allocate(count);
}

// Bits a key below `bound` uses (at least 1).
int key_bits(std::uint64_t bound) {
  int bits = 1;
  while (bits < 64 && (bound >> bits) != 0) ++bits;
  return bits;
}

// Sorts items[0, count) by sort_key (keys below `bound`) in place: keys and indices radix-
// sorted as pairs, the items gathered in that order into `sorted`, copied back.
template <typename T>
void sort_by_key(T* items, std::uint32_t count, std::uint64_t bound, DeviceBuffer<T>& sorted, RegionSortScratch& s,
                 cudaStream_t stream) {
  if (count < 2) return;
  grow(s.keys_in, count);
  grow(s.keys_out, count);
  grow(s.order_in, count);
  grow(s.order_out, count);
  grow(sorted, count);
  std::uint64_t* keys = s.keys_in.data();
  std::uint32_t* order = s.order_in.data();
  parallel_for(
      count,
      SLS_LAMBDA(std::size_t n) {
        keys[n] = sort_key(items[n]);
        order[n] = static_cast<std::uint32_t>(n);
      },
      stream);
  const int end_bit = key_bits(bound);
  std::size_t needed = 0;
  SLS_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, needed, s.keys_in.data(), s.keys_out.data(),
                                                 s.order_in.data(), s.order_out.data(), static_cast<int>(count), 0,
                                                 end_bit, stream));
  grow(s.temp, needed);
  SLS_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(s.temp.data(), needed, s.keys_in.data(), s.keys_out.data(),
                                                 s.order_in.data(), s.order_out.data(), static_cast<int>(count), 0,
                                                 end_bit, stream));
  const std::uint32_t* sorted_order = s.order_out.data();
  T* out = sorted.data();
  parallel_for(
      count, SLS_LAMBDA(std::size_t n) { out[n] = items[sorted_order[n]]; }, stream);
  SLS_CUDA_CHECK(cudaMemcpyAsync(items, sorted.data(), count * sizeof(T), cudaMemcpyDeviceToDevice, stream));
}

dim3 voxel_grid(int nx, int ny, int nz, const dim3& block) {
  return dim3((static_cast<unsigned>(nx) + block.x - 1) / block.x, (static_cast<unsigned>(ny) + block.y - 1) / block.y,
              static_cast<unsigned>(nz));
}

}  // namespace

void launch_resample_cuda(const VolumeView& from, const VolumeView& to, const Rigid3f& grid_from_to,
                          cudaStream_t stream) {
  // Each voxel of the new volume written, one of the old one's read for it.
  const KernelTimer timer("resample",
                          static_cast<double>(to.voxel_count()) *
                              static_cast<double>(to.bytes_per_voxel() + from.bytes_per_voxel()),
                          stream);
  if (to.surface_bricks != nullptr) SLS_CUDA_CHECK(cudaMemsetAsync(to.surface_bricks, 0, to.brick_count(), stream));
  const dim3 block(64, 4, 1);
  resample_kernel<<<voxel_grid(to.nx, to.ny, to.nz, block), block, 0, stream>>>(from, to, grid_from_to);
  SLS_CUDA_CHECK_LAUNCH();
}

std::uint32_t region_brick_count(const VolumeView& volume) { return RegionBricks(volume).count(); }

void launch_region_bricks_cuda(const VolumeView& volume, const RegionFilter& region, std::uint32_t* bricks,
                               std::uint32_t* count, cudaStream_t stream) {
  const RegionBricks grid(volume);
  const unsigned threads = 256;  // a multiple of the warp: region_bricks_kernel's ballot
  region_bricks_kernel<<<(grid.count() + threads - 1) / threads, threads, 0, stream>>>(volume, region, grid, bricks,
                                                                                       count);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_region_crossings_cuda(const VolumeView& volume, const RegionFilter& region, float min_weight,
                                  const std::uint32_t* bricks, std::uint32_t brick_count, EdgeCrossing* out,
                                  std::uint32_t capacity, std::uint32_t* count, cudaStream_t stream) {
  if (brick_count == 0) return;
  const KernelTimer timer("ship_region", region_bytes(volume, brick_count), stream);
  const auto kernel = volume.format == VoxelFormat::kFloat32 ? region_crossings_kernel<VoxelFormat::kFloat32>
                                                             : region_crossings_kernel<VoxelFormat::kCompact>;
  kernel<<<brick_count, region_block(), 0, stream>>>(volume, region, min_weight, RegionBricks(volume), bricks, out,
                                                     capacity, count);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_region_cells_cuda(const VolumeView& volume, const RegionFilter& region, float min_weight,
                              const std::uint32_t* bricks, std::uint32_t brick_count, CellCase* out,
                              std::uint32_t capacity, std::uint32_t* count, cudaStream_t stream) {
  if (brick_count == 0) return;
  const KernelTimer timer("ship_region", region_bytes(volume, brick_count), stream);
  const auto kernel = volume.format == VoxelFormat::kFloat32 ? region_cells_kernel<VoxelFormat::kFloat32>
                                                             : region_cells_kernel<VoxelFormat::kCompact>;
  kernel<<<brick_count, region_block(), 0, stream>>>(volume, region, min_weight, RegionBricks(volume), bricks, out,
                                                     capacity, count);
  SLS_CUDA_CHECK_LAUNCH();
}

void sort_region_parts_cuda(EdgeCrossing* crossings, std::uint32_t crossing_count, CellCase* cells,
                            std::uint32_t cell_count, std::uint64_t voxel_count, RegionSortScratch* scratch,
                            cudaStream_t stream) {
  sort_by_key(crossings, crossing_count, 3u * voxel_count, scratch->crossings, *scratch, stream);  // grid_edge_id
  sort_by_key(cells, cell_count, voxel_count, scratch->cells, *scratch, stream);
}

}  // namespace sls::fusion::detail
