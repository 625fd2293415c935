#include "sdk/core/png_gray_decode.h"

#include <cstring>
#include <memory>
#include <vector>

#if SLS_HAVE_LIBDEFLATE
#include <libdeflate.h>
#endif

namespace sls::png_detail {

#if !SLS_HAVE_LIBDEFLATE

std::optional<AnyImage> decode_gray_png(const std::uint8_t*, std::size_t, const ImageRegion&, MemoryType) {
  return std::nullopt;
}

#else

namespace {

constexpr std::size_t kSignatureBytes = 8;

std::uint32_t big_endian_u32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
}

bool host_is_little_endian() {
  const std::uint16_t probe = 1;
  std::uint8_t first = 0;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

// A chunk's CRC covers its type and data.
bool crc_matches(const std::uint8_t* chunk, std::uint32_t length) {
  return libdeflate_crc32(0, chunk + 4, std::size_t{4} + length) == big_endian_u32(chunk + 8 + length);
}

// Per thread, kept for the next image: the inflated rows of a 4000 x 3000 16-bit image are
// 24 MB, whose first touch of fresh pages cost as much as a fifth of the inflation. A buffer
// grown past kKeptBytes is released after its image.
class Scratch {
 public:
  static constexpr std::size_t kKeptBytes = std::size_t{64} << 20;
  std::uint8_t* get(std::size_t bytes) {
    if (bytes > capacity_) {
      bytes_.reset();
      bytes_.reset(new std::uint8_t[bytes]);  // not value-initialised: inflation writes it
      capacity_ = bytes;
    }
    return bytes_.get();
  }
  void trim() {
    if (capacity_ > kKeptBytes) {
      bytes_.reset();
      capacity_ = 0;
    }
  }

 private:
  std::unique_ptr<std::uint8_t[]> bytes_;
  std::size_t capacity_ = 0;
};

struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

// PNG's row filters (ISO 15948 section 9) undone in place; `previous` is the row above, already
// unfiltered, or nullptr for the first row (whose row above counts as zeros).
bool unfilter_row(int filter, std::uint8_t* row, const std::uint8_t* previous, std::size_t row_bytes, int bpp) {
  const std::size_t b = static_cast<std::size_t>(bpp);
  switch (filter) {
    case 0:
      return true;
    case 1:  // Sub
      for (std::size_t i = b; i < row_bytes; ++i) row[i] = static_cast<std::uint8_t>(row[i] + row[i - b]);
      return true;
    case 2:  // Up
      if (previous != nullptr) {
        for (std::size_t i = 0; i < row_bytes; ++i) row[i] = static_cast<std::uint8_t>(row[i] + previous[i]);
      }
      return true;
    case 3:  // Average
      for (std::size_t i = 0; i < row_bytes; ++i) {
        const unsigned left = i >= b ? row[i - b] : 0u;
        const unsigned up = previous != nullptr ? previous[i] : 0u;
        row[i] = static_cast<std::uint8_t>(row[i] + ((left + up) >> 1));
      }
      return true;
    case 4:  // Paeth
      for (std::size_t i = 0; i < row_bytes; ++i) {
        const int a = i >= b ? row[i - b] : 0;
        const int up = previous != nullptr ? previous[i] : 0;
        const int c = (i >= b && previous != nullptr) ? previous[i - b] : 0;
        const int p = a + up - c;
        const int pa = p > a ? p - a : a - p;
        const int pb = p > up ? p - up : up - p;
        const int pc = p > c ? p - c : c - p;
        const int predictor = (pa <= pb && pa <= pc) ? a : (pb <= pc ? up : c);
        row[i] = static_cast<std::uint8_t>(row[i] + predictor);
      }
      return true;
    default:
      return false;
  }
}

template <typename T>
void copy_region_row(const std::uint8_t* row, int x0, int width, T* out) {
  if constexpr (sizeof(T) == 1) {
    std::memcpy(out, row + x0, static_cast<std::size_t>(width));
  } else {
    const std::uint8_t* p = row + 2 * static_cast<std::size_t>(x0);
    if (host_is_little_endian()) {
      for (int x = 0; x < width; ++x) out[x] = static_cast<T>((p[2 * x] << 8) | p[2 * x + 1]);  // PNG is big-endian
    } else {
      std::memcpy(out, p, 2 * static_cast<std::size_t>(width));
    }
  }
}

template <typename T>
std::optional<AnyImage> unfilter_into(std::uint8_t* rows, std::size_t row_bytes, const ImageRegion& region,
                                      MemoryType memory) {
  Image<T> image(memory);
  image.resize_uninitialized(region.width, region.height);
  const std::size_t stride = row_bytes + 1;  // a filter-type byte before each row
  const std::uint8_t* previous = nullptr;
  for (int y = 0; y < region.y0 + region.height; ++y) {
    std::uint8_t* row = rows + static_cast<std::size_t>(y) * stride;
    if (!unfilter_row(row[0], row + 1, previous, row_bytes, static_cast<int>(sizeof(T)))) return std::nullopt;
    if (y >= region.y0) {
      copy_region_row(row + 1, region.x0, region.width,
                      image.data() + static_cast<std::size_t>(y - region.y0) * static_cast<std::size_t>(region.width));
    }
    previous = row + 1;
  }
  return AnyImage(std::move(image));
}

}  // namespace

std::optional<AnyImage> decode_gray_png(const std::uint8_t* data, std::size_t size, const ImageRegion& region,
                                        MemoryType memory) {
  // The header: IHDR first, 13 bytes (image_io.cpp has checked the signature).
  std::size_t at = kSignatureBytes;
  if (size < at + 8 + 13 + 4 || big_endian_u32(data + at) != 13 || std::memcmp(data + at + 4, "IHDR", 4) != 0 ||
      !crc_matches(data + at, 13)) {
    return std::nullopt;
  }
  const std::uint8_t* ihdr = data + at + 8;
  const std::uint32_t width = big_endian_u32(ihdr);
  const std::uint32_t height = big_endian_u32(ihdr + 4);
  const int bit_depth = ihdr[8];
  // Gray, deflate, the one filter method, not interlaced: anything else goes to libpng.
  if (ihdr[9] != 0 || (bit_depth != 8 && bit_depth != 16) || ihdr[10] != 0 || ihdr[11] != 0 || ihdr[12] != 0) {
    return std::nullopt;
  }
  // Sides of up to 2^24 keep every size below in 64 bits (image_io's own limit is 2^20).
  if (width == 0 || height == 0 || width > (1u << 24) || height > (1u << 24) || region.x0 < 0 || region.y0 < 0 || region.width <= 0 || region.height <= 0 ||
      std::uint64_t(region.x0) + std::uint64_t(region.width) > width ||
      std::uint64_t(region.y0) + std::uint64_t(region.height) > height) {
    return std::nullopt;
  }
  const std::size_t row_bytes = std::size_t{width} * static_cast<std::size_t>(bit_depth / 8);
  const std::size_t inflated_bytes = (row_bytes + 1) * std::size_t{height};
  // Deflate compresses at most 1032:1: a file too short for its header's image (or an image
  // past 4 GiB) is libpng's path's to refuse, before anything is allocated.
  if (inflated_bytes / 1032 > size || row_bytes * std::size_t{height} > (std::size_t{1} << 32)) return std::nullopt;
  at += 8 + 13 + 4;

  // The chunks: ancillary ones are skipped (libpng reads them, but none of them changes a
  // gray image's pixels as image_io reads them: no gamma, no sBIT shift, alpha dropped);
  // the image data is the one run of consecutive IDAT chunks; IEND ends the file.
  std::vector<std::pair<const std::uint8_t*, std::size_t>> image_data;
  bool data_ended = false, ended = false;
  while (at + 12 <= size) {
    const std::uint32_t length = big_endian_u32(data + at);
    if (length > 0x7fffffffu || std::size_t{length} + 12 > size - at) return std::nullopt;
    const std::uint8_t* type = data + at + 4;
    const bool critical = (type[0] & 0x20) == 0;
    if (std::memcmp(type, "IDAT", 4) == 0) {
      if (data_ended || !crc_matches(data + at, length)) return std::nullopt;
      image_data.emplace_back(data + at + 8, length);
    } else {
      if (!image_data.empty()) data_ended = true;
      if (std::memcmp(type, "IEND", 4) == 0) {
        if (!crc_matches(data + at, length)) return std::nullopt;
        ended = true;
        break;
      }
      if (critical) return std::nullopt;  // PLTE in a gray image, an unknown critical chunk: libpng decides
    }
    at += 12 + std::size_t{length};
  }
  if (!ended || image_data.empty()) return std::nullopt;

  thread_local Scratch compressed, inflated;
  thread_local std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> decompressor;
  if (!decompressor) decompressor.reset(libdeflate_alloc_decompressor());
  if (!decompressor) return std::nullopt;  // out of memory: libpng's path says so

  const std::uint8_t* stream = image_data.front().first;
  std::size_t stream_bytes = image_data.front().second;
  if (image_data.size() > 1) {  // libdeflate inflates one contiguous stream
    stream_bytes = 0;
    for (const auto& part : image_data) stream_bytes += part.second;
    std::uint8_t* joined = compressed.get(stream_bytes);
    std::size_t offset = 0;
    for (const auto& part : image_data) {
      std::memcpy(joined + offset, part.first, part.second);
      offset += part.second;
    }
    stream = joined;
  }
  std::uint8_t* rows = inflated.get(inflated_bytes);
  // Exactly the rows' bytes, or nullopt: a short or long stream is libpng's to judge.
  const libdeflate_result result =
      libdeflate_zlib_decompress(decompressor.get(), stream, stream_bytes, rows, inflated_bytes, nullptr);
  std::optional<AnyImage> image;
  if (result == LIBDEFLATE_SUCCESS) {
    image = bit_depth == 16 ? unfilter_into<std::uint16_t>(rows, row_bytes, region, memory)
                            : unfilter_into<std::uint8_t>(rows, row_bytes, region, memory);
  }
  compressed.trim();
  inflated.trim();
  return image;
}

#endif  // SLS_HAVE_LIBDEFLATE

}  // namespace sls::png_detail
