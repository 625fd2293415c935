// PFM (Portable Float Map): bit-exact round trips, the on-disk layout (header, bottom-to-top
// rows, byte order), and every kind of broken file giving an sls::Error that names it.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

using Bytes = std::vector<std::uint8_t>;

std::uint32_t bits_of(float value) {
  std::uint32_t bits;
  std::memcpy(&bits, &value, 4);
  return bits;
}

float float_of(std::uint32_t bits) {
  float value;
  std::memcpy(&value, &bits, 4);
  return value;
}

void expect_bit_identical(const Image32f& a, const Image32f& b) {
  ASSERT_EQ(a.width(), b.width());
  ASSERT_EQ(a.height(), b.height());
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      ASSERT_EQ(bits_of(a(x, y)), bits_of(b(x, y))) << x << "," << y;
    }
  }
}

Image32f awkward_image(int width, int height) {
  Image32f image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) image(x, y) = 0.001f * static_cast<float>(x) - 3.25f * static_cast<float>(y);
  }
  image(0, 0) = std::numeric_limits<float>::quiet_NaN();
  image(1, 0) = std::numeric_limits<float>::infinity();
  image(2, 0) = -std::numeric_limits<float>::infinity();
  image(3, 0) = -0.0f;
  image(4, 0) = std::numeric_limits<float>::denorm_min();
  image(5, 0) = std::numeric_limits<float>::max();
  image(6, 0) = float_of(0x7fc12345u);  // a NaN with a payload
  return image;
}

void write_bytes(const std::string& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

Bytes with_header(const std::string& header, const std::vector<float>& samples, bool big_endian = false) {
  Bytes out(header.begin(), header.end());
  for (float sample : samples) {
    const std::uint32_t bits = bits_of(sample);
    for (int i = 0; i < 4; ++i) {
      const int shift = big_endian ? 24 - 8 * i : 8 * i;
      out.push_back(static_cast<std::uint8_t>(bits >> shift));
    }
  }
  return out;
}

TEST(Pfm, RoundTripIsBitExact) {
  test::TemporaryDirectory dir;
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{1, 1}, {7, 3}, {640, 480}, {13, 1000}}) {
    const Image32f image = awkward_image(std::max(w, 7), h);
    const std::string path = dir.file("image.pfm");
    write_pfm(path, image);
    expect_bit_identical(read_pfm(path), image);
    EXPECT_EQ(std::filesystem::file_size(path), std::string("Pf\n").size() +
                                                    std::to_string(image.width()).size() + 1 +
                                                    std::to_string(h).size() + 1 + 5 +
                                                    image.pixel_count() * 4);
  }
  // Nothing else is left in the folder (the write is atomic through a temporary).
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 1);
}

TEST(Pfm, LayoutIsBottomRowFirstLittleEndian) {
  Image32f image(2, 3);
  float value = 1;
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 2; ++x) image(x, y) = value++;  // rows: {1,2} {3,4} {5,6}
  }
  const Bytes bytes = encode_pfm(image.view());
  EXPECT_EQ(bytes, with_header("Pf\n2 3\n-1.0\n", {5, 6, 3, 4, 1, 2}));
}

TEST(Pfm, WritesAStridedView) {
  const Image32f big = awkward_image(20, 10);
  // The 5x4 window at (3, 2).
  const ImageView<const float> window{big.data() + 2 * 20 + 3, 5, 4, big.stride_bytes()};
  const Image32f back = decode_pfm(encode_pfm(window).data(), encode_pfm(window).size(), "window");
  ASSERT_EQ(back.width(), 5);
  ASSERT_EQ(back.height(), 4);
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 5; ++x) EXPECT_EQ(bits_of(back(x, y)), bits_of(big(x + 3, y + 2)));
  }
}

