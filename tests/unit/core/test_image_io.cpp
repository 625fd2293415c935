// PNG I/O: exact round trips, byte order, the conversions on reading, and that every kind of
// broken file gives an sls::Error naming the file (never a crash).
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <optional>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <png.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/png_gray_decode.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

using Bytes = std::vector<std::uint8_t>;

// --- A minimal PNG writer (stored deflate blocks), independent of libpng, to feed the
// reader colour types and bit depths our writer never produces.

std::uint32_t crc32_of(const std::uint8_t* data, std::size_t size) {
  std::uint32_t crc = 0xffffffffu;
  for (std::size_t i = 0; i < size; ++i) {
    crc ^= data[i];
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return crc ^ 0xffffffffu;
}

void put_u32(Bytes& out, std::uint32_t value) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<std::uint8_t>(value >> shift));
}

void put_chunk(Bytes& out, const char* type, const Bytes& data) {
  put_u32(out, static_cast<std::uint32_t>(data.size()));
  Bytes typed(type, type + 4);
  typed.insert(typed.end(), data.begin(), data.end());
  out.insert(out.end(), typed.begin(), typed.end());
  put_u32(out, crc32_of(typed.data(), typed.size()));
}

// `scanlines`: each row already prefixed with its filter byte (0 = none).
Bytes make_png(std::uint32_t width, std::uint32_t height, int bit_depth, int color_type, const Bytes& scanlines,
               const std::vector<std::pair<const char*, Bytes>>& extra_chunks = {}, bool interlaced = false,
               std::size_t idat_chunks = 1) {
  Bytes out = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  Bytes ihdr;
  put_u32(ihdr, width);
  put_u32(ihdr, height);
  ihdr.push_back(static_cast<std::uint8_t>(bit_depth));
  ihdr.push_back(static_cast<std::uint8_t>(color_type));
  ihdr.push_back(0);
  ihdr.push_back(0);
  ihdr.push_back(interlaced ? 1 : 0);
  put_chunk(out, "IHDR", ihdr);
  for (const auto& [type, data] : extra_chunks) put_chunk(out, type, data);
  // zlib stream: header, one stored block (data < 64 KiB), Adler-32.
  Bytes z = {0x78, 0x01, 0x01};
  const auto length = static_cast<std::uint16_t>(scanlines.size());
  z.push_back(static_cast<std::uint8_t>(length & 0xff));
  z.push_back(static_cast<std::uint8_t>(length >> 8));
  z.push_back(static_cast<std::uint8_t>(~length & 0xff));
  z.push_back(static_cast<std::uint8_t>((~length >> 8) & 0xff));
  z.insert(z.end(), scanlines.begin(), scanlines.end());
  std::uint32_t a = 1, b = 0;
  for (std::uint8_t byte : scanlines) {
    a = (a + byte) % 65521u;
    b = (b + a) % 65521u;
  }
  put_u32(z, (b << 16) | a);
  // The stream split over `idat_chunks` consecutive IDAT chunks, as encoders with a buffer do.
  const std::size_t part = (z.size() + idat_chunks - 1) / idat_chunks;
  for (std::size_t at = 0; at < z.size(); at += part) {
    put_chunk(out, "IDAT", Bytes(z.begin() + static_cast<std::ptrdiff_t>(at),
                                 z.begin() + static_cast<std::ptrdiff_t>(std::min(z.size(), at + part))));
  }
  put_chunk(out, "IEND", {});
  return out;
}

// PNG's five row filters (ISO 15948 section 9) applied to unfiltered rows, as an encoder does:
// row y gets filter `filter_of(y)`; the result carries each row's filter byte.
int paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

