// The CUDA launcher of the simulator's renderer: the same per-pixel functions as the CPU
// backend (drivers/sim/render_shared.h), one thread per pixel, explicit device memory, one
// stream. Geometry stays on the device between the pattern images of a frame.
#include <cuda_runtime.h>

#include "drivers/sim/render_backend.h"
#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/cuda/device_buffer.h"

namespace sls::sim {
namespace {

constexpr int kBlock = 256;

unsigned blocks_for(std::size_t count) { return static_cast<unsigned>((count + kBlock - 1) / kBlock); }

__global__ void trace_kernel(FrameRenderParams params, const Vec3f* rays, const std::uint8_t* valid,
                             PixelGeometry* geometry, std::size_t count) {
  const std::size_t i = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= count) return;
  geometry[i] = trace_pixel(params, rays[i], valid[i] != 0);
}

__global__ void electrons_kernel(const PixelGeometry* geometry, PatternDesc pattern, ProjectorModel projector,
                                 float* electrons, std::size_t count) {
  const std::size_t i = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= count) return;
  electrons[i] = pattern_electrons(geometry[i], pattern, projector);
}

__global__ void blur_rows_kernel(const float* electrons, const PixelGeometry* geometry, float* blurred, int width,
                                 int height) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y);
  if (x >= width || y >= height) return;
  const std::size_t row = static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
  blurred[row + static_cast<std::size_t>(x)] =
      blur_gather_1d(electrons + row, width, 1, x, geometry[row + static_cast<std::size_t>(x)].camera_sigma_px);
}

__global__ void blur_columns_and_sense_kernel(const float* blurred_rows, const PixelGeometry* geometry,
                                              PatternRenderParams params, std::uint16_t* image, int width,
                                              int height) {
  const int x = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  const int y = static_cast<int>(blockIdx.y);
  if (x >= width || y >= height) return;
  const std::size_t index = static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
  const float electrons = blur_gather_1d(blurred_rows + x, height, width, y, geometry[index].camera_sigma_px);
  NoiseKey key = params.key;
  key.pixel = static_cast<std::uint32_t>(index);
  image[index] = pixel_digital_number(params.sensor, exposed_electrons(params, electrons), key, params.noise);
}

__global__ void depth_kernel(const PixelGeometry* geometry, NoiseKey key, float* depth, std::size_t count) {
  const std::size_t i = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= count) return;
  NoiseKey pixel_key = key;
  pixel_key.pixel = static_cast<std::uint32_t>(i);
  depth[i] = noisy_depth(geometry[i], pixel_key);
}

class CudaRenderBackend final : public RenderBackend {
 public:
  CudaRenderBackend(const RayMap& rays, int device_id)
      : device_id_(device_id), width_(rays.width), height_(rays.height), count_(rays.rays.size()) {
    SLS_CUDA_CHECK(cudaSetDevice(device_id_));
    SLS_CUDA_CHECK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
    rays_.allocate(count_);
    valid_.allocate(count_);
    geometry_.allocate(count_);
    electrons_.allocate(count_);
    blurred_rows_.allocate(count_);
    image_.allocate(count_);
    rays_.upload(rays.rays.data(), count_, stream_);
    valid_.upload(rays.valid.data(), count_, stream_);
    SLS_CUDA_CHECK(cudaStreamSynchronize(stream_));
  }
  ~CudaRenderBackend() override {
    if (stream_ != nullptr) (void)cudaStreamDestroy(stream_);
  }
  CudaRenderBackend(const CudaRenderBackend&) = delete;
  CudaRenderBackend& operator=(const CudaRenderBackend&) = delete;

  void trace(const FrameRenderParams& params) override {
    SLS_CUDA_CHECK(cudaSetDevice(device_id_));
    trace_kernel<<<blocks_for(count_), kBlock, 0, stream_>>>(params, rays_.data(), valid_.data(), geometry_.data(),
                                                             count_);
    SLS_CUDA_CHECK_LAUNCH();
  }

  void render_pattern(const PatternRenderParams& params, std::uint16_t* out) override {
    SLS_CUDA_CHECK(cudaSetDevice(device_id_));
    electrons_kernel<<<blocks_for(count_), kBlock, 0, stream_>>>(geometry_.data(), params.pattern, params.projector,
                                                                 electrons_.data(), count_);
    SLS_CUDA_CHECK_LAUNCH();
    const dim3 grid(static_cast<unsigned>((width_ + kBlock - 1) / kBlock), static_cast<unsigned>(height_));
    blur_rows_kernel<<<grid, kBlock, 0, stream_>>>(electrons_.data(), geometry_.data(), blurred_rows_.data(), width_,
                                                   height_);
    SLS_CUDA_CHECK_LAUNCH();
    blur_columns_and_sense_kernel<<<grid, kBlock, 0, stream_>>>(blurred_rows_.data(), geometry_.data(), params,
                                                                image_.data(), width_, height_);
    SLS_CUDA_CHECK_LAUNCH();
    if (out != nullptr) {
      image_.download(out, count_, stream_);
      SLS_CUDA_CHECK(cudaStreamSynchronize(stream_));
    }
  }

  void download_geometry(PixelGeometry* out) const override {
    SLS_CUDA_CHECK(cudaSetDevice(device_id_));
    geometry_.download(out, count_, stream_);
    SLS_CUDA_CHECK(cudaStreamSynchronize(stream_));
  }

  void render_depth(const NoiseKey& key, float* out) override {
    SLS_CUDA_CHECK(cudaSetDevice(device_id_));
    depth_kernel<<<blocks_for(count_), kBlock, 0, stream_>>>(geometry_.data(), key, electrons_.data(), count_);
    SLS_CUDA_CHECK_LAUNCH();
    electrons_.download(out, count_, stream_);
    SLS_CUDA_CHECK(cudaStreamSynchronize(stream_));
  }

  void synchronize() override { SLS_CUDA_CHECK(cudaStreamSynchronize(stream_)); }

 private:
  int device_id_;
  int width_;
  int height_;
  std::size_t count_;
  cudaStream_t stream_ = nullptr;
  DeviceBuffer<Vec3f> rays_;
  DeviceBuffer<std::uint8_t> valid_;
  DeviceBuffer<PixelGeometry> geometry_;
  DeviceBuffer<float> electrons_;
  DeviceBuffer<float> blurred_rows_;
  DeviceBuffer<std::uint16_t> image_;
};

}  // namespace

std::unique_ptr<RenderBackend> make_cuda_render_backend(const RayMap& rays, int device_id) {
  return std::make_unique<CudaRenderBackend>(rays, device_id);
}

}  // namespace sls::sim
