// Images: owning buffers (Image<T>) and non-owning views (ImageView<T>) for 8/16-bit
// integer, float and Vec3f pixels. Views are trivially copyable plain structs so kernels and
// *_shared.h code take them by value; rows are addressed through a byte stride so a view
// can describe a pitched CUDA allocation or a sub-rectangle.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "sdk/core/buffer.h"
#include "sdk/core/error.h"
#include "sdk/core/host_device.h"
#include "sdk/core/memory_type.h"

namespace sls {

// Rows first, first + step, ..., count of them (a grid's rows of an image).
struct RowSet {
  int first = 0;
  int step = 1;
  int count = 0;
};

template <typename T>
struct ImageView {
  T* data = nullptr;
  int width = 0;
  int height = 0;
  std::size_t stride_bytes = 0;  // bytes from one row to the next

  SLS_HOST_DEVICE T* row(int y) const {
    return reinterpret_cast<T*>(reinterpret_cast<
        std::conditional_t<std::is_const_v<T>, const unsigned char*, unsigned char*>>(data) +
        static_cast<std::size_t>(y) * stride_bytes);
  }
  SLS_HOST_DEVICE T& operator()(int x, int y) const { return row(y)[x]; }
  SLS_HOST_DEVICE bool contains(int x, int y) const {
    return x >= 0 && y >= 0 && x < width && y < height;
  }
  SLS_HOST_DEVICE bool empty() const { return width <= 0 || height <= 0; }
  SLS_HOST_DEVICE std::size_t pixel_count() const {
    return static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  }
  // A view is implicitly a view of const pixels.
  SLS_HOST_DEVICE operator ImageView<const T>() const { return {data, width, height, stride_bytes}; }
};

// An owning image that knows where its pixels live (as nvblox's Image<T>(MemoryType)): pageable
// host memory, page-locked (MemoryType::kPinned) for images a GPU reads — a camera's pattern
// images when the scan fuses on a GPU — or a GPU's memory (kDevice: a depth map the decoder
// left there for tracking and integration). Copies live where the source lives. Pixel access
// (operator(), view()'s rows) is for host images; a device image is read by kernels through
// data() and view(), or copied.
template <typename T>
class Image {
  static_assert(std::is_trivially_copyable_v<T>, "pixels are plain values (integers, floats, Vec3f)");

 public:
  Image() = default;
  // An empty image whose pixels, once resized, go to `memory` (a driver fills it with resize).
  explicit Image(MemoryType memory) : memory_(memory) {}
  Image(int width, int height, T fill = T{}, MemoryType memory = MemoryType::kHost) : memory_(memory) {
    resize(width, height, fill);
  }

