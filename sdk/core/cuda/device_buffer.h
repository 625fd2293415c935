// Owning, explicit device memory (no managed memory, DESIGN.md section 6). Allocation
// failure is sls::Error(kOutOfMemory) naming the size, so "the volume does not fit" is a
// clear error, not a crash. Copies take a stream and are asynchronous.
#pragma once

#include <cstddef>
#include <utility>

#include <cuda_runtime_api.h>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/device.h"

namespace sls {

template <typename T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(std::size_t count) { allocate(count); }
  ~DeviceBuffer() { release(); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& other) noexcept
      : data_(std::exchange(other.data_, nullptr)), count_(std::exchange(other.count_, 0)) {}
  DeviceBuffer& operator=(DeviceBuffer&& other) noexcept {
    if (this != &other) {
      release();
      data_ = std::exchange(other.data_, nullptr);
      count_ = std::exchange(other.count_, 0);
    }
    return *this;
  }

  void allocate(std::size_t count) {
    release();
    if (count == 0) return;
    void* pointer = nullptr;
    const cudaError_t status = cudaMalloc(&pointer, count * sizeof(T));
    if (status != cudaSuccess) {
      (void)cudaGetLastError();
      std::size_t free_bytes = 0, total_bytes = 0;
      (void)cudaMemGetInfo(&free_bytes, &total_bytes);
      throw_error(status == cudaErrorMemoryAllocation ? ErrorCode::kOutOfMemory : ErrorCode::kDevice,
                  "cannot allocate {:.1f} MiB on the GPU ({:.1f} MiB free of {:.1f} MiB): {}",
                  static_cast<double>(count * sizeof(T)) / 1048576.0, static_cast<double>(free_bytes) / 1048576.0,
                  static_cast<double>(total_bytes) / 1048576.0, cudaGetErrorString(status));
    }
    data_ = static_cast<T*>(pointer);
    count_ = count;
    note_gpu_allocation(static_cast<std::ptrdiff_t>(count * sizeof(T)));
  }

  void release() {
    if (data_ != nullptr) {
      (void)cudaFree(data_);
      note_gpu_allocation(-static_cast<std::ptrdiff_t>(count_ * sizeof(T)));
    }
    data_ = nullptr;
    count_ = 0;
  }

  void upload(const T* host, std::size_t count, cudaStream_t stream) {
    check_count(count);
    SLS_CUDA_CHECK(cudaMemcpyAsync(data_, host, count * sizeof(T), cudaMemcpyHostToDevice, stream));
  }
  void download(T* host, std::size_t count, cudaStream_t stream) const {
    check_count(count);
    SLS_CUDA_CHECK(cudaMemcpyAsync(host, data_, count * sizeof(T), cudaMemcpyDeviceToHost, stream));
  }

  T* data() { return data_; }
  const T* data() const { return data_; }
  std::size_t size() const { return count_; }
  std::size_t size_bytes() const { return count_ * sizeof(T); }

 private:
  void check_count(std::size_t count) const {
    if (count > count_) {
      throw_error(ErrorCode::kInvalidArgument, "copy of {} elements into a device buffer of {}", count, count_);
    }
  }

  T* data_ = nullptr;
  std::size_t count_ = 0;
};

}  // namespace sls
