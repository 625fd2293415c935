// CUDA launchers of the ICP tracker: one thread per pixel around downsample_depth,
// live_normal, accumulate_frame_statistics and track_pixel (track_shared.h), and for the
// photometric term downsample_texture, accumulate_texture_statistics and photometric_pixel
// (photometric_shared.h): the code the CPU loops run, with the two-stage reductions described
// in track_cuda.h.
#include "fusion/cuda/track_cuda.h"

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/kernel_profile.h"

namespace sls::fusion::detail {
namespace {

constexpr int kWarps = kTrackThreads / 32;

int reduction_blocks(int pixels) {
  const int blocks = (pixels + kTrackThreads - 1) / kTrackThreads;
  return blocks < 1 ? 1 : (blocks > kTrackMaxBlocks ? kTrackMaxBlocks : blocks);
}

// The block's N sums (each thread's in `values`) into partials[blockIdx.x * N + k], in double.
// Every thread of the block must call it.
template <int N>
__device__ void block_sums_to_partials(float (&values)[N], double* partials) {
  __shared__ float warp_sums[N][kWarps];
  const int lane = static_cast<int>(threadIdx.x) & 31;
  const int warp = static_cast<int>(threadIdx.x) >> 5;
#pragma unroll
  for (int k = 0; k < N; ++k) {
    float value = values[k];
#pragma unroll
    for (int offset = 16; offset > 0; offset >>= 1) value += __shfl_down_sync(0xffffffffu, value, offset);
    if (lane == 0) warp_sums[k][warp] = value;
  }
  __syncthreads();
  if (threadIdx.x < static_cast<unsigned>(N)) {
    double sum = 0.0;
    for (int w = 0; w < kWarps; ++w) sum += static_cast<double>(warp_sums[threadIdx.x][w]);
    partials[static_cast<std::size_t>(blockIdx.x) * N + threadIdx.x] = sum;
  }
}

// Block k adds column k of the partials over `blocks` blocks, in double, in a fixed order.
template <int N>
__global__ void finish_sums_kernel(const double* __restrict__ partials, int blocks, double* __restrict__ out) {
  __shared__ double shared[kTrackThreads];
  const int k = static_cast<int>(blockIdx.x);
  double sum = 0.0;
  for (int b = static_cast<int>(threadIdx.x); b < blocks; b += kTrackThreads) {
    sum += partials[static_cast<std::size_t>(b) * N + static_cast<std::size_t>(k)];
  }
  shared[threadIdx.x] = sum;
  __syncthreads();
  for (int stride = kTrackThreads / 2; stride > 0; stride >>= 1) {
    if (static_cast<int>(threadIdx.x) < stride) shared[threadIdx.x] += shared[threadIdx.x + static_cast<unsigned>(stride)];
    __syncthreads();
  }
  if (threadIdx.x == 0) out[k] = shared[0];
}

__global__ void downsample_kernel(const float* __restrict__ fine, const float* __restrict__ fine_weight,
                                  int fine_width, int fine_height, float fine_fx, float* __restrict__ coarse,
                                  float* __restrict__ coarse_weight, int coarse_width, int coarse_height) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= coarse_width || y >= coarse_height) return;
  const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(coarse_width) + static_cast<std::size_t>(x);
  float weight = 0.0f;
  coarse[i] = downsample_depth(fine, fine_width, fine_height, fine_fx, x, y, fine_weight,
                               coarse_weight != nullptr ? &weight : nullptr);
  if (coarse_weight != nullptr) coarse_weight[i] = weight;
}

__global__ void live_normals_kernel(const float* __restrict__ depth, const Vec3f* __restrict__ rays, int width,
                                    int height, float fx, float baseline_m, Vec3f* __restrict__ normals) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= width || y >= height) return;
  normals[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] =
      live_normal(depth, rays, width, height, fx, baseline_m, x, y);
}

__global__ void model_normals_kernel(const Vec3f* __restrict__ points, int width, int height, float fx,
                                     float baseline_m, Vec3f* __restrict__ normals) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= width || y >= height) return;
  normals[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] =
      baseline_normal(PointMap{points}, width, height, fx, baseline_m, x, y);
}

