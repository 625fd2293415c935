// A Buffer<T> in a GPU's memory (MemoryType::kDevice, buffer.h) for CUDA backend sources: sized
// by allocate(), uninitialised, with copies that take a stream and are asynchronous. Allocation
// failure is sls::Error(kOutOfMemory) naming the size, so "the volume does not fit" is a clear
// error, not a crash. Not copyable (a stage's scratch memory is not duplicated by accident).
#pragma once

#include <cstddef>
#include <utility>

#include <cuda_runtime_api.h>

#include "sdk/core/buffer.h"
#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/error.h"

namespace sls {

template <typename T>
class DeviceBuffer : public Buffer<T> {
 public:
  DeviceBuffer() = default;
  explicit DeviceBuffer(std::size_t count) { allocate(count); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&&) noexcept = default;
  DeviceBuffer& operator=(DeviceBuffer&&) noexcept = default;
  ~DeviceBuffer() = default;

  // `count` elements of device memory (kept when the size is unchanged); contents unspecified.
  void allocate(std::size_t count) { this->resize_uninitialized(count, MemoryType::kDevice); }
  void release() { this->clear(); }

  void upload(const T* host, std::size_t count, cudaStream_t stream) {
    check_count(count);
    SLS_CUDA_CHECK(cudaMemcpyAsync(this->data(), host, count * sizeof(T), cudaMemcpyHostToDevice, stream));
  }
  void download(T* host, std::size_t count, cudaStream_t stream) const {
    check_count(count);
    SLS_CUDA_CHECK(cudaMemcpyAsync(host, this->data(), count * sizeof(T), cudaMemcpyDeviceToHost, stream));
  }

 private:
  void check_count(std::size_t count) const {
    if (count > this->size()) {
      throw_error(ErrorCode::kInvalidArgument, "copy of {} elements into a device buffer of {}", count,
                  this->size());
    }
  }
};

}  // namespace sls
