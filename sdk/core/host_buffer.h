// An owning array of host memory that knows where it lives (MemoryType): pageable, or
// page-locked from the pinned cache (pinned_memory.h) so a GPU's copy engine reads it at the
// bus's rate. Image<T> keeps its pixels in one. A kPinned request that cannot be met (no CUDA,
// no GPU, none left) gives pageable memory: memory_type() says what it got.
//
// Copies are deep and live where the source lives; moves take the memory.
#pragma once

#include <algorithm>
#include <cstddef>
#include <memory>
#include <new>
#include <type_traits>
#include <utility>

#include "sdk/core/memory_type.h"
#include "sdk/core/pinned_memory.h"

namespace sls {

template <typename T>
class HostBuffer {
  static_assert(std::is_trivially_copyable_v<T>, "host buffers hold plain values");

 public:
  HostBuffer() = default;
  HostBuffer(std::size_t count, T fill, MemoryType memory = MemoryType::kHost) { assign(count, fill, memory); }
  HostBuffer(const HostBuffer& other) { copy_from(other); }
  HostBuffer(HostBuffer&& other) noexcept { take(other); }
  HostBuffer& operator=(const HostBuffer& other) {
    if (this != &other) copy_from(other);
    return *this;
  }
  HostBuffer& operator=(HostBuffer&& other) noexcept {
    if (this != &other) {
      release();
      take(other);
    }
    return *this;
  }
  ~HostBuffer() { release(); }

  // `count` values of `fill`, in memory of the type asked for (or pageable, see above). Keeps
  // the memory it has when the size and type are unchanged. Throws std::bad_alloc.
  void assign(std::size_t count, T fill, MemoryType memory = MemoryType::kHost) {
    reserve_exactly(count, memory);
    std::fill(data_, data_ + size_, fill);
  }

  T* data() { return data_; }
  const T* data() const { return data_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  // Where the values are; kHost for an empty buffer.
  MemoryType memory_type() const { return pinned_ ? MemoryType::kPinned : MemoryType::kHost; }

  bool operator==(const HostBuffer& other) const {
    return size_ == other.size_ && std::equal(data_, data_ + size_, other.data_);
  }

 private:
  void reserve_exactly(std::size_t count, MemoryType memory) {
    const bool want_pinned = memory == MemoryType::kPinned;
    if (count == size_ && (want_pinned == pinned_ || count == 0)) return;
    release();
    if (count == 0) return;
    if (count > static_cast<std::size_t>(-1) / sizeof(T)) throw std::bad_alloc();
    const std::size_t bytes = count * sizeof(T);
    if (want_pinned) {
      data_ = static_cast<T*>(allocate_pinned(bytes));
      pinned_ = data_ != nullptr;
    }
    if (data_ == nullptr) data_ = static_cast<T*>(::operator new(bytes));
    size_ = count;
  }
  void copy_from(const HostBuffer& other) {
    reserve_exactly(other.size_, other.memory_type());
    if (size_ > 0) std::copy(other.data_, other.data_ + size_, data_);
  }
  void take(HostBuffer& other) noexcept {
    data_ = std::exchange(other.data_, nullptr);
    size_ = std::exchange(other.size_, 0);
    pinned_ = std::exchange(other.pinned_, false);
  }
  void release() noexcept {
    if (data_ != nullptr) {
      if (pinned_) {
        release_pinned(data_, size_ * sizeof(T));
      } else {
        ::operator delete(data_);
      }
    }
    data_ = nullptr;
    size_ = 0;
    pinned_ = false;
  }

  T* data_ = nullptr;
  std::size_t size_ = 0;
  bool pinned_ = false;
};

}  // namespace sls