Bytes filter_rows(const Bytes& raw, std::size_t row_bytes, std::size_t bpp, int (*filter_of)(int)) {
  Bytes out;
  const std::size_t height = raw.size() / row_bytes;
  for (std::size_t y = 0; y < height; ++y) {
    const int filter = filter_of(static_cast<int>(y));
    out.push_back(static_cast<std::uint8_t>(filter));
    const std::uint8_t* row = raw.data() + y * row_bytes;
    const std::uint8_t* up = y > 0 ? row - row_bytes : nullptr;
    for (std::size_t i = 0; i < row_bytes; ++i) {
      const int a = i >= bpp ? row[i - bpp] : 0, b = up ? up[i] : 0, c = (up && i >= bpp) ? up[i - bpp] : 0;
      const int predictor = filter == 1 ? a : filter == 2 ? b : filter == 3 ? (a + b) / 2 : filter == 4 ? paeth(a, b, c) : 0;
      out.push_back(static_cast<std::uint8_t>(row[i] - predictor));
    }
  }
  return out;
}

void write_bytes(const std::string& path, const Bytes& bytes) {
  std::ofstream stream(path, std::ios::binary | std::ios::trunc);
  stream.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

template <typename T>
Image<T> random_image(int width, int height, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> value(0, std::numeric_limits<T>::max());
  Image<T> image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) image(x, y) = static_cast<T>(value(random));
  }
  return image;
}

// Expects `call` to throw sls::Error with `code` and a message containing `needle`.
template <typename Call>
void expect_error(Call&& call, ErrorCode code, const std::string& needle) {
  try {
    call();
    ADD_FAILURE() << "no error thrown";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), code) << error.what();
    EXPECT_NE(std::string(error.what()).find(needle), std::string::npos) << error.what();
  }
}

TEST(Png, RoundTrip8BitExact) {
  test::TemporaryDirectory dir;
  const Image8u image = random_image<std::uint8_t>(37, 23, 1);
  write_png(dir.file("a.png"), image);
  const AnyImage read = read_png(dir.file("a.png"));
  ASSERT_TRUE(std::holds_alternative<Image8u>(read));
  EXPECT_EQ(std::get<Image8u>(read), image);
  EXPECT_EQ(read_png_u8(dir.file("a.png")), image);
}

TEST(Png, RoundTrip16BitExact) {
  test::TemporaryDirectory dir;
  Image16u image = random_image<std::uint16_t>(37, 23, 2);
  image(0, 0) = 0;
  image(1, 0) = 65535;
  write_png(dir.file("a.png"), image);
  const AnyImage read = read_png(dir.file("a.png"));
  ASSERT_TRUE(std::holds_alternative<Image16u>(read));
  EXPECT_EQ(std::get<Image16u>(read), image);
  const PngHeader header = read_png_header(dir.file("a.png"));
  EXPECT_EQ(header.width, 37);
  EXPECT_EQ(header.height, 23);
  EXPECT_EQ(header.bit_depth, 16);
  EXPECT_EQ(header.channels, 1);
}

TEST(Png, EveryCompressionSettingRoundTrips) {
  const Image16u image = random_image<std::uint16_t>(64, 9, 3);
  for (int level = 0; level <= 9; ++level) {
    for (bool fast : {true, false}) {
      PngWriteOptions options;
      options.compression_level = level;
      options.fast = fast;
      const Bytes bytes = encode_png(image, options);
      EXPECT_EQ(std::get<Image16u>(decode_png(bytes.data(), bytes.size(), "memory")), image) << level;
    }
  }
}

TEST(Png, StridedViewWritesOnlyItsPixels) {
  test::TemporaryDirectory dir;
  const Image8u big = random_image<std::uint8_t>(40, 30, 4);
  ImageView<const std::uint8_t> window = big.view();
  window.data = &big(5, 7);
  window.width = 11;
  window.height = 13;
  write_png(dir.file("w.png"), window);
  const Image8u read = read_png_u8(dir.file("w.png"));
  ASSERT_EQ(read.width(), 11);
  ASSERT_EQ(read.height(), 13);
  for (int y = 0; y < 13; ++y) {
    for (int x = 0; x < 11; ++x) ASSERT_EQ(read(x, y), big(x + 5, y + 7));
  }
}

