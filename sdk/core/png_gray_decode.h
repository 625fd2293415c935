// The fast path of sdk/core/image_io's PNG reading, for the PNGs cameras' recordings hold:
// grayscale, 8 or 16 bits, not interlaced. libdeflate inflates the image data in one call
// (~1.6x zlib's speed on a 4000 x 3000 16-bit image) and the rows are unfiltered here, into
// the region asked for only. Internal to sdk/core (image_io.cpp is its one caller).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>

#include "sdk/core/image.h"
#include "sdk/core/image_io.h"

namespace sls::png_detail {

// The pixels of `region` (inside the image: the caller checks) of a PNG of the kind above,
// or nullopt for any other PNG and for any file this path finds fault with (a CRC, the
// deflate stream, a filter type, a critical chunk it does not know): libpng then decodes it,
// or names the fault. So this path returns only what libpng would decode to the same pixels.
// Without libdeflate (SLS_HAVE_LIBDEFLATE unset: a machine without it), always nullopt.
// Rows below the region are neither unfiltered nor checked.
std::optional<AnyImage> decode_gray_png(const std::uint8_t* data, std::size_t size, const ImageRegion& region,
                                        MemoryType memory);

}  // namespace sls::png_detail