__global__ void model_creases_kernel(const Vec3f* __restrict__ normals, const Vec3f* __restrict__ points, int width,
                                     int height, float fx, float radius_m, float min_cos,
                                     std::uint8_t* __restrict__ mask) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= width || y >= height) return;
  mask[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)] =
      near_crease(normals, points, width, height, fx, radius_m, min_cos, x, y) ? 1 : 0;
}

__global__ void frame_statistics_kernel(const Vec3f* __restrict__ model_points, const float* __restrict__ live_depth,
                                        const Vec3f* __restrict__ live_rays, TrackRegion region, int pixels,
                                        Vec3f reference, double* __restrict__ partials) {
  float sums[kFrameSums] = {};
  for (int n = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x); n < pixels;
       n += static_cast<int>(gridDim.x * blockDim.x)) {
    accumulate_frame_statistics(model_points[n], live_depth[n], live_rays[n], region, reference, sums);
  }
  block_sums_to_partials<kFrameSums>(sums, partials);
}

__global__ void track_kernel(TrackLiveView live, TrackModelView model, TrackParams params,
                             double* __restrict__ partials) {
  float sums[kTrackSums] = {};
  const int pixels = live.width * live.height;
  for (int n = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x); n < pixels;
       n += static_cast<int>(gridDim.x * blockDim.x)) {
    accumulate_track_pixel(live, model, params, n, sums);
  }
  block_sums_to_partials<kTrackSums>(sums, partials);
}

__global__ void downsample_texture_kernel(const float* __restrict__ fine, int fine_width, int fine_height,
                                          float* __restrict__ coarse, int coarse_width, int coarse_height) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= coarse_width || y >= coarse_height) return;
  coarse[static_cast<std::size_t>(y) * static_cast<std::size_t>(coarse_width) + static_cast<std::size_t>(x)] =
      downsample_texture(fine, fine_width, fine_height, x, y);
}

__global__ void texture_statistics_kernel(const float* __restrict__ texture, const float* __restrict__ depth,
                                          int pixels, double* __restrict__ partials) {
  float sums[kTextureSums] = {};
  for (int n = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x); n < pixels;
       n += static_cast<int>(gridDim.x * blockDim.x)) {
    accumulate_texture_statistics(texture[n], depth[n], sums);
  }
  block_sums_to_partials<kTextureSums>(sums, partials);
}

__global__ void photometric_kernel(PhotometricLevelView reference, PhotometricLevelView live, PhotometricParams params,
                                   double* __restrict__ partials) {
  float sums[kPhotometricSums] = {};
  const int pixels = reference.width * reference.height;
  for (int n = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x); n < pixels;
       n += static_cast<int>(gridDim.x * blockDim.x)) {
    const int y = n / reference.width;
    const int x = n - y * reference.width;
    float jacobian[6];
    float residual = 0.0f, live_value = 0.0f, ref_value = 0.0f;
    const int outcome = photometric_pixel(reference, live, params, x, y, jacobian, &residual, &live_value, &ref_value);
    accumulate_photometric(outcome, jacobian, residual, live_value, ref_value, params.huber, sums);
  }
  block_sums_to_partials<kPhotometricSums>(sums, partials);
}

dim3 image_grid(int width, int height, dim3 block) {
  return dim3((static_cast<unsigned>(width) + block.x - 1) / block.x,
              (static_cast<unsigned>(height) + block.y - 1) / block.y);
}

}  // namespace