TEST(Pfm, ReadsBigEndianAndLooseWhitespace) {
  const std::vector<float> samples = {5, 6, 3, 4, 1, -2.5f};
  for (const std::string& header : {std::string("Pf\n2 3\n1.0\n"), std::string("Pf 2  3\t\n  4.0\n"),
                                    std::string("Pf\r\n2\n3\n1e0\n")}) {
    const Bytes bytes = with_header(header, samples, /*big_endian=*/true);
    const Image32f image = decode_pfm(bytes.data(), bytes.size(), "big");
    ASSERT_EQ(image.width(), 2) << header;
    ASSERT_EQ(image.height(), 3);
    EXPECT_EQ(image(0, 0), 1.0f);
    EXPECT_EQ(image(1, 0), -2.5f);  // the scale's magnitude is not applied
    EXPECT_EQ(image(0, 2), 5.0f);
  }
  // Little-endian with another negative scale, and trailing bytes after the pixels.
  Bytes bytes = with_header("Pf\n2 3\n-0.5\n", samples);
  bytes.push_back('\n');
  const Image32f image = decode_pfm(bytes.data(), bytes.size(), "little");
  EXPECT_EQ(image(1, 0), -2.5f);
}

ErrorCode decode_error(const Bytes& bytes, std::string* message = nullptr) {
  try {
    decode_pfm(bytes.data(), bytes.size(), "sample.pfm");
  } catch (const Error& error) {
    if (message != nullptr) *message = error.what();
    EXPECT_NE(std::string(error.what()).find("sample.pfm"), std::string::npos) << error.what();
    return error.code();
  }
  return ErrorCode::kInternal;
}

TEST(Pfm, RejectsBrokenFiles) {
  const std::vector<float> six = {1, 2, 3, 4, 5, 6};
  std::string message;
  EXPECT_EQ(decode_error({}), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("P5\n2 3\n255\n", {})), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("PF\n2 3\n-1.0\n", six), &message), ErrorCode::kFormat);
  EXPECT_NE(message.find("colour"), std::string::npos) << message;
  EXPECT_EQ(decode_error(with_header("Pfx\n2 3\n-1.0\n", six)), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n0 3\n-1.0\n", six)), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n-2 3\n-1.0\n", six)), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n2x 3\n-1.0\n", six)), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n2000000 3\n-1.0\n", six)), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n2 3\n0.0\n", six)), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n2 3\nnan\n", six)), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n2 3\n-1.0x\n", six)), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n2 3\n", {})), ErrorCode::kFormat);
  EXPECT_EQ(decode_error(with_header("Pf\n2 3\n-1.0", {})), ErrorCode::kFormat);  // ends in the header
  EXPECT_EQ(decode_error(with_header("Pf\n2 3\n-1.0\n", {1, 2, 3, 4, 5}), &message), ErrorCode::kFormat);
  EXPECT_NE(message.find("truncated"), std::string::npos) << message;
  Bytes short_by_one = with_header("Pf\n2 3\n-1.0\n", six);
  short_by_one.pop_back();
  EXPECT_EQ(decode_error(short_by_one), ErrorCode::kFormat);
}

TEST(Pfm, FileErrorsNameThePath) {
  test::TemporaryDirectory dir;
  const std::string missing = dir.file("missing.pfm");
  try {
    read_pfm(missing);
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kNotFound);
    EXPECT_NE(std::string(error.what()).find(missing), std::string::npos) << error.what();
  }
  const std::string truncated = dir.file("truncated.pfm");
  write_bytes(truncated, with_header("Pf\n4 4\n-1.0\n", {1, 2, 3}));
  try {
    read_pfm(truncated);
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kFormat);
    EXPECT_NE(std::string(error.what()).find(truncated), std::string::npos) << error.what();
  }
  const std::string empty = dir.file("empty.pfm");
  try {
    write_pfm(empty, Image32f());
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find(empty), std::string::npos) << error.what();
  }
  EXPECT_FALSE(std::filesystem::exists(empty));
  const std::string unwritable = dir.file("no/such/folder/x.pfm");
  EXPECT_THROW(write_pfm(unwritable, awkward_image(8, 2)), Error);
}

// Only the bytes the header announces are read: a file with a huge (sparse) tail after the
// pixels reads at once, with no allocation of the tail.
TEST(Pfm, BytesAfterThePixelsAreNotRead) {
  test::TemporaryDirectory dir;
  const std::string path = dir.file("tail.pfm");
  write_bytes(path, with_header("Pf\n2 3\n-1.0\n", {1, 2, 3, 4, 5, 6}));
  ASSERT_EQ(::truncate(path.c_str(), off_t{8} << 30), 0);
  const Image32f image = read_pfm(path);
  ASSERT_EQ(image.width(), 2);
  EXPECT_EQ(image(0, 0), 5.0f);  // rows are stored bottom first
}

}  // namespace
}  // namespace sls
