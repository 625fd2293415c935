// Structs that carry their size (sls.h, "versioned structs"): inputs (the configs, the fed
// frames) and outputs (infos, summaries, results). The caller's struct_size, set by the _init()
// macro of the headers it was compiled with (the caller's sizeof), says how many bytes of the
// struct it has, so a program built against older headers (a smaller struct) gets the fields it
// knows, nothing is written past its struct, and the fields it lacks keep the library's defaults.
// An appended field must start at or after the previous version's sizeof (static_assert it
// where the struct is read): one in the old padding would read as present from an old struct.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <type_traits>

#include "sls/sls_export.h"

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

// A struct's _init for a caller's struct of `caller_size` bytes: `value` (the library's defaults)
// as far as both structs go, zeros past the library's (a newer header's fields: its context is
// refused anyway), struct_size the caller's size. Writes nothing past caller_size, and nothing
// at all for a size that cannot be a struct's (below struct_size's own, above kMaxStructSize).
template <typename T>
void init_versioned(T* out, std::size_t caller_size, T value) {
  static_assert(std::is_trivially_copyable<T>::value, "versioned structs are plain C structs");
  static_assert(offsetof(T, struct_size) == 0, "struct_size comes first");
  if (out == nullptr || caller_size < sizeof(std::size_t) || caller_size > kMaxStructSize) return;
  value.struct_size = caller_size;
  std::memcpy(out, &value, std::min(caller_size, sizeof(T)));
  if (caller_size > sizeof(T)) std::memset(reinterpret_cast<char*>(out) + sizeof(T), 0, caller_size - sizeof(T));
}

// A struct of T's type with every byte 0 and struct_size set: the defaults of most.
template <typename T>
T zeroed() {
  T value;
  std::memset(&value, 0, sizeof(value));
  value.struct_size = sizeof(value);
  return value;
}

// The sizeof a version of T had whose last field ended `end` bytes in: rounded up to T's
// alignment, as the compiler rounded it (what a program built against that version passes).
template <typename T>
constexpr std::size_t size_ending_at(std::size_t end) {
  return (end + alignof(T) - 1) / alignof(T) * alignof(T);
}

}  // namespace sls::capi

// The sizeof T had in API 0.4, whose last field was LAST.
#define SLS_CAPI_SIZE_0_4(T, LAST) sls::capi::size_ending_at<T>(offsetof(T, LAST) + sizeof(T::LAST))

// Defines the two exported _init functions of versioned struct T (sls.h): T_init_sized(s, size),
// which the headers' T_init(s) macro calls with the caller's sizeof, and T_init(s) itself, for
// programs built against the 0.4 headers (before the macro): it writes the 0.4 struct, whose
// last field was LAST_0_4. DEFAULTS: an expression giving T with the library's defaults.
#define SLS_CAPI_DEFINE_INIT(T, LAST_0_4, DEFAULTS)                                          \
  SLS_API void T##_init_sized(T* out, size_t size) {                                         \
    sls::capi::init_versioned<T>(out, size, DEFAULTS);                                       \
  }                                                                                          \
  SLS_API void(T##_init)(T * out) {                                                          \
    sls::capi::init_versioned<T>(out, SLS_CAPI_SIZE_0_4(T, LAST_0_4), DEFAULTS);             \
  }

namespace sls::capi {

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
