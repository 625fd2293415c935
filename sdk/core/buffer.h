// An owning array that knows where it lives (MemoryType, as nvblox's): pageable host memory,
// page-locked host memory from the pinned cache (pinned_memory.h) so a GPU's copy engine reads
// it at the bus's rate, or a CUDA GPU's memory (device_memory.h). Image<T> keeps its pixels in
// one, and DeviceBuffer<T> (sdk/core/cuda) is one on the device. A kPinned request that cannot be
// met (no CUDA, no GPU, none left) gives pageable memory: memory_type() says what it got. A
// kDevice request that cannot be met throws (allocate_device).
//
// Copies are deep and live where the source lives; moves take the memory. Element access
// (operator[]) is for host memory; device memory is read by kernels through data(), or copied.
#pragma once

#include <algorithm>
#include <cstddef>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>
#include <vector>

#include "sdk/core/device_memory.h"
#include "sdk/core/memory_type.h"
#include "sdk/core/pinned_memory.h"

namespace sls {

template <typename T>
class Buffer {
  static_assert(std::is_trivially_copyable_v<T>, "buffers hold plain values");

 public:
  Buffer() = default;
  Buffer(std::size_t count, T fill, MemoryType memory = MemoryType::kHost) { assign(count, fill, memory); }
  Buffer(const Buffer& other) { copy_from(other); }
  Buffer(Buffer&& other) noexcept { take(other); }
  Buffer& operator=(const Buffer& other) {
    if (this != &other) copy_from(other);
    return *this;
  }
  Buffer& operator=(Buffer&& other) noexcept {
    if (this != &other) {
      release();
      take(other);
    }
    return *this;
  }
  ~Buffer() { release(); }

  // `count` values of `fill`, in memory of the type asked for (or pageable, see above). Keeps
  // the memory it has when the size and type are unchanged. Throws std::bad_alloc, and for
  // device memory allocate_device's errors.
  void assign(std::size_t count, T fill, MemoryType memory = MemoryType::kHost) {
    resize_uninitialized(count, memory);
    if (size_ == 0) return;
    if (memory_ != MemoryType::kDevice) {
      std::fill(data_, data_ + size_, fill);
    } else if (is_zero(fill)) {
      zero_device(data_, size_ * sizeof(T));
    } else {
      const std::vector<T> values(size_, fill);
      copy_memory(data_, values.data(), size_ * sizeof(T), true);
    }
  }
  // `count` values whose contents are unspecified, in memory of the type asked for; keeps the
  // memory it has when the size and type are unchanged.
  void resize_uninitialized(std::size_t count, MemoryType memory) {
    if (count == size_ && (memory == requested_ || count == 0)) return;
    release();
    requested_ = memory;
    if (count == 0) return;
    if (count > static_cast<std::size_t>(-1) / sizeof(T)) throw std::bad_alloc();
    const std::size_t bytes = count * sizeof(T);
    if (memory == MemoryType::kDevice) {
      data_ = static_cast<T*>(allocate_device(bytes));
      memory_ = MemoryType::kDevice;
    } else if (memory == MemoryType::kPinned) {
      data_ = static_cast<T*>(allocate_pinned(bytes));
      if (data_ != nullptr) memory_ = MemoryType::kPinned;
    }
    if (data_ == nullptr) {
      data_ = static_cast<T*>(::operator new(bytes));
      memory_ = MemoryType::kHost;
    }
    size_ = count;
  }
  // Gives the memory back; the buffer is empty.
  void clear() noexcept { release(); }

  T* data() { return data_; }
  const T* data() const { return data_; }
  std::size_t size() const { return size_; }
  std::size_t size_bytes() const { return size_ * sizeof(T); }
  bool empty() const { return size_ == 0; }
  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  // Where the values are; kHost for an empty buffer.
  MemoryType memory_type() const { return memory_; }

  // Equal sizes and values (device values compared through host copies).
  bool operator==(const Buffer& other) const {
    if (size_ != other.size_) return false;
    if (memory_ != MemoryType::kDevice && other.memory_ != MemoryType::kDevice) {
      return std::equal(data_, data_ + size_, other.data_);
    }
    return other.host_values() == host_values();
  }

  // The values in a host vector (copied from the device where they live there).
  std::vector<T> host_values() const {
    std::vector<T> values(size_);
    copy_memory(values.data(), data_, size_bytes(), memory_ == MemoryType::kDevice);
    return values;
  }

 private:
  static bool is_zero(const T& value) {
    const unsigned char* bytes = reinterpret_cast<const unsigned char*>(&value);
    return std::all_of(bytes, bytes + sizeof(T), [](unsigned char b) { return b == 0; });
  }
  void copy_from(const Buffer& other) {
    resize_uninitialized(other.size_, other.memory_);
    copy_memory(data_, other.data_, size_bytes(),
                memory_ == MemoryType::kDevice || other.memory_ == MemoryType::kDevice);
  }
  void take(Buffer& other) noexcept {
    data_ = std::exchange(other.data_, nullptr);
    size_ = std::exchange(other.size_, 0);
    memory_ = std::exchange(other.memory_, MemoryType::kHost);
    requested_ = std::exchange(other.requested_, MemoryType::kHost);
  }
  void release() noexcept {
    if (data_ != nullptr) {
      const std::size_t bytes = size_ * sizeof(T);
      if (memory_ == MemoryType::kDevice) {
        release_device(data_, bytes);
      } else if (memory_ == MemoryType::kPinned) {
        release_pinned(data_, bytes);
      } else {
        ::operator delete(data_);
      }
    }
    data_ = nullptr;
    size_ = 0;
    memory_ = MemoryType::kHost;
  }

  T* data_ = nullptr;
  std::size_t size_ = 0;
  MemoryType memory_ = MemoryType::kHost;     // where data_ is
  MemoryType requested_ = MemoryType::kHost;  // what the last allocation asked for
};

}  // namespace sls
