#include "sdk/core/image_io.h"

#include <fcntl.h>
#include <png.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <limits>
#include <new>
#include <optional>
#include <variant>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/png_gray_decode.h"

// libpng reports errors by calling our error callback, which must not return: it longjmps
// back to the setjmp in run_guarded(). Nothing with a destructor may live in the frames
// that longjmp skips (the lambda bodies below and libpng's C frames), so the libpng structs
// and all buffers are owned by objects outside them, and the sls::Error is thrown only after
// run_guarded() has returned. No C++ exception ever crosses a libpng frame.

namespace sls {
namespace {

constexpr std::size_t kSignatureSize = 8;
// Signature + IHDR chunk (length, type, 13 data bytes, CRC).
constexpr std::size_t kHeaderBytes = kSignatureSize + 4 + 4 + 13 + 4;
// Refuse absurd sizes from a corrupt header before allocating (libpng's default limit is
// 1e6 per side; 4000x3000 scans are far below both).
constexpr png_uint_32 kMaxSide = 1u << 20;
constexpr std::size_t kMaxImageBytes = std::size_t{1} << 32;

bool host_is_little_endian() {
  const std::uint16_t probe = 1;
  unsigned char first = 0;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

// Where the error callback leaves libpng's message (fixed size: the callback must not
// allocate, an exception there would cross C frames).
struct ErrorSink {
  char message[256] = {};
};

void on_png_error(png_structp png, png_const_charp message) {
  auto* sink = static_cast<ErrorSink*>(png_get_error_ptr(png));
  if (sink != nullptr) {
    std::snprintf(sink->message, sizeof(sink->message), "%s", message != nullptr ? message : "unknown libpng error");
  }
  png_longjmp(png, 1);
}

// Warnings (e.g. a CRC error in an ancillary chunk, which libpng then skips) are not fatal:
// the pixels are intact.
void on_png_warning(png_structp, png_const_charp) {}

// Runs `body` under a setjmp; returns false when libpng reported an error inside it.
template <typename Body>
bool run_guarded(png_structp png, Body&& body) {
  if (setjmp(png_jmpbuf(png)) != 0) return false;
  body();
  return true;
}

ErrorCode code_for_libpng_message(const char* message) {
  return std::strstr(message, "memory") != nullptr ? ErrorCode::kOutOfMemory : ErrorCode::kFormat;
}

// ---------------------------------------------------------------------------------------
// Reading

struct ReadContext {
  ErrorSink sink;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  std::size_t offset = 0;
  png_structp png = nullptr;
  png_infop info = nullptr;

  ReadContext() = default;
  ReadContext(const ReadContext&) = delete;
  ReadContext& operator=(const ReadContext&) = delete;
  ~ReadContext() {
    if (png != nullptr) png_destroy_read_struct(&png, &info, nullptr);
  }
};

void read_from_memory(png_structp png, png_bytep out, std::size_t length) {
  auto* context = static_cast<ReadContext*>(png_get_io_ptr(png));
  if (length > context->size - context->offset) png_error(png, "file is truncated (unexpected end of data)");
  std::memcpy(out, context->data + context->offset, length);
  context->offset += length;
}

// The layout after our transforms (png_read_update_info).
struct DecodedLayout {
  png_uint_32 width = 0;
  png_uint_32 height = 0;
  int bit_depth = 0;
  int channels = 0;
  std::size_t row_bytes = 0;
  int stored_bits_per_pixel = 0;  // as in the file, before the transforms
};

void set_up_transforms(png_structp png, png_infop info, DecodedLayout* layout) {
  png_set_user_limits(png, kMaxSide, kMaxSide);
  png_read_info(png, info);
  const int color_type = png_get_color_type(png, info);
  const int bit_depth = png_get_bit_depth(png, info);
  layout->stored_bits_per_pixel = bit_depth * png_get_channels(png, info);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (color_type == PNG_COLOR_TYPE_GRAY && bit_depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  // Transparency carries no intensity: drop alpha channels and tRNS.
  png_set_strip_alpha(png);
  if ((color_type & PNG_COLOR_MASK_COLOR) != 0) {
    png_set_rgb_to_gray_fixed(png, 1 /* silently */, -1, -1);  // default luma weights
  }
  if (bit_depth == 16 && host_is_little_endian()) png_set_swap(png);
  (void)png_set_interlace_handling(png);
  png_read_update_info(png, info);
  layout->width = png_get_image_width(png, info);
  layout->height = png_get_image_height(png, info);
  layout->bit_depth = png_get_bit_depth(png, info);
  layout->channels = png_get_channels(png, info);
  layout->row_bytes = png_get_rowbytes(png, info);
}

void read_rows(png_structp png, png_bytepp rows) {
  png_read_image(png, rows);
  png_read_end(png, nullptr);  // checks the chunks after the image data up to IEND
}

template <typename T>
AnyImage decode_into(ReadContext& context, const DecodedLayout& layout, const std::string& name,
                     MemoryType memory) {
  // Decoded straight into the memory asked for (page-locked for a scan fused on a GPU): no
  // copy, and no fill first (libpng writes every row: row_bytes is the width's, checked).
  Image<T> image(memory);
  image.resize_uninitialized(static_cast<int>(layout.width), static_cast<int>(layout.height));
  std::vector<png_bytep> rows(layout.height);
  for (png_uint_32 y = 0; y < layout.height; ++y) {
    rows[y] = reinterpret_cast<png_bytep>(image.data() + static_cast<std::size_t>(y) * layout.width);
  }
  png_structp png = context.png;
  png_bytepp row_pointers = rows.data();
  if (!run_guarded(png, [png, row_pointers] { read_rows(png, row_pointers); })) {
    throw Error(code_for_libpng_message(context.sink.message),
                fmt::format("{}: corrupt PNG: {}", name, context.sink.message));
  }
  return image;
}

// ---------------------------------------------------------------------------------------
// Writing

struct WriteContext {
  ErrorSink sink;
  std::vector<std::uint8_t> bytes;
  png_structp png = nullptr;
  png_infop info = nullptr;

  WriteContext() = default;
  WriteContext(const WriteContext&) = delete;
  WriteContext& operator=(const WriteContext&) = delete;
  ~WriteContext() {
    if (png != nullptr) png_destroy_write_struct(&png, &info);
  }
};

bool append_bytes(std::vector<std::uint8_t>& bytes, const std::uint8_t* data, std::size_t length) noexcept {
  try {
    bytes.insert(bytes.end(), data, data + length);
    return true;
  } catch (...) {
    return false;
  }
}

void write_to_memory(png_structp png, png_bytep data, std::size_t length) {
  auto* context = static_cast<WriteContext*>(png_get_io_ptr(png));
  if (!append_bytes(context->bytes, data, length)) png_error(png, "out of memory for the encoded PNG");
}

void flush_nothing(png_structp) {}

struct WriteJob {
  const unsigned char* first_row = nullptr;
  std::size_t stride_bytes = 0;
  png_uint_32 width = 0;
  png_uint_32 height = 0;
  int bit_depth = 0;
  int color_type = PNG_COLOR_TYPE_GRAY;
  int compression_level = 1;
  bool fast = true;
};

void write_image(png_structp png, png_infop info, const WriteJob& job) {
  png_set_IHDR(png, info, job.width, job.height, job.bit_depth, job.color_type, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_compression_level(png, job.compression_level);
  if (job.fast) {
    // Camera noise defeats LZ matching, so deflate's match search is mostly wasted time;
    // UP + Z_RLE keeps the entropy coding and the long runs of flat (rendered) regions.
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
    png_set_compression_strategy(png, Z_RLE);
  } else {
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_ALL_FILTERS);
  }
  // Larger IDAT chunks: less per-chunk overhead on 24 MB images.
  png_set_compression_buffer_size(png, 256 * 1024);
  png_write_info(png, info);
  if (job.bit_depth == 16 && host_is_little_endian()) png_set_swap(png);  // PNG is big-endian
  for (png_uint_32 y = 0; y < job.height; ++y) {
    png_write_row(png, job.first_row + static_cast<std::size_t>(y) * job.stride_bytes);
  }
  png_write_end(png, nullptr);
}

// `what` names the encoder in errors (encode_png, encode_png_rgb).
std::vector<std::uint8_t> encode_job(WriteJob job, int width, int height, std::size_t bytes_per_pixel,
                                     const PngWriteOptions& options, const char* what) {
  if (width <= 0 || height <= 0 || job.first_row == nullptr) {
    throw_error(ErrorCode::kInvalidArgument, "{}: the image is empty ({}x{})", what, width, height);
  }
  if (static_cast<png_uint_32>(width) > kMaxSide || static_cast<png_uint_32>(height) > kMaxSide) {
    throw_error(ErrorCode::kInvalidArgument, "{}: image size {}x{} is too large", what, width, height);
  }
  if (options.compression_level < 0 || options.compression_level > 9) {
    throw_error(ErrorCode::kInvalidArgument, "{}: compression level {} is outside 0..9", what,
                options.compression_level);
  }
  WriteContext context;
  const std::size_t raw_bytes = static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * bytes_per_pixel;
  // Camera images rarely compress below half; reserving avoids most regrowth copies.
  context.bytes.reserve(raw_bytes / 2 + 1024);
  context.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &context.sink, on_png_error, on_png_warning);
  if (context.png == nullptr) throw_error(ErrorCode::kOutOfMemory, "{}: cannot create the libpng writer", what);
  context.info = png_create_info_struct(context.png);
  if (context.info == nullptr) throw_error(ErrorCode::kOutOfMemory, "{}: cannot create the libpng info", what);
  png_set_write_fn(context.png, &context, write_to_memory, flush_nothing);

  job.width = static_cast<png_uint_32>(width);
  job.height = static_cast<png_uint_32>(height);
  job.compression_level = options.compression_level;
  job.fast = options.fast;
  png_structp png = context.png;
  png_infop info = context.info;
  const WriteJob* job_pointer = &job;
  if (!run_guarded(png, [png, info, job_pointer] { write_image(png, info, *job_pointer); })) {
    throw Error(code_for_libpng_message(context.sink.message),
                fmt::format("{}: libpng failed: {}", what, context.sink.message));
  }
  return std::move(context.bytes);
}

template <typename T>
std::vector<std::uint8_t> encode_any(ImageView<const T> image, const PngWriteOptions& options) {
  WriteJob job;
  job.first_row = image.empty() ? nullptr : reinterpret_cast<const unsigned char*>(image.data);
  job.stride_bytes = image.stride_bytes;
  job.bit_depth = static_cast<int>(sizeof(T) * 8);
  job.color_type = PNG_COLOR_TYPE_GRAY;
  return encode_job(job, image.width, image.height, sizeof(T), options, "encode_png");
}

std::vector<std::uint8_t> encode_rgb(const std::uint8_t* rgb, int width, int height, const PngWriteOptions& options) {
  WriteJob job;
  job.first_row = rgb;
  job.stride_bytes = static_cast<std::size_t>(std::max(width, 0)) * 3;
  job.bit_depth = 8;
  job.color_type = PNG_COLOR_TYPE_RGB;
  return encode_job(job, width, height, 3, options, "encode_png_rgb");
}

std::uint32_t big_endian_u32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
}

bool has_png_signature(const std::uint8_t* data, std::size_t size) {
  return size >= kSignatureSize && png_sig_cmp(data, 0, kSignatureSize) == 0;
}

[[noreturn]] void throw_not_png(const std::string& name, std::size_t size) {
  if (size < kSignatureSize) {
    throw_error(ErrorCode::kFormat, "{}: not a PNG file (only {} bytes)", name, size);
  }
  throw_error(ErrorCode::kFormat, "{}: not a PNG file (bad signature)", name);
}

// Parses the signature and IHDR chunk of a file's first bytes (`size` may be fewer than
// kHeaderBytes: a truncated file).
PngHeader parse_png_header(const std::uint8_t* bytes, std::size_t size, const std::string& path) {
  if (!has_png_signature(bytes, size)) throw_not_png(path, size);
  if (size < kHeaderBytes) throw_error(ErrorCode::kFormat, "{}: corrupt PNG: file is truncated inside the header", path);
  const std::uint8_t* chunk = bytes + kSignatureSize;
  if (big_endian_u32(chunk) != 13 || std::memcmp(chunk + 4, "IHDR", 4) != 0) {
    throw_error(ErrorCode::kFormat, "{}: corrupt PNG: the first chunk is not a valid IHDR", path);
  }
  const std::uint32_t crc = static_cast<std::uint32_t>(crc32(crc32(0L, Z_NULL, 0), chunk + 4, 4 + 13));
  if (crc != big_endian_u32(chunk + 4 + 4 + 13)) throw_error(ErrorCode::kFormat, "{}: corrupt PNG: IHDR CRC error", path);
  const std::uint8_t* data = chunk + 8;
  const std::uint32_t width = big_endian_u32(data);
  const std::uint32_t height = big_endian_u32(data + 4);
  const int bit_depth = data[8];
  const int color_type = data[9];
  const int interlace = data[12];
  if (width == 0 || height == 0 || width > kMaxSide || height > kMaxSide) {
    throw_error(ErrorCode::kFormat, "{}: corrupt or unsupported PNG: image size {}x{}", path, width, height);
  }
  PngHeader header;
  header.width = static_cast<int>(width);
  header.height = static_cast<int>(height);
  header.bit_depth = bit_depth;
  header.interlaced = interlace == 1;
  bool depth_ok = false;
  switch (color_type) {
    case 0:  // gray
      header.channels = 1;
      depth_ok = bit_depth == 1 || bit_depth == 2 || bit_depth == 4 || bit_depth == 8 || bit_depth == 16;
      break;
    case 3:  // palette
      header.channels = 3;
      header.palette = true;
      depth_ok = bit_depth == 1 || bit_depth == 2 || bit_depth == 4 || bit_depth == 8;
      break;
    case 2:  // RGB
    case 4:  // gray + alpha
    case 6:  // RGBA
      header.channels = color_type == 2 ? 3 : color_type == 4 ? 2 : 4;
      depth_ok = bit_depth == 8 || bit_depth == 16;
      break;
    default:
      throw_error(ErrorCode::kFormat, "{}: corrupt PNG: invalid colour type {}", path, color_type);
  }
  if (!depth_ok) {
    throw_error(ErrorCode::kFormat, "{}: corrupt PNG: bit depth {} is invalid for colour type {}", path, bit_depth,
                color_type);
  }
  if (interlace > 1) throw_error(ErrorCode::kFormat, "{}: corrupt PNG: invalid interlace method {}", path, interlace);
  return header;
}

// The most a PNG file of this header can reasonably hold, so that a corrupt or hostile file
// is refused before it is read into memory: the filtered rows (plus a filter byte per row
// of each interlace pass), an eighth more for deflate blocks and chunk framing, and 64 MiB
// of ancillary chunks (text, ICC profiles, EXIF).
std::uint64_t max_png_file_bytes(const PngHeader& header) {
  const std::uint64_t samples = header.palette ? 1 : static_cast<std::uint64_t>(header.channels);
  const std::uint64_t row_bytes =
      (static_cast<std::uint64_t>(header.width) * samples * static_cast<std::uint64_t>(header.bit_depth) + 7) / 8;
  const std::uint64_t height = static_cast<std::uint64_t>(header.height);
  const std::uint64_t raw = height * (row_bytes + 1) + (header.interlaced ? 2 * height + 64 : 0);
  return kHeaderBytes + raw + raw / 8 + (std::uint64_t{64} << 20);
}

}  // namespace

PngHeader read_png_header(const std::string& path) {
  const RegularFile file(path);
  std::uint8_t bytes[kHeaderBytes] = {};
  return parse_png_header(bytes, file.read_at(0, bytes, kHeaderBytes), path);
}

namespace {

// Every chunk's length against the bytes that follow it, before libpng sees the file: libpng
// reads an ancillary chunk (text, a profile) whole into a buffer of the length the chunk
// claims, so a 106-byte file claiming a 1.8 GB text chunk made it allocate and fill 1.8 GB
// (found by fuzz_png; png_set_chunk_malloc_max does not cover that path).
void check_chunk_lengths(const std::uint8_t* data, std::size_t size, const std::string& name) {
  std::size_t at = 8;  // after the signature
  while (at + 8 <= size) {
    const std::uint32_t length = (std::uint32_t{data[at]} << 24) | (std::uint32_t{data[at + 1]} << 16) |
                                 (std::uint32_t{data[at + 2]} << 8) | data[at + 3];
    const std::string type(reinterpret_cast<const char*>(data + at + 4), 4);
    const std::size_t left = size - at - 8;  // data and CRC
    if (length > 0x7fffffffu || std::size_t{length} + 4 > left) {
      throw_error(ErrorCode::kFormat, "{}: corrupt PNG: chunk at byte {} claims {} bytes, {} follow (a truncated or "
                  "corrupt file)", name, at, length, left >= 4 ? left - 4 : 0);
    }
    if (type == "IEND") return;
    at += 12 + std::size_t{length};
  }
}

}  // namespace

namespace {

template <typename T>
AnyImage crop_image(const Image<T>& image, const ImageRegion& region, MemoryType memory) {
  Image<T> out(memory);
  out.resize_uninitialized(region.width, region.height);
  for (int y = 0; y < region.height; ++y) {
    const T* row = image.data() + static_cast<std::size_t>(region.y0 + y) * static_cast<std::size_t>(image.width());
    std::copy(row + region.x0, row + region.x0 + region.width,
              out.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(region.width));
  }
  return out;
}

// Decodes the whole image (region nullptr) or its region (checked by the caller).
AnyImage decode_png_in(const std::uint8_t* data, std::size_t size, const std::string& name,
                       const ImageRegion* region, MemoryType memory);

}  // namespace

AnyImage decode_png(const std::uint8_t* data, std::size_t size, const std::string& name, MemoryType memory) {
  return decode_png_in(data, size, name, nullptr, memory);
}

AnyImage decode_png(const std::uint8_t* data, std::size_t size, const std::string& name, const ImageRegion& region,
                    MemoryType memory) {
  if (data == nullptr || !has_png_signature(data, size)) throw_not_png(name, data == nullptr ? 0 : size);
  const PngHeader header = parse_png_header(data, size, name);
  if (region.x0 < 0 || region.y0 < 0 || region.width <= 0 || region.height <= 0 ||
      std::int64_t{region.x0} + region.width > header.width || std::int64_t{region.y0} + region.height > header.height) {
    throw_error(ErrorCode::kInvalidArgument, "{}: the region {}x{} at ({}, {}) is not inside the {}x{} image", name,
                region.width, region.height, region.x0, region.y0, header.width, header.height);
  }
  return decode_png_in(data, size, name, &region, memory);
}

namespace {

AnyImage decode_png_in(const std::uint8_t* data, std::size_t size, const std::string& name,
                       const ImageRegion* region, MemoryType memory) {
  if (memory == MemoryType::kDevice) {
    throw_error(ErrorCode::kInvalidArgument, "{}: a PNG decodes into host memory, not a GPU's", name);
  }
  if (data == nullptr || !has_png_signature(data, size)) throw_not_png(name, data == nullptr ? 0 : size);
  check_chunk_lengths(data, size, name);
  // A camera's PNG (gray, 8 or 16 bits, not interlaced): inflated by libdeflate, unfiltered
  // into the region only. Any other PNG, or one that path finds fault with, through libpng.
  // (Sides past kMaxSide are libpng's to refuse.)
  const std::uint32_t width = size >= kHeaderBytes ? big_endian_u32(data + kSignatureSize + 8) : 0;
  const std::uint32_t height = size >= kHeaderBytes ? big_endian_u32(data + kSignatureSize + 12) : 0;
  if (width > 0 && height > 0 && width <= kMaxSide && height <= kMaxSide) {
    const ImageRegion whole{0, 0, static_cast<int>(width), static_cast<int>(height)};
    if (std::optional<AnyImage> fast = png_detail::decode_gray_png(data, size, region ? *region : whole, memory)) {
      return std::move(*fast);
    }
  }
  ReadContext context;
  context.data = data;
  context.size = size;
  context.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &context.sink, on_png_error, on_png_warning);
  if (context.png == nullptr) throw_error(ErrorCode::kOutOfMemory, "{}: cannot create the libpng reader", name);
  context.info = png_create_info_struct(context.png);
  if (context.info == nullptr) throw_error(ErrorCode::kOutOfMemory, "{}: cannot create the libpng info", name);
  png_set_read_fn(context.png, &context, read_from_memory);