TEST(Png, SixteenBitIsBigEndianOnDisk) {
  // Written by us: at level 0 the IDAT holds the raw row, [filter][0x01][0x02] for one pixel
  // (no filter changes the first pixel of the first row).
  Image16u one(1, 1, 0x0102);
  PngWriteOptions stored;
  stored.compression_level = 0;
  const Bytes bytes = encode_png(one, stored);
  const std::string text(bytes.begin(), bytes.end());
  const std::size_t idat = text.find("IDAT");
  ASSERT_NE(idat, std::string::npos);
  const std::size_t row = idat + 4 + 2 /* zlib header */ + 5 /* stored block header */;
  ASSERT_LT(row + 2, bytes.size());
  EXPECT_EQ(bytes[row + 1], 0x01);
  EXPECT_EQ(bytes[row + 2], 0x02);
  EXPECT_EQ(std::get<Image16u>(decode_png(bytes.data(), bytes.size(), "memory"))(0, 0), 0x0102);

  // Written by someone else: big-endian bytes 01 02 read back as 0x0102.
  const Bytes crafted = make_png(1, 1, 16, 0, {0, 0x01, 0x02});
  EXPECT_EQ(std::get<Image16u>(decode_png(crafted.data(), crafted.size(), "crafted"))(0, 0), 0x0102);
}

// A camera's PNG (gray, 8 or 16 bits) with each of the five row filters, its data split over
// several IDAT chunks: read back exactly, whichever path reads it (libdeflate's or libpng's),
// and by libdeflate's where the build has it.
TEST(Png, EveryRowFilterOfACamerasImageReadsBackExactly) {
  const int width = 37, height = 30;
  for (const int bit_depth : {8, 16}) {
    const std::size_t bpp = static_cast<std::size_t>(bit_depth / 8), row_bytes = std::size_t{width} * bpp;
    std::mt19937 random(static_cast<std::uint32_t>(bit_depth));
    Bytes raw(row_bytes * height);
    for (std::size_t i = 0; i < raw.size(); ++i) {
      raw[i] = static_cast<std::uint8_t>((i % row_bytes) * 3 + (i / row_bytes) * 5 + (random() % 9));  // a ramp, noisy
    }
    const Bytes scanlines = filter_rows(raw, row_bytes, bpp, [](int y) { return y % 5; });
    for (const std::size_t chunks : {std::size_t{1}, std::size_t{4}}) {
      const Bytes png = make_png(width, height, bit_depth, 0, scanlines, {{"tEXt", Bytes(5, 'x')}}, false, chunks);
      const AnyImage decoded = decode_png(png.data(), png.size(), "filters");
      std::optional<AnyImage> fast = png_detail::decode_gray_png(png.data(), png.size(), {0, 0, width, height},
                                                                 MemoryType::kHost);
#if SLS_HAVE_LIBDEFLATE
      ASSERT_TRUE(fast.has_value()) << bit_depth << " bits, " << chunks << " IDAT chunks";
#endif
      for (const AnyImage* image : {&decoded, fast ? &*fast : &decoded}) {
        for (int y = 0; y < height; ++y) {
          for (int x = 0; x < width; ++x) {
            const std::uint8_t* sample = raw.data() + static_cast<std::size_t>(y) * row_bytes + static_cast<std::size_t>(x) * bpp;
            if (bit_depth == 8) {
              ASSERT_EQ(std::get<Image8u>(*image)(x, y), sample[0]) << x << "," << y;
            } else {
              ASSERT_EQ(std::get<Image16u>(*image)(x, y), (sample[0] << 8) | sample[1]) << x << "," << y;
            }
          }
        }
      }
    }
  }
}

