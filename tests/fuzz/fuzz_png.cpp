// libFuzzer target: PNG decoding (any colour type, bit depth and interlacing libpng reads).
// Whatever is accepted is an 8- or 16-bit grey image that survives an encode/decode round trip.
// Each input is tried as it is and with its chunk CRCs made right.
#include <algorithm>
#include <variant>
#include <vector>

#include <zlib.h>

#include "sdk/core/error.h"
#include "sdk/core/image_io.h"
#include "tests/fuzz/fuzz_support.h"

using sls::fuzz::check;

namespace {

void round_trip(const sls::Image32f&) { check(false); }  // PNGs decode to 8 or 16 bits only

template <typename T>
void round_trip(const sls::Image<T>& image) {
  check(image.width() > 0 && image.height() > 0);
  const std::vector<std::uint8_t> encoded = sls::encode_png(image);
  const sls::AnyImage again = sls::decode_png(encoded.data(), encoded.size(), "again.png");
  const auto* same = std::get_if<sls::Image<T>>(&again);
  check(same != nullptr && same->width() == image.width() && same->height() == image.height());
  check(std::equal(image.data(), image.data() + image.pixel_count(), same->data()));
}

// A copy whose chunk CRCs are made right, so that mutations reach past libpng's CRC checks
// into the chunk parsers and the image data.
std::vector<std::uint8_t> with_valid_crcs(const std::uint8_t* data, std::size_t size) {
  std::vector<std::uint8_t> bytes(data, data + size);
  std::size_t at = 8;  // after the signature
  while (at + 12 <= bytes.size()) {
    const std::uint32_t length = (std::uint32_t{bytes[at]} << 24) | (std::uint32_t{bytes[at + 1]} << 16) |
                                 (std::uint32_t{bytes[at + 2]} << 8) | bytes[at + 3];
    if (length > bytes.size() - at - 12) break;
    const std::uint32_t crc =
        static_cast<std::uint32_t>(crc32(crc32(0L, Z_NULL, 0), bytes.data() + at + 4, length + 4));
    std::uint8_t* out = bytes.data() + at + 8 + length;
    for (int k = 0; k < 4; ++k) out[k] = static_cast<std::uint8_t>(crc >> (24 - 8 * k));
    at += 12 + length;
  }
  return bytes;
}

void decode(const std::uint8_t* data, std::size_t size) {
  sls::AnyImage image;
  try {
    image = sls::decode_png(data, size, "fuzz.png");
  } catch (const sls::Error&) {
    return;
  }
  std::visit([](const auto& decoded) { round_trip(decoded); }, image);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  decode(data, size);
  const std::vector<std::uint8_t> fixed = with_valid_crcs(data, size);
  decode(fixed.data(), fixed.size());
  return 0;
}