  DecodedLayout layout;
  png_structp png = context.png;
  png_infop info = context.info;
  DecodedLayout* layout_pointer = &layout;
  if (!run_guarded(png, [png, info, layout_pointer] { set_up_transforms(png, info, layout_pointer); })) {
    throw Error(code_for_libpng_message(context.sink.message),
                fmt::format("{}: corrupt PNG: {}", name, context.sink.message));
  }
  if (layout.channels != 1 || (layout.bit_depth != 8 && layout.bit_depth != 16)) {
    throw_error(ErrorCode::kFormat, "{}: unsupported PNG layout ({} channels of {} bits after conversion to gray)",
                name, layout.channels, layout.bit_depth);
  }
  // Deflate compresses at most 1032:1, so a file this short cannot hold the image its header
  // announces: refused before the image is allocated (a 100-byte PNG claiming 1M x 1M pixels).
  constexpr std::uint64_t kMaxDeflateRatio = 1032;
  const std::uint64_t stored_bytes = std::uint64_t{layout.width} * layout.height *
                                     static_cast<std::uint64_t>(layout.stored_bits_per_pixel) / 8;
  if (stored_bytes / kMaxDeflateRatio > size) {
    throw_error(ErrorCode::kFormat, "{}: corrupt PNG: {} bytes cannot hold the {}x{} image its header announces "
                "(truncated?)", name, size, layout.width, layout.height);
  }
  const std::size_t bytes_per_pixel = layout.bit_depth == 16 ? 2 : 1;
  if (layout.row_bytes != std::size_t{layout.width} * bytes_per_pixel ||
      std::size_t{layout.height} * layout.row_bytes > kMaxImageBytes) {
    throw_error(ErrorCode::kFormat, "{}: unsupported PNG: {}x{} pixels, {} bytes per row", name, layout.width,
                layout.height, layout.row_bytes);
  }
  if (region == nullptr) {
    return layout.bit_depth == 16 ? decode_into<std::uint16_t>(context, layout, name, memory)
                                  : decode_into<std::uint8_t>(context, layout, name, memory);
  }
  const AnyImage whole = layout.bit_depth == 16 ? decode_into<std::uint16_t>(context, layout, name, MemoryType::kHost)
                                                : decode_into<std::uint8_t>(context, layout, name, MemoryType::kHost);
  return std::visit([region, memory](const auto& image) { return crop_image(image, *region, memory); }, whole);
}

}  // namespace

