// What the parser fuzz targets share. Each target calls a parser on the input and catches
// sls::Error only: any other exception (std::bad_alloc from a huge count, std::out_of_range,
// a JSON or YAML library's own) escapes, and libFuzzer reports it with the input.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace sls::fuzz {

// A property violation: abort, so libFuzzer saves the input.
inline void check(bool condition) {
  if (!condition) std::abort();
}

inline std::string as_text(const std::uint8_t* data, std::size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

}  // namespace sls::fuzz