  // Into the memory the image was made for (a kPinned request may get pageable memory:
  // memory_type() says where the pixels are).
  void resize(int width, int height, T fill = T{}) {
    if (width < 0 || height < 0) {
      throw_error(ErrorCode::kInvalidArgument, "image size {}x{} is negative", width, height);
    }
    width_ = width;
    height_ = height;
    pixels_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), fill, memory_);
  }

  // The same without the fill, for a writer that sets every pixel next (a PNG's rows): a
  // 12 MP image is not written twice.
  void resize_uninitialized(int width, int height) {
    if (width < 0 || height < 0) {
      throw_error(ErrorCode::kInvalidArgument, "image size {}x{} is negative", width, height);
    }
    width_ = width;
    height_ = height;
    pixels_.resize_uninitialized(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), memory_);
  }

  int width() const { return width_; }
  int height() const { return height_; }
  bool empty() const { return pixels_.empty(); }
  std::size_t pixel_count() const { return pixels_.size(); }
  MemoryType memory_type() const { return pixels_.memory_type(); }
  // Where resize() puts the pixels: what Image(MemoryType) asked for (an empty image's pixels
  // are nowhere yet; a kPinned request may have got pageable memory).
  MemoryType memory_requested() const { return memory_; }
  std::size_t size_bytes() const { return pixels_.size() * sizeof(T); }
  std::size_t stride_bytes() const { return static_cast<std::size_t>(width_) * sizeof(T); }

  T* data() { return pixels_.data(); }
  const T* data() const { return pixels_.data(); }
  T& operator()(int x, int y) { return pixels_[index(x, y)]; }
  const T& operator()(int x, int y) const { return pixels_[index(x, y)]; }

  ImageView<T> view() { return {pixels_.data(), width_, height_, stride_bytes()}; }
  ImageView<const T> view() const { return {pixels_.data(), width_, height_, stride_bytes()}; }

  // A copy of the image in `memory` (kDevice: uploaded to the current GPU; from a device
  // image to the host: downloaded). Throws as Buffer's allocation does.
  Image copy_to(MemoryType memory) const {
    Image out(memory);
    out.width_ = width_;
    out.height_ = height_;
    out.pixels_.resize_uninitialized(pixels_.size(), memory);
    copy_memory(out.data(), data(), size_bytes(),
                out.memory_type() == MemoryType::kDevice || memory_type() == MemoryType::kDevice);
    return out;
  }

  // `source`'s pixels into this image, in the memory it was made for (Image(MemoryType)),
  // keeping its allocation when the size is unchanged (a ring of device frames reuses it): on
  // `stream` (asynchronous where a GPU is involved) or, with none, before returning.
  void copy_from(const Image& source, const GpuStream& stream = {}) {
    if (&source == this) return;
    pixels_.resize_uninitialized(source.pixel_count(), memory_);
    width_ = source.width_;
    height_ = source.height_;
    copy_memory(data(), source.data(), size_bytes(),
                memory_type() == MemoryType::kDevice || source.memory_type() == MemoryType::kDevice, stream);
  }

  // Only `rows` of `source`, one set after another, into this image (made `source`'s width and
  // as many rows as the sets name, without a fill, in the memory it was made for): on `stream`
  // as copy_from. What reads a few rows of a GPU's image brings down those alone, into a buffer
  // of their size. sls::Error(kInvalidArgument) for a row outside `source` or a step below 1.
  void gather_rows_from(const Image& source, const std::vector<RowSet>& rows, const GpuStream& stream = {}) {
    long long total = 0;
    for (const RowSet& set : rows) {
      if (set.count < 0 || set.step < 1 || set.first < 0 ||
          (set.count > 0 && static_cast<long long>(set.first) + static_cast<long long>(set.count - 1) * set.step >=
                                source.height_)) {
        throw_error(ErrorCode::kInvalidArgument, "rows {} + k * {} (k < {}) of an image of {} rows", set.first,
                    set.step, set.count, source.height_);
      }
      total += set.count;
    }
    if (&source == this) throw_error(ErrorCode::kInvalidArgument, "gather_rows_from: an image into itself");
    if (width_ != source.width_ || height_ != total) resize_uninitialized(source.width_, static_cast<int>(total));
    const bool device = memory_type() == MemoryType::kDevice || source.memory_type() == MemoryType::kDevice;
    std::size_t to = 0;  // this image's next row
    for (const RowSet& set : rows) {
      if (set.count == 0) continue;
      const std::size_t offset = static_cast<std::size_t>(set.first) * stride_bytes();
      copy_memory_2d(reinterpret_cast<unsigned char*>(data()) + to * stride_bytes(), stride_bytes(),
                     reinterpret_cast<const unsigned char*>(source.data()) + offset,
                     static_cast<std::size_t>(set.step) * stride_bytes(), stride_bytes(),
                     static_cast<std::size_t>(set.count), device, stream);
      to += static_cast<std::size_t>(set.count);
    }
  }

  bool operator==(const Image& other) const {
    return width_ == other.width_ && height_ == other.height_ && pixels_ == other.pixels_;
  }
  bool operator!=(const Image& other) const { return !(*this == other); }

 private:
  std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(x);
  }

  int width_ = 0;
  int height_ = 0;
  MemoryType memory_ = MemoryType::kHost;  // where resize() puts the pixels
  Buffer<T> pixels_;
};

using Image8u = Image<std::uint8_t>;
using Image16u = Image<std::uint16_t>;
using Image32f = Image<float>;

// An image whose pixel type is known only at run time (e.g. read from a file).
using AnyImage = std::variant<Image8u, Image16u, Image32f>;

template <typename T>
struct NonDeduced {
  using type = T;
};

// Copies pixels between views of the same size (any strides). T is deduced from the
// destination so a mutable source view converts.
template <typename T>
void copy_pixels(typename NonDeduced<ImageView<const T>>::type source, ImageView<T> destination) {
  if (source.width != destination.width || source.height != destination.height) {
    throw_error(ErrorCode::kInvalidArgument, "copy_pixels: size {}x{} differs from {}x{}",
                source.width, source.height, destination.width, destination.height);
  }
  for (int y = 0; y < source.height; ++y) {
    const T* in = source.row(y);
    T* out = destination.row(y);
    for (int x = 0; x < source.width; ++x) out[x] = in[x];
  }
}

}  // namespace sls