// What the fast path leaves to libpng, and libpng then judges: a PLTE chunk in a gray image, a
// bad filter type, a zlib stream shorter than the image.
TEST(Png, ACamerasImageTheFastPathFindsFaultWithGoesToLibpng) {
  const Bytes rows = {0, 1, 2, 0, 3, 4};
  Bytes png = make_png(2, 2, 8, 0, rows, {{"PLTE", {0, 0, 0}}});
  EXPECT_FALSE(png_detail::decode_gray_png(png.data(), png.size(), {0, 0, 2, 2}, MemoryType::kHost));
  png = make_png(2, 2, 8, 0, {7, 1, 2, 0, 3, 4});
  EXPECT_FALSE(png_detail::decode_gray_png(png.data(), png.size(), {0, 0, 2, 2}, MemoryType::kHost));
  expect_error([&] { (void)decode_png(png.data(), png.size(), "filter.png"); }, ErrorCode::kFormat, "filter.png");
  png = make_png(2, 2, 8, 0, {0, 1, 2});
  EXPECT_FALSE(png_detail::decode_gray_png(png.data(), png.size(), {0, 0, 2, 2}, MemoryType::kHost));
  expect_error([&] { (void)decode_png(png.data(), png.size(), "short.png"); }, ErrorCode::kFormat, "short.png");
  // Sides past what image_io reads (2^20): libpng refuses them.
  png = make_png(1u << 25, 1, 8, 0, {0, 1, 2});
  EXPECT_FALSE(png_detail::decode_gray_png(png.data(), png.size(), {0, 0, 2, 1}, MemoryType::kHost));
  expect_error([&] { (void)decode_png(png.data(), png.size(), "wide.png"); }, ErrorCode::kFormat, "wide.png");
}

// A region of the image: the crop of the whole image, for a camera's PNG (libdeflate's path)
// and for those libpng reads (RGB, interlaced); one outside the image is refused.
TEST(Png, ARegionIsTheCropOfTheWholeImage) {
  test::TemporaryDirectory dir;
  const Image16u image16 = random_image<std::uint16_t>(41, 29, 11);
  write_png(dir.file("16.png"), image16);
  const ImageRegion region{5, 7, 30, 13};
  const Image16u part = read_png_u16(dir.file("16.png"), region);
  ASSERT_EQ(part.width(), 30);
  ASSERT_EQ(part.height(), 13);
  for (int y = 0; y < 13; ++y) {
    for (int x = 0; x < 30; ++x) ASSERT_EQ(part(x, y), image16(x + 5, y + 7));
  }
  const Image8u image8 = random_image<std::uint8_t>(41, 29, 12);
  write_png(dir.file("8.png"), image8);
  const Image16u widened = read_png_u16(dir.file("8.png"), region);
  for (int y = 0; y < 13; ++y) {
    for (int x = 0; x < 30; ++x) ASSERT_EQ(widened(x, y), image8(x + 5, y + 7));
  }
  // RGB with equal channels (libpng converts it to that gray value).
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(41) * 29 * 3);
  for (std::size_t n = 0; n < rgb.size(); ++n) rgb[n] = image8.data()[n / 3];
  write_png_rgb(dir.file("rgb.png"), rgb.data(), 41, 29);
  const Image16u from_rgb = read_png_u16(dir.file("rgb.png"), region);
  for (int y = 0; y < 13; ++y) {
    for (int x = 0; x < 30; ++x) ASSERT_EQ(from_rgb(x, y), image8(x + 5, y + 7));
  }
  const Bytes adam7 = make_png(2, 2, 8, 0, {0, 11, 0, 22, 0, 33, 44}, {}, true);
  EXPECT_EQ(std::get<Image8u>(decode_png(adam7.data(), adam7.size(), "adam7", ImageRegion{1, 1, 1, 1}))(0, 0), 44);
  for (const ImageRegion outside : {ImageRegion{35, 0, 7, 5}, ImageRegion{0, 25, 5, 5}, ImageRegion{-1, 0, 5, 5},
                                    ImageRegion{0, 0, 0, 5}}) {
    expect_error([&] { (void)read_png_u16(dir.file("16.png"), outside); }, ErrorCode::kInvalidArgument,
                 "16.png: the region");
  }
}

