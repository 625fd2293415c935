// PNG image I/O on libpng (no OpenCV: the GPU machine has none, DESIGN.md section 9), and
// PFM for float images (at the end of this file).
//
// Images are grayscale, 8 or 16 bits per pixel (8-bit RGB too, written only: figures).
// Pixel values are stored and read back as they are: a 12-bit camera image goes into a
// 16-bit PNG unscaled (0..4095), and no sBIT or gamma transform is applied, so a round trip
// is exact. 16-bit samples are big-endian on
// disk; the byte order is handled here, callers always see native uint16 values.
//
// Reading accepts any valid PNG: bit depths 1..16 are expanded to 8 or 16 bits, palette and
// RGB(A) images are converted to luma (libpng's default sRGB/BT.709 weights), alpha is
// dropped, interlaced images are de-interlaced.
//
// Every failure throws sls::Error naming the file: kNotFound (missing), kIo (unreadable or
// unwritable), kFormat (not a PNG, truncated, CRC or zlib error, unsupported content).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "sdk/core/image.h"

namespace sls {

struct PngWriteOptions {
  // zlib level 0..9 (0 = stored, no compression). Recordings are written live at camera
  // rate (24 MB per 4000x3000x16 image), so the default favours speed over size.
  int compression_level = 1;
  // true: the UP row filter and run-length-only deflate (Z_RLE). On 4000x3000 12-bit camera
  // images this encoded about twice as fast as libpng's defaults at the same size (noisy
  // images: ~14 MB, ~0.4 s), and noise-free rendered images shrink to almost nothing.
  // false: libpng's adaptive filter choice and default deflate strategy (slower).
  bool fast = true;
};

// What a PNG's header (IHDR) says, before any conversion.
struct PngHeader {
  int width = 0;
  int height = 0;
  int bit_depth = 0;   // bits per sample as stored: 1, 2, 4, 8 or 16
  int channels = 0;    // 1 gray, 2 gray+alpha, 3 RGB or palette index (palette = true), 4 RGBA
  bool palette = false;
  bool interlaced = false;
};

// Reads only the signature and the IHDR chunk (33 bytes) to validate a file cheaply.
PngHeader read_png_header(const std::string& path);

// Decodes to Image8u (stored bit depth <= 8) or Image16u (16 bits), into host memory of the
// kind asked for (MemoryType::kPinned: page-locked where a GPU can lock it, else pageable; not
// kDevice).
AnyImage read_png(const std::string& path, MemoryType memory = MemoryType::kHost);
// As read_png, then: read_png_u8 rejects a 16-bit PNG (kFormat: it would lose bits);
// read_png_u16 widens an 8-bit PNG by value (no scaling: 255 stays 255).
Image8u read_png_u8(const std::string& path);
Image16u read_png_u16(const std::string& path, MemoryType memory = MemoryType::kHost);

// Decodes a PNG held in memory; `name` is used in error messages in place of a path.
AnyImage decode_png(const std::uint8_t* data, std::size_t size, const std::string& name,
                    MemoryType memory = MemoryType::kHost);

// A rectangle of an image: columns [x0, x0 + width), rows [y0, y0 + height).
struct ImageRegion {
  int x0 = 0, y0 = 0, width = 0, height = 0;
};

// As read_png_u16 and decode_png, only the pixels of `region` (a non-empty rectangle inside
// the image, else kInvalidArgument): only they are allocated and written, and a camera's PNG
// (gray, not interlaced) is not unfiltered below the region. What a calibration reads around
// its board.
Image16u read_png_u16(const std::string& path, const ImageRegion& region, MemoryType memory = MemoryType::kHost);
AnyImage decode_png(const std::uint8_t* data, std::size_t size, const std::string& name, const ImageRegion& region,
                    MemoryType memory = MemoryType::kHost);

// Encodes to a PNG in memory (8-bit or 16-bit grayscale). Throws kInvalidArgument for an
// empty image and kFormat/kOutOfMemory if libpng fails.
std::vector<std::uint8_t> encode_png(ImageView<const std::uint8_t> image, const PngWriteOptions& options = {});
std::vector<std::uint8_t> encode_png(ImageView<const std::uint16_t> image, const PngWriteOptions& options = {});

// Encodes, then writes with sls::write_file_atomic (temporary file, fsync, rename), so a
// crash never leaves half a PNG under `path`.
void write_png(const std::string& path, ImageView<const std::uint8_t> image, const PngWriteOptions& options = {});
void write_png(const std::string& path, ImageView<const std::uint16_t> image, const PngWriteOptions& options = {});
inline void write_png(const std::string& path, const Image8u& image, const PngWriteOptions& options = {}) {
  write_png(path, image.view(), options);
}
inline void write_png(const std::string& path, const Image16u& image, const PngWriteOptions& options = {}) {
  write_png(path, image.view(), options);
}
inline std::vector<std::uint8_t> encode_png(const Image8u& image, const PngWriteOptions& options = {}) {
  return encode_png(image.view(), options);
}
inline std::vector<std::uint8_t> encode_png(const Image16u& image, const PngWriteOptions& options = {}) {
  return encode_png(image.view(), options);
}

// 8-bit RGB, for figures (reports, heat maps) rather than camera data: `rgb` holds
// width*height*3 bytes, rows top to bottom, R G B per pixel, no padding. Reading it back with
// read_png gives luma (see above). Same errors as encode_png; write_png_rgb writes atomically
// like write_png.
std::vector<std::uint8_t> encode_png_rgb(const std::uint8_t* rgb, int width, int height,
                                         const PngWriteOptions& options = {});
void write_png_rgb(const std::string& path, const std::uint8_t* rgb, int width, int height,
                   const PngWriteOptions& options = {});

// PFM (Portable Float Map) for float images: depth maps, phase maps, ground truth.
//
// Layout (the format as Debevec's PFM page and OpenCV define it): the ASCII header "Pf\n"
// (grey; "PF" is colour), "<width> <height>\n", "<scale>\n", then width*height 32-bit floats,
// rows stored bottom-to-top. A negative scale means little-endian samples, a positive one
// big-endian; its magnitude is a scale factor that readers here ignore (samples come back
// exactly as stored; OpenCV divides by it, so we always write -1.0, which both read alike).
// We write "Pf\n<w> <h>\n-1.0\n" and little-endian samples. Reading accepts either byte
// order and any whitespace between the header fields, rejects colour PFM, and ignores bytes
// after the pixels. Errors throw sls::Error naming the file: kNotFound, kIo, kFormat (bad
// header, zero or absurd size, zero/NaN scale, truncated data).
std::vector<std::uint8_t> encode_pfm(ImageView<const float> image);
Image32f decode_pfm(const std::uint8_t* data, std::size_t size, const std::string& name);
// Writes with sls::write_file_atomic (temporary, fsync, rename).
void write_pfm(const std::string& path, ImageView<const float> image);
inline void write_pfm(const std::string& path, const Image32f& image) { write_pfm(path, image.view()); }
Image32f read_pfm(const std::string& path);

}  // namespace sls