namespace {

// The file's bytes, its header checked first (a size it cannot hold is refused unread), in
// a buffer this thread keeps for its next file: a 4000 x 3000 camera image's PNG is ~12 MB,
// and fresh pages for each cost more than the copy from the page cache. Valid until the
// thread's next call.
const std::vector<std::uint8_t>& read_png_file(const std::string& path) {
  constexpr std::size_t kKeptBytes = std::size_t{64} << 20;
  thread_local std::vector<std::uint8_t> bytes;
  if (bytes.capacity() > kKeptBytes) std::vector<std::uint8_t>().swap(bytes);
  const RegularFile file(path);
  std::uint8_t header_bytes[kHeaderBytes] = {};
  const PngHeader header = parse_png_header(header_bytes, file.read_at(0, header_bytes, kHeaderBytes), path);
  file.read_all(max_png_file_bytes(header), &bytes);
  return bytes;
}

// An 8-bit image widened by value (255 stays 255).
Image16u widened_to_u16(AnyImage image, MemoryType memory) {
  if (auto* image16 = std::get_if<Image16u>(&image)) return std::move(*image16);
  const Image8u& image8 = std::get<Image8u>(image);
  Image16u widened(image8.width(), image8.height(), 0, memory);
  std::copy(image8.data(), image8.data() + image8.pixel_count(), widened.data());
  return widened;
}

}  // namespace