TEST(Png, ReadsLowBitDepthGray) {
  // 1-bit: 8 pixels 10110001 -> 255 0 255 255 0 0 0 255 (libpng scales up to 8 bits).
  Bytes png = make_png(8, 1, 1, 0, {0, 0xb1});
  Image8u image = std::get<Image8u>(decode_png(png.data(), png.size(), "1bit"));
  const std::uint8_t expected1[] = {255, 0, 255, 255, 0, 0, 0, 255};
  for (int x = 0; x < 8; ++x) EXPECT_EQ(image(x, 0), expected1[x]) << x;
  // 2-bit: 0..3 -> 0, 85, 170, 255.
  png = make_png(4, 1, 2, 0, {0, 0x1b});
  image = std::get<Image8u>(decode_png(png.data(), png.size(), "2bit"));
  const std::uint8_t expected2[] = {0, 85, 170, 255};
  for (int x = 0; x < 4; ++x) EXPECT_EQ(image(x, 0), expected2[x]) << x;
  // 4-bit, odd width: 0x0 0xf 0x8 -> 0, 255, 136.
  png = make_png(3, 1, 4, 0, {0, 0x0f, 0x80});
  image = std::get<Image8u>(decode_png(png.data(), png.size(), "4bit"));
  EXPECT_EQ(image(0, 0), 0);
  EXPECT_EQ(image(1, 0), 255);
  EXPECT_EQ(image(2, 0), 136);
}

TEST(Png, ReadsInterlaced) {
  // Adam7 on 2x2: pass 1 holds (0,0), pass 6 (1,0), pass 7 the second row.
  const Bytes png = make_png(2, 2, 8, 0, {0, 11, 0, 22, 0, 33, 44}, {}, true);
  const Image8u image = std::get<Image8u>(decode_png(png.data(), png.size(), "adam7"));
  EXPECT_EQ(image(0, 0), 11);
  EXPECT_EQ(image(1, 0), 22);
  EXPECT_EQ(image(0, 1), 33);
  EXPECT_EQ(image(1, 1), 44);
}

TEST(Png, ConvertsAlphaColourAndPaletteToGray) {
  // Gray + alpha, 8 bit: the alpha is dropped.
  Bytes png = make_png(2, 1, 8, 4, {0, 10, 255, 200, 0});
  Image8u image = std::get<Image8u>(decode_png(png.data(), png.size(), "ga"));
  EXPECT_EQ(image(0, 0), 10);
  EXPECT_EQ(image(1, 0), 200);
  // Gray + alpha, 16 bit.
  png = make_png(1, 1, 16, 4, {0, 0x12, 0x34, 0xff, 0xff});
  EXPECT_EQ(std::get<Image16u>(decode_png(png.data(), png.size(), "ga16"))(0, 0), 0x1234);
  // RGB and RGBA with equal channels give that value; pure red gives its luma.
  png = make_png(2, 1, 8, 2, {0, 77, 77, 77, 255, 0, 0});
  image = std::get<Image8u>(decode_png(png.data(), png.size(), "rgb"));
  EXPECT_EQ(image(0, 0), 77);
  EXPECT_NEAR(image(1, 0), 54, 1);  // 0.2126 * 255
  png = make_png(1, 1, 8, 6, {0, 99, 99, 99, 7});
  EXPECT_EQ(std::get<Image8u>(decode_png(png.data(), png.size(), "rgba"))(0, 0), 99);
  // Palette (2-bit indices) with a tRNS chunk.
  png = make_png(3, 1, 2, 3, {0, 0x24}, {{"PLTE", {0, 0, 0, 50, 50, 50, 200, 200, 200}}, {"tRNS", {0, 128}}});
  image = std::get<Image8u>(decode_png(png.data(), png.size(), "palette"));
  EXPECT_EQ(image(0, 0), 0);
  EXPECT_EQ(image(1, 0), 200);
  EXPECT_EQ(image(2, 0), 50);
}

TEST(Png, TypedReadersConvertOrReject) {
  test::TemporaryDirectory dir;
  const Image8u image8 = random_image<std::uint8_t>(5, 4, 5);
  write_png(dir.file("8.png"), image8);
  const Image16u widened = read_png_u16(dir.file("8.png"));
  ASSERT_EQ(widened.width(), 5);
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 5; ++x) EXPECT_EQ(widened(x, y), image8(x, y));
  }
  write_png(dir.file("16.png"), random_image<std::uint16_t>(5, 4, 6));
  expect_error([&] { read_png_u8(dir.file("16.png")); }, ErrorCode::kFormat, "16.png");
}

