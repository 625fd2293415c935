// CUDA backend of the ray map: a thin launcher around ray_map_pixel (sdk/core/ray_map.h),
// the same per-pixel code the CPU loop runs.
#include "sdk/core/cuda/ray_map_cuda.h"

#include <cstddef>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/cuda/device_buffer.h"
#include "sdk/core/ray_map.h"

namespace sls::detail {
namespace {

__global__ void ray_map_kernel(CameraIntrinsics intrinsics, Vec3f* rays, std::uint8_t* valid) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y * blockDim.y + threadIdx.y);
  if (x >= intrinsics.width || y >= intrinsics.height) return;
  const std::size_t i =
      static_cast<std::size_t>(y) * static_cast<std::size_t>(intrinsics.width) + static_cast<std::size_t>(x);
  Vec3f ray;
  valid[i] = ray_map_pixel(intrinsics, x, y, &ray) ? std::uint8_t{1} : std::uint8_t{0};
  rays[i] = ray;
}

// Owns a stream so an exception on the way out still destroys it.
class Stream {
 public:
  Stream() { SLS_CUDA_CHECK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking)); }
  ~Stream() { (void)cudaStreamDestroy(stream_); }
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  cudaStream_t get() const { return stream_; }

 private:
  cudaStream_t stream_ = nullptr;
};

}  // namespace

void launch_ray_map_cuda(const CameraIntrinsics& intrinsics, Vec3f* rays_device, std::uint8_t* valid_device,
                    cudaStream_t stream) {
  if (intrinsics.width <= 0 || intrinsics.height <= 0) return;
  const dim3 block(32, 8);
  const dim3 grid((static_cast<unsigned>(intrinsics.width) + block.x - 1) / block.x,
                  (static_cast<unsigned>(intrinsics.height) + block.y - 1) / block.y);
  ray_map_kernel<<<grid, block, 0, stream>>>(intrinsics, rays_device, valid_device);
  SLS_CUDA_CHECK_LAUNCH();
}

void compute_ray_map_cuda(const CameraIntrinsics& intrinsics, Vec3f* rays_host, std::uint8_t* valid_host) {
  const std::size_t count =
      static_cast<std::size_t>(intrinsics.width) * static_cast<std::size_t>(intrinsics.height);
  if (count == 0) return;
  const Stream stream;
  DeviceBuffer<Vec3f> rays(count);
  DeviceBuffer<std::uint8_t> valid(count);
  launch_ray_map_cuda(intrinsics, rays.data(), valid.data(), stream.get());
  rays.download(rays_host, count, stream.get());
  valid.download(valid_host, count, stream.get());
  SLS_CUDA_CHECK(cudaStreamSynchronize(stream.get()));
}

}  // namespace sls::detail