void launch_downsample_depth_cuda(const float* fine, const float* fine_weight, int fine_width, int fine_height,
                                  float fine_fx, float* coarse, float* coarse_weight, int coarse_width,
                                  int coarse_height, cudaStream_t stream) {
  const dim3 block(32, 8);
  downsample_kernel<<<image_grid(coarse_width, coarse_height, block), block, 0, stream>>>(
      fine, fine_weight, fine_width, fine_height, fine_fx, coarse, coarse_weight, coarse_width, coarse_height);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_live_normals_cuda(const float* depth, const Vec3f* rays, int width, int height, float fx,
                              float baseline_m, Vec3f* normals, cudaStream_t stream) {
  const dim3 block(32, 8);
  live_normals_kernel<<<image_grid(width, height, block), block, 0, stream>>>(depth, rays, width, height, fx,
                                                                              baseline_m, normals);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_model_creases_cuda(const Vec3f* points, int width, int height, float fx, float baseline_m,
                               float radius_m, float min_cos, Vec3f* normals, std::uint8_t* mask,
                               cudaStream_t stream) {
  const dim3 block(32, 8);
  const dim3 grid = image_grid(width, height, block);
  model_normals_kernel<<<grid, block, 0, stream>>>(points, width, height, fx, baseline_m, normals);
  SLS_CUDA_CHECK_LAUNCH();
  model_creases_kernel<<<grid, block, 0, stream>>>(normals, points, width, height, fx, radius_m, min_cos, mask);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_frame_statistics_cuda(const Vec3f* model_points, const float* live_depth, const Vec3f* live_rays,
                                  const TrackRegion& region, int pixels, Vec3f reference, double* partials,
                                  double* out, cudaStream_t stream) {
  const int blocks = reduction_blocks(pixels);
  frame_statistics_kernel<<<blocks, kTrackThreads, 0, stream>>>(model_points, live_depth, live_rays, region, pixels,
                                                                 reference, partials);
  SLS_CUDA_CHECK_LAUNCH();
  finish_sums_kernel<kFrameSums><<<kFrameSums, kTrackThreads, 0, stream>>>(partials, blocks, out);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_track_cuda(const TrackLiveView& live, const TrackModelView& model, const TrackParams& params,
                       double* partials, double* out, cudaStream_t stream) {
  // Per live pixel its depth, ray, normal (and weight) read, and the model's point and normal
  // it projects to.
  const double pixel_bytes = 4.0 + 12.0 + 12.0 + (live.weights != nullptr ? 4.0 : 0.0) + 24.0;
  const KernelTimer timer("icp_reduction", pixel_bytes * static_cast<double>(live.width) * live.height, stream);
  const int blocks = reduction_blocks(live.width * live.height);
  track_kernel<<<blocks, kTrackThreads, 0, stream>>>(live, model, params, partials);
  SLS_CUDA_CHECK_LAUNCH();
  finish_sums_kernel<kTrackSums><<<kTrackSums, kTrackThreads, 0, stream>>>(partials, blocks, out);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_downsample_texture_cuda(const float* fine, int fine_width, int fine_height, float* coarse,
                                    int coarse_width, int coarse_height, cudaStream_t stream) {
  const dim3 block(32, 8);
  downsample_texture_kernel<<<image_grid(coarse_width, coarse_height, block), block, 0, stream>>>(
      fine, fine_width, fine_height, coarse, coarse_width, coarse_height);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_texture_statistics_cuda(const float* texture, const float* depth, int pixels, double* partials,
                                    double* out, cudaStream_t stream) {
  const int blocks = reduction_blocks(pixels);
  texture_statistics_kernel<<<blocks, kTrackThreads, 0, stream>>>(texture, depth, pixels, partials);
  SLS_CUDA_CHECK_LAUNCH();
  finish_sums_kernel<kTextureSums><<<kTextureSums, kTrackThreads, 0, stream>>>(partials, blocks, out);
  SLS_CUDA_CHECK_LAUNCH();
}

void launch_photometric_cuda(const PhotometricLevelView& reference, const PhotometricLevelView& live,
                             const PhotometricParams& params, double* partials, double* out, cudaStream_t stream) {
  const int blocks = reduction_blocks(reference.width * reference.height);
  photometric_kernel<<<blocks, kTrackThreads, 0, stream>>>(reference, live, params, partials);
  SLS_CUDA_CHECK_LAUNCH();
  finish_sums_kernel<kPhotometricSums><<<kPhotometricSums, kTrackThreads, 0, stream>>>(partials, blocks, out);
  SLS_CUDA_CHECK_LAUNCH();
}

}  // namespace sls::fusion::detail