TEST(Png, MissingFileIsNotFound) {
  test::TemporaryDirectory dir;
  expect_error([&] { read_png(dir.file("absent.png")); }, ErrorCode::kNotFound, "absent.png");
  expect_error([&] { read_png_header(dir.file("absent.png")); }, ErrorCode::kNotFound, "absent.png");
}

TEST(Png, NotAPngNamesTheFile) {
  test::TemporaryDirectory dir;
  write_file_atomic(dir.file("text.png"), "this is plain text, not an image");
  expect_error([&] { read_png(dir.file("text.png")); }, ErrorCode::kFormat, "text.png: not a PNG");
  expect_error([&] { read_png_header(dir.file("text.png")); }, ErrorCode::kFormat, "text.png: not a PNG");
  write_file_atomic(dir.file("empty.png"), "");
  expect_error([&] { read_png(dir.file("empty.png")); }, ErrorCode::kFormat, "empty.png");
  expect_error([&] { read_png_header(dir.file("empty.png")); }, ErrorCode::kFormat, "empty.png");
}

TEST(Png, TruncatedPngNamesTheFile) {
  test::TemporaryDirectory dir;
  const Bytes full = encode_png(random_image<std::uint16_t>(37, 23, 7));
  // Cut inside the image data, just before IEND, and inside the header.
  for (std::size_t keep : {full.size() / 2, full.size() - 12, full.size() - 1, std::size_t{20}}) {
    const std::string name = "cut" + std::to_string(keep) + ".png";
    write_bytes(dir.file(name), Bytes(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(keep)));
    expect_error([&] { read_png(dir.file(name)); }, ErrorCode::kFormat, name);
  }
  expect_error([&] { read_png(dir.file("cut" + std::to_string(full.size() / 2) + ".png")); }, ErrorCode::kFormat,
               "truncated");
  // The header alone is readable from a file cut after IHDR, but not from one cut inside it.
  EXPECT_EQ(read_png_header(dir.file("cut" + std::to_string(full.size() / 2) + ".png")).width, 37);
  expect_error([&] { read_png_header(dir.file("cut20.png")); }, ErrorCode::kFormat, "cut20.png");
}

