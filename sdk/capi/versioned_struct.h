// Structs that carry their size: outputs (sls_device_info, sls_camera_info, sls_frame_info) and
// inputs (sls_context_config, sls_scan_config, sls_capture_config, sls_calibration_config), and
// sls_scan_summary, sls_loop_closure, sls_calibration_summary, sls_intrinsics and
// sls_calibration_view (outputs). The caller's struct_size,
// set by the _init() of the headers it was compiled with, says how many bytes of the struct it
// has, so a program built against older headers (a smaller struct) gets the fields it knows,
// nothing is written past its struct, and the fields it lacks keep the library's defaults.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <type_traits>

#include "sdk/core/error.h"

namespace sls::capi {

// The largest struct_size taken as genuine; anything larger is an uninitialised struct.
constexpr std::size_t kMaxStructSize = 65536;

// Throws kInvalidArgument unless `out` has a struct_size a caller's _init() can have set:
// at least `first_version_size` (the struct's first published version). `type` names the
// struct in the message. Check before doing work whose result would otherwise be lost.
template <typename T>
void require_versioned(const T* out, std::size_t first_version_size, const char* type) {
  static_assert(offsetof(T, struct_size) == 0, "struct_size comes first");
  if (out->struct_size < first_version_size || out->struct_size > kMaxStructSize) {
    throw_error(ErrorCode::kInvalidArgument, "{}.struct_size is {} (initialise it with {}_init)", type,
                out->struct_size, type);
  }
}

// Copies `value` into `*out` up to the caller's struct_size (checked as above).
template <typename T>
void write_versioned(const T& value, T* out, std::size_t first_version_size, const char* type) {
  static_assert(std::is_trivially_copyable<T>::value, "versioned structs are plain C structs");
  require_versioned(out, first_version_size, type);
  const std::size_t caller_size = out->struct_size;
  std::memcpy(out, &value, std::min(caller_size, sizeof(T)));
  out->struct_size = caller_size;
}

// The caller's input struct over `defaults` (from the library's own _init()): the fields its
// struct_size covers are the caller's (checked as above), the rest keep their defaults.
template <typename T>
T read_versioned(const T* in, T defaults, std::size_t first_version_size, const char* type) {
  static_assert(std::is_trivially_copyable<T>::value, "versioned structs are plain C structs");
  require_versioned(in, first_version_size, type);
  std::memcpy(&defaults, in, std::min(in->struct_size, sizeof(T)));
  defaults.struct_size = sizeof(T);
  return defaults;
}

// The integer a C caller stored in an enum field of one of its structs. C may store any int
// there, while loading a C++ enum outside the range of its values is undefined behaviour: read
// the bytes, then compare with the enumerators.
template <typename Enum>
long long c_enum_value(const Enum& field) {
  static_assert(std::is_enum<Enum>::value, "an enum field");
  std::underlying_type_t<Enum> value;
  std::memcpy(&value, &field, sizeof(value));
  return static_cast<long long>(value);
}

}  // namespace sls::capi
