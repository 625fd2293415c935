// Transport-independent pieces of the Aravis camera driver: frame-id gap counting and the
// unpacking of mono pixel buffers into 16-bit images. No Aravis types, so they are unit-tested
// on their own (tests/unit/drivers/test_aravis_frame_data.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "sdk/core/error.h"
#include "sdk/core/image.h"

namespace sls::drivers {

// Frames the camera numbered between `previous` and `next` that never arrived. GigE Vision 1.x
// block ids are 16 bits and skip 0 when they wrap (65535 → 1); GigE Vision 2 extended ids and
// USB3 Vision ids are 64 bits and do not wrap in practice. A step backwards that is no 16-bit
// wrap (the camera restarted its counter) counts as no gap: nothing tells how many were lost.
inline std::uint64_t frames_missed_between(std::uint64_t previous, std::uint64_t next) {
  if (next > previous) return next - previous - 1;
  constexpr std::uint64_t kLastShortId = 0xFFFF;
  if (next < previous && previous <= kLastShortId && next >= 1) {
    const std::uint64_t missed = (kLastShortId - previous) + (next - 1);
    if (missed < kLastShortId / 2) return missed;  // a plausible wrap, not a counter reset
  }
  return 0;
}

// The id the camera gives the frame after `previous` (16-bit ids wrap 65535 → 1; a camera with
// 64-bit ids that sits exactly at 65535 is taken for a 16-bit one).
inline std::uint64_t next_frame_id(std::uint64_t previous) {
  constexpr std::uint64_t kLastShortId = 0xFFFF;
  return previous == kLastShortId ? 1u : previous + 1u;
}

// An unpacked mono pixel layout: one byte per pixel (Mono8) or a 16-bit little-endian container
// per pixel (Mono10, Mono12, Mono16), as GenICam's PFNC defines them.
struct MonoLayout {
  std::string name;   // PFNC name, e.g. "Mono12"
  int bytes_per_pixel = 0;
  int bit_depth = 0;  // significant bits
};

// The layouts the driver reads. Packed formats (Mono12Packed, Mono12p) are not among them: a
// camera offering only those is refused when the format is chosen.
inline const MonoLayout* find_mono_layout(const std::string& name) {
  static const MonoLayout kLayouts[] = {
      {"Mono8", 1, 8}, {"Mono10", 2, 10}, {"Mono12", 2, 12}, {"Mono16", 2, 16}};
  for (const MonoLayout& layout : kLayouts) {
    if (layout.name == name) return &layout;
  }
  return nullptr;
}

// Copies a received mono buffer into `out` (resized to width × height). Rows are `row_stride`
// bytes apart (GigE Vision may pad rows). Mono8 values are stored as they are (0..255, bit
// depth 8), not scaled to 16 bits, so every image's values stay within 0 .. 2^bit_depth − 1.
// Throws sls::Error(kFormat) when `size` is too small for the image.
inline void unpack_mono(const std::uint8_t* data, std::size_t size, int width, int height,
                        std::size_t row_stride, int bytes_per_pixel, Image16u& out) {
  if (width <= 0 || height <= 0 || (bytes_per_pixel != 1 && bytes_per_pixel != 2)) {
    throw_error(ErrorCode::kFormat, "mono image {}x{} with {} bytes per pixel", width, height, bytes_per_pixel);
  }
  const std::size_t row_bytes = static_cast<std::size_t>(width) * static_cast<std::size_t>(bytes_per_pixel);
  if (row_stride < row_bytes) {
    throw_error(ErrorCode::kFormat, "row stride {} bytes is shorter than a row of {} bytes", row_stride, row_bytes);
  }
  const std::size_t needed = row_stride * static_cast<std::size_t>(height - 1) + row_bytes;
  if (size < needed) {
    throw_error(ErrorCode::kFormat, "{}x{} image needs {} bytes, the buffer holds {}", width, height, needed, size);
  }
  out.resize(width, height);
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* src = data + static_cast<std::size_t>(y) * row_stride;
    std::uint16_t* dst = &out(0, y);
    if (bytes_per_pixel == 1) {
      for (int x = 0; x < width; ++x) dst[x] = src[x];
    } else {
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
      std::memcpy(dst, src, row_bytes);  // the wire's little-endian words are the host's
#else
      for (int x = 0; x < width; ++x) {
        dst[x] = static_cast<std::uint16_t>(src[2 * x] | (src[2 * x + 1] << 8));
      }
#endif
    }
  }
}

}  // namespace sls::drivers