TEST(Png, CorruptDataNamesTheFile) {
  test::TemporaryDirectory dir;
  const Bytes good = encode_png(random_image<std::uint8_t>(37, 23, 8));
  const std::string text(good.begin(), good.end());
  // A flipped bit in the image data: CRC error.
  Bytes bad = good;
  bad[text.find("IDAT") + 20] ^= 0x10;
  write_bytes(dir.file("crc.png"), bad);
  expect_error([&] { read_png(dir.file("crc.png")); }, ErrorCode::kFormat, "crc.png");
  // A flipped bit in IHDR: caught by the header reader too.
  bad = good;
  bad[18] ^= 0x01;
  write_bytes(dir.file("ihdr.png"), bad);
  expect_error([&] { read_png(dir.file("ihdr.png")); }, ErrorCode::kFormat, "ihdr.png");
  expect_error([&] { read_png_header(dir.file("ihdr.png")); }, ErrorCode::kFormat, "CRC");
  // Valid CRCs around garbage compressed data: a zlib error.
  Bytes scan(1 + 4, 0);
  Bytes garbage = make_png(4, 1, 8, 0, scan);
  const std::string garbage_text(garbage.begin(), garbage.end());
  const std::size_t idat = garbage_text.find("IDAT");
  garbage[idat + 4 + 2] = 0xff;  // invalid deflate block type; the chunk CRC is then fixed
  const std::uint32_t length = (std::uint32_t{garbage[idat - 4]} << 24) | (std::uint32_t{garbage[idat - 3]} << 16) |
                               (std::uint32_t{garbage[idat - 2]} << 8) | garbage[idat - 1];
  const std::uint32_t crc = crc32_of(garbage.data() + idat, 4 + length);
  for (int i = 0; i < 4; ++i) garbage[idat + 4 + length + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(crc >> (24 - 8 * i));
  write_bytes(dir.file("zlib.png"), garbage);
  expect_error([&] { read_png(dir.file("zlib.png")); }, ErrorCode::kFormat, "zlib.png");
}

// Decoded with libpng's simplified API as RGB (our reader converts to luma), so the round
// trip checks the very bytes written.
TEST(Png, RgbRoundTripIsExact) {
  test::TemporaryDirectory dir;
  const int width = 29, height = 17;
  std::mt19937 rng(4);
  std::vector<std::uint8_t> rgb(static_cast<std::size_t>(width) * height * 3);
  for (std::uint8_t& v : rgb) v = static_cast<std::uint8_t>(rng() & 0xffu);
  write_png_rgb(dir.file("c.png"), rgb.data(), width, height);
  const PngHeader header = read_png_header(dir.file("c.png"));
  EXPECT_EQ(header.width, width);
  EXPECT_EQ(header.height, height);
  EXPECT_EQ(header.bit_depth, 8);
  EXPECT_EQ(header.channels, 3);
  EXPECT_FALSE(header.palette);

  const std::vector<std::uint8_t> encoded = encode_png_rgb(rgb.data(), width, height);
  png_image image;
  std::memset(&image, 0, sizeof(image));
  image.version = PNG_IMAGE_VERSION;
  ASSERT_NE(png_image_begin_read_from_memory(&image, encoded.data(), encoded.size()), 0) << image.message;
  image.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> decoded(PNG_IMAGE_SIZE(image));
  ASSERT_NE(png_image_finish_read(&image, nullptr, decoded.data(), 0, nullptr), 0) << image.message;
  EXPECT_EQ(decoded, rgb);

  // Our reader gives grey for grey pixels exactly.
  std::vector<std::uint8_t> grey_rgb(static_cast<std::size_t>(width) * height * 3);
  for (std::size_t n = 0; n < grey_rgb.size(); ++n) grey_rgb[n] = static_cast<std::uint8_t>((n / 3) % 256);
  write_png_rgb(dir.file("g.png"), grey_rgb.data(), width, height);
  const Image8u grey = read_png_u8(dir.file("g.png"));
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) EXPECT_EQ(grey(x, y), static_cast<std::uint8_t>((y * width + x) % 256));
  }
  expect_error([&] { write_png_rgb(dir.file("e.png"), nullptr, 4, 4); }, ErrorCode::kInvalidArgument, "e.png");
  expect_error([&] { write_png_rgb(dir.file("z.png"), rgb.data(), 0, 4); }, ErrorCode::kInvalidArgument, "z.png");
}

TEST(Png, RejectsUnwritableInput) {
  test::TemporaryDirectory dir;
  expect_error([&] { write_png(dir.file("e.png"), Image8u()); }, ErrorCode::kInvalidArgument, "e.png");
  PngWriteOptions options;
  options.compression_level = 12;
  expect_error([&] { write_png(dir.file("l.png"), Image8u(2, 2), options); }, ErrorCode::kInvalidArgument, "level");
  expect_error([&] { write_png(dir.file("no/such/dir/x.png"), Image8u(2, 2)); }, ErrorCode::kIo, "x.png");
}

// A PNG file far larger than its header's image can be (here 1 GiB, sparse) is refused from
// its size before anything is read into memory; a normal one with a little trailing data is not.
TEST(Png, AFileLargerThanItsHeaderAllowsIsRefusedBeforeReading) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("huge.png");
  const Bytes small = encode_png(random_image<std::uint16_t>(8, 8, 3));
  write_file_atomic(path, std::string(small.begin(), small.end()));
  ASSERT_EQ(::truncate(path.c_str(), off_t{1} << 30), 0);
  expect_error([&] { read_png(path); }, ErrorCode::kFormat, path + ": the file holds 1073741824 bytes (1024.0 MiB)");
  EXPECT_EQ(read_png_header(path).width, 8);  // the header alone is still readable
  ASSERT_EQ(::truncate(path.c_str(), static_cast<off_t>(small.size() + 4096)), 0);
  EXPECT_EQ(std::get<Image16u>(read_png(path)).width(), 8);
}