AnyImage read_png(const std::string& path, MemoryType memory) {
  const std::vector<std::uint8_t>& bytes = read_png_file(path);
  return decode_png(bytes.data(), bytes.size(), path, memory);
}

Image16u read_png_u16(const std::string& path, const ImageRegion& region, MemoryType memory) {
  const std::vector<std::uint8_t>& bytes = read_png_file(path);
  return widened_to_u16(decode_png(bytes.data(), bytes.size(), path, region, memory), memory);
}

Image8u read_png_u8(const std::string& path) {
  AnyImage image = read_png(path);
  if (auto* image8 = std::get_if<Image8u>(&image)) return std::move(*image8);
  throw_error(ErrorCode::kFormat, "{}: is a 16-bit PNG where an 8-bit image was expected", path);
}

Image16u read_png_u16(const std::string& path, MemoryType memory) {
  return widened_to_u16(read_png(path, memory), memory);
}

std::vector<std::uint8_t> encode_png(ImageView<const std::uint8_t> image, const PngWriteOptions& options) {
  return encode_any(image, options);
}

std::vector<std::uint8_t> encode_png(ImageView<const std::uint16_t> image, const PngWriteOptions& options) {
  return encode_any(image, options);
}

namespace {

template <typename T>
void write_any(const std::string& path, ImageView<const T> image, const PngWriteOptions& options) {
  std::vector<std::uint8_t> bytes;
  try {
    bytes = encode_any(image, options);
  } catch (const Error& error) {
    throw Error(error.code(), path + ": " + error.what());
  }
  write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace

void write_png(const std::string& path, ImageView<const std::uint8_t> image, const PngWriteOptions& options) {
  write_any(path, image, options);
}

void write_png(const std::string& path, ImageView<const std::uint16_t> image, const PngWriteOptions& options) {
  write_any(path, image, options);
}

std::vector<std::uint8_t> encode_png_rgb(const std::uint8_t* rgb, int width, int height, const PngWriteOptions& options) {
  return encode_rgb(rgb, width, height, options);
}

void write_png_rgb(const std::string& path, const std::uint8_t* rgb, int width, int height,
                   const PngWriteOptions& options) {
  std::vector<std::uint8_t> bytes;
  try {
    bytes = encode_rgb(rgb, width, height, options);
  } catch (const Error& error) {
    throw Error(error.code(), path + ": " + error.what());
  }
  write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

// ---------------------------------------------------------------------------------------
// PFM

namespace {

// read_pfm looks for the header in the file's first bytes: "Pf", two sides and a scale are a
// few dozen characters; this leaves room for odd whitespace.
constexpr std::size_t kMaxPfmHeaderBytes = 4096;

bool is_pfm_space(std::uint8_t c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

struct PfmLayout {
  std::size_t width = 0;
  std::size_t height = 0;
  bool little_endian = true;
  std::size_t data_offset = 0;
};

PfmLayout parse_pfm_header(const std::uint8_t* data, std::size_t size, const std::string& name) {
  if (data == nullptr || size < 2 || data[0] != 'P' || (data[1] != 'f' && data[1] != 'F')) {
    throw_error(ErrorCode::kFormat, "{}: not a PFM file (it does not start with \"Pf\")", name);
  }
  if (data[1] == 'F') {
    throw_error(ErrorCode::kFormat, "{}: colour PFM (\"PF\") is not supported, only grey (\"Pf\")", name);
  }
  std::size_t pos = 2;
  // A header field: whitespace, then up to 64 non-space characters, then one whitespace.
  auto field = [&](const char* what) -> std::string {
    if (pos >= size || !is_pfm_space(data[pos])) {
      throw_error(ErrorCode::kFormat, "{}: corrupt PFM header: {} expected", name,
                  pos >= size ? std::string("more data") : fmt::format("whitespace before the {}", what));
    }
    while (pos < size && is_pfm_space(data[pos])) ++pos;
    const std::size_t start = pos;
    while (pos < size && !is_pfm_space(data[pos]) && pos - start <= 64) ++pos;
    if (pos >= size) throw_error(ErrorCode::kFormat, "{}: corrupt PFM: the file ends inside the header", name);
    if (pos == start || !is_pfm_space(data[pos])) {
      throw_error(ErrorCode::kFormat, "{}: corrupt PFM header: bad {}", name, what);
    }
    return std::string(reinterpret_cast<const char*>(data + start), pos - start);
  };
  auto side = [&](const std::string& text, const char* what) -> std::size_t {
    std::uint64_t value = 0;
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (error != std::errc() || end != text.data() + text.size() || value == 0 || value > kMaxSide) {
      throw_error(ErrorCode::kFormat, "{}: corrupt or unsupported PFM header: {} \"{}\"", name, what, text);
    }
    return static_cast<std::size_t>(value);
  };
  PfmLayout layout;
  layout.width = side(field("width"), "width");
  layout.height = side(field("height"), "height");
  const std::string scale_text = field("scale");
  double scale = 0;
  const auto [end, error] = std::from_chars(scale_text.data(), scale_text.data() + scale_text.size(), scale);
  if (error != std::errc() || end != scale_text.data() + scale_text.size() || !std::isfinite(scale) || scale == 0.0) {
    throw_error(ErrorCode::kFormat, "{}: corrupt PFM header: scale \"{}\" (must be a non-zero number)", name,
                scale_text);
  }
  layout.little_endian = scale < 0.0;
  layout.data_offset = pos + 1;  // exactly one whitespace character ends the header
  return layout;
}

std::uint32_t byte_swap32(std::uint32_t v) {
  return (v >> 24) | ((v >> 8) & 0x0000ff00u) | ((v << 8) & 0x00ff0000u) | (v << 24);
}

}  // namespace

std::vector<std::uint8_t> encode_pfm(ImageView<const float> image) {
  if (image.empty() || image.data == nullptr) {
    throw_error(ErrorCode::kInvalidArgument, "encode_pfm: the image is empty ({}x{})", image.width, image.height);
  }
  if (static_cast<png_uint_32>(image.width) > kMaxSide || static_cast<png_uint_32>(image.height) > kMaxSide) {
    throw_error(ErrorCode::kInvalidArgument, "encode_pfm: image size {}x{} is too large", image.width, image.height);
  }
  const std::string header = fmt::format("Pf\n{} {}\n-1.0\n", image.width, image.height);
  const std::size_t row_bytes = static_cast<std::size_t>(image.width) * sizeof(float);
  std::vector<std::uint8_t> bytes(header.size() + row_bytes * static_cast<std::size_t>(image.height));
  std::memcpy(bytes.data(), header.data(), header.size());
  const bool swap = !host_is_little_endian();
  std::uint8_t* out = bytes.data() + header.size();
  for (int y = image.height - 1; y >= 0; --y) {  // bottom row first
    std::memcpy(out, image.row(y), row_bytes);
    if (swap) {
      for (std::size_t i = 0; i < row_bytes; i += 4) {
        std::uint32_t v;
        std::memcpy(&v, out + i, 4);
        v = byte_swap32(v);
        std::memcpy(out + i, &v, 4);
      }
    }
    out += row_bytes;
  }
  return bytes;
}

Image32f decode_pfm(const std::uint8_t* data, std::size_t size, const std::string& name) {
  const PfmLayout layout = parse_pfm_header(data, size, name);
  const std::size_t row_bytes = layout.width * sizeof(float);
  const std::size_t needed = row_bytes * layout.height;
  if (needed > kMaxImageBytes) {
    throw_error(ErrorCode::kFormat, "{}: unsupported PFM: {}x{} pixels is too large", name, layout.width,
                layout.height);
  }
  const std::size_t available = size - std::min(size, layout.data_offset);
  if (available < needed) {
    throw_error(ErrorCode::kFormat, "{}: corrupt PFM: truncated data ({} of {} bytes for {}x{} pixels)", name,
                available, needed, layout.width, layout.height);
  }
  Image32f image(static_cast<int>(layout.width), static_cast<int>(layout.height));
  const bool swap = layout.little_endian != host_is_little_endian();
  const std::uint8_t* in = data + layout.data_offset;
  for (std::size_t r = 0; r < layout.height; ++r) {  // file row r is image row height-1-r
    float* row = image.data() + (layout.height - 1 - r) * layout.width;
    std::memcpy(row, in + r * row_bytes, row_bytes);
    if (swap) {
      for (std::size_t x = 0; x < layout.width; ++x) {
        std::uint32_t v;
        std::memcpy(&v, row + x, 4);
        v = byte_swap32(v);
        std::memcpy(row + x, &v, 4);
      }
    }
  }
  return image;
}

void write_pfm(const std::string& path, ImageView<const float> image) {
  std::vector<std::uint8_t> bytes;
  try {
    bytes = encode_pfm(image);
  } catch (const Error& error) {
    throw Error(error.code(), path + ": " + error.what());
  }
  write_file_atomic(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

Image32f read_pfm(const std::string& path) {
  const RegularFile file(path);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(std::min<std::uint64_t>(file.size(), kMaxPfmHeaderBytes)));
  bytes.resize(file.read_at(0, bytes.data(), bytes.size()));
  const PfmLayout layout = parse_pfm_header(bytes.data(), bytes.size(), path);
  const std::uint64_t pixel_bytes = std::uint64_t{layout.width} * layout.height * sizeof(float);
  if (pixel_bytes > kMaxImageBytes) {
    throw_error(ErrorCode::kFormat, "{}: unsupported PFM: {}x{} pixels is too large", path, layout.width,
                layout.height);
  }
  // Only what the header says: bytes after the pixels are ignored, so they are not read.
  const std::uint64_t wanted = std::min<std::uint64_t>(layout.data_offset + pixel_bytes, file.size());
  const std::size_t have = bytes.size();
  bytes.resize(static_cast<std::size_t>(std::max<std::uint64_t>(wanted, have)));
  bytes.resize(have + file.read_at(have, bytes.data() + have, bytes.size() - have));
  return decode_pfm(bytes.data(), bytes.size(), path);
}

}  // namespace sls
