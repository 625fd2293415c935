// libFuzzer target: PFM decoding (header fields, either byte order). Whatever is accepted
// survives an encode/decode round trip bit for bit.
#include <cstring>
#include <vector>

#include "sdk/core/error.h"
#include "sdk/core/image_io.h"
#include "tests/fuzz/fuzz_support.h"

using sls::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  sls::Image32f image;
  try {
    image = sls::decode_pfm(data, size, "fuzz.pfm");
  } catch (const sls::Error&) {
    return 0;
  }
  check(image.width() > 0 && image.height() > 0);
  const std::vector<std::uint8_t> encoded = sls::encode_pfm(image.view());
  const sls::Image32f again = sls::decode_pfm(encoded.data(), encoded.size(), "again.pfm");
  check(again.width() == image.width() && again.height() == image.height());
  check(std::memcmp(again.data(), image.data(), image.pixel_count() * sizeof(float)) == 0);
  return 0;
}