// A decompression bomb: a file of a hundred bytes whose header announces 1M x 1M pixels (and a
// 1 GiB image of 16-bit RGBA) is refused before the image is allocated, since deflate cannot
// expand 1032-fold; a highly compressible real image is not.
TEST(Png, AHeaderAnnouncingMoreThanTheFileCanHoldIsRefusedBeforeAllocating) {
  const Bytes bomb = make_png(1u << 20, 1u << 20, 8, 0, Bytes(10, 0));
  expect_error([&] { (void)decode_png(bomb.data(), bomb.size(), "bomb.png"); }, ErrorCode::kFormat,
               "bomb.png: corrupt PNG: " + std::to_string(bomb.size()) +
                   " bytes cannot hold the 1048576x1048576 image its header announces");
  const Bytes rgba = make_png(16384, 4096, 16, 6, Bytes(10, 0));
  expect_error([&] { (void)decode_png(rgba.data(), rgba.size(), "rgba.png"); }, ErrorCode::kFormat,
               "bytes cannot hold the 16384x4096 image");
  const Bytes flat = encode_png(Image16u(4000, 3000, 0));
  EXPECT_EQ(std::get<Image16u>(decode_png(flat.data(), flat.size(), "flat.png")).width(), 4000);
}

// Found by fuzz_png: a 106-byte file (its IHDR CRC made right) whose tEXt chunk claims 1.8 GB.
// libpng reads ancillary chunks whole and allocated that much; chunk lengths are now checked
// against the bytes that follow first.
// In a child (a clean baseline), the decode must leave the peak of its address space within
// 64 MiB. (Sanitizers reserve address space of their own, so they skip it.)
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
std::size_t vm_peak_kb() {
  std::FILE* status = std::fopen("/proc/self/status", "r");
  unsigned long kb = 0;
  char line[256];
  while (status != nullptr && std::fgets(line, sizeof line, status) != nullptr) {
    if (std::sscanf(line, "VmPeak: %lu kB", &kb) == 1) break;
  }
  if (status != nullptr) std::fclose(status);
  return kb;
}

TEST(Png, AnAncillaryChunkClaimingGigabytesIsNotAllocated) {
  const Bytes file = {0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
                      0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x06, 0x00, 0x00, 0x00, 0x72, 0xb6, 0x0d,
                      0x24, 0x6d, 0x6f, 0x72, 0x79, 0x74, 0x45, 0x58, 0x74, 0x43, 0x6f, 0x6d, 0x6d, 0x65, 0x6e, 0x74,
                      0x00, 0x73, 0x65, 0x65, 0x64, 0xcb, 0x99, 0xb6, 0xe3, 0x00, 0x00, 0x00, 0x16, 0x49, 0x44, 0x41,
                      0x54, 0x78, 0xda, 0x63, 0xf8, 0xcf, 0xc0, 0xaa, 0x1f, 0x08, 0x1b, 0x34, 0x27, 0x40, 0xe7, 0x27,
                      0x18, 0x00, 0x7f, 0x37, 0x31, 0x05, 0x97, 0x76, 0x51, 0xcb, 0x7e, 0x00, 0x00, 0x00, 0x00, 0x49,
                      0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::size_t before = vm_peak_kb();
    bool format_error = false;
    try {
      (void)decode_png(file.data(), file.size(), "text.png");
    } catch (const Error& error) {
      format_error = error.code() == ErrorCode::kFormat;
    }
    const std::size_t grown_kb = vm_peak_kb() - before;
    _exit(before == 0 ? 3 : !format_error ? 2 : grown_kb > (64u << 10) ? 1 : 0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: gigabytes allocated; 2: not a format error; 3: no VmPeak";
}
#endif

}  // namespace
}  // namespace sls
