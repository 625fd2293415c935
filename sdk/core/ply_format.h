// Internal to the PLY reader and writer (sdk/core/ply_*.cpp): scalar types, byte access and
// the parsed header. Not part of the SDK's interface.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "sdk/core/error.h"

namespace sls::ply_detail {

constexpr bool kHostBigEndian = __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;

// ---------------------------------------------------------------------------------------------
// Scalar types and byte access

enum class Type : std::uint8_t { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

inline std::size_t type_size(Type type) {
  switch (type) {
    case Type::kInt8:
    case Type::kUint8: return 1;
    case Type::kInt16:
    case Type::kUint16: return 2;
    case Type::kInt32:
    case Type::kUint32:
    case Type::kFloat32: return 4;
    case Type::kFloat64: return 8;
  }
  return 0;
}

inline bool is_integer(Type type) { return type != Type::kFloat32 && type != Type::kFloat64; }

// Calls f with a value of the C++ type for `type`, so one template body serves all eight.
template <typename F>
decltype(auto) visit_type(Type type, F&& f) {
  switch (type) {
    case Type::kInt8: return f(std::int8_t{});
    case Type::kUint8: return f(std::uint8_t{});
    case Type::kInt16: return f(std::int16_t{});
    case Type::kUint16: return f(std::uint16_t{});
    case Type::kInt32: return f(std::int32_t{});
    case Type::kUint32: return f(std::uint32_t{});
    case Type::kFloat32: return f(float{});
    case Type::kFloat64: return f(double{});
  }
  throw_error(ErrorCode::kInternal, "invalid PLY scalar type {}", static_cast<int>(type));
}

// memcpy, not a cast: PLY records are packed, so values are unaligned.
template <typename T, bool Swap>
T load(const char* p) {
  T value;
  if constexpr (Swap) {
    char bytes[sizeof(T)];
    for (std::size_t i = 0; i < sizeof(T); ++i) bytes[i] = p[sizeof(T) - 1 - i];
    std::memcpy(&value, bytes, sizeof(T));
  } else {
    std::memcpy(&value, p, sizeof(T));
  }
  return value;
}

template <typename T>
T load(const char* p, bool swap) {
  return swap ? load<T, true>(p) : load<T, false>(p);
}

inline double load_as_double(const char* p, Type type, bool swap) {
  return visit_type(type, [&](auto tag) { return static_cast<double>(load<decltype(tag)>(p, swap)); });
}

// Integer types only (checked when the header is read); uint32 fits in int64.
inline std::int64_t load_as_integer(const char* p, Type type, bool swap) {
  return visit_type(type, [&](auto tag) -> std::int64_t {
    using T = decltype(tag);
    if constexpr (std::is_integral_v<T>) {
      return static_cast<std::int64_t>(load<T>(p, swap));
    } else {
      throw_error(ErrorCode::kInternal, "PLY integer read of a floating-point value");
    }
  });
}

template <typename T>
void store(char*& p, T value) {
  if constexpr (kHostBigEndian) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T); ++i) p[i] = bytes[sizeof(T) - 1 - i];
  } else {
    std::memcpy(p, &value, sizeof(T));
  }
  p += sizeof(T);
}

// ---------------------------------------------------------------------------------------------
// Header

enum class Format { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct Property {
  std::string name;
  Type type = Type::kFloat32;  // the scalar's type, or the type of a list's items
  bool is_list = false;
  Type count_type = Type::kUint8;  // lists only
  std::size_t offset = 0;          // byte offset in a fixed-size binary record
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;
  bool fixed_size = true;         // no lists: every binary record has record_bytes bytes
  std::size_t record_bytes = 0;   // fixed size, or the smallest record (all lists empty)

  const Property* find(std::string_view property_name) const {
    for (const Property& property : properties) {
      if (property.name == property_name) return &property;
    }
    return nullptr;
  }
  std::size_t index_of(const Property* property) const {
    return static_cast<std::size_t>(property - properties.data());
  }
};

struct Header {
  Format format = Format::kBinaryLittleEndian;
  std::vector<Element> elements;
  std::size_t data_offset = 0;
};

inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f'; }

// For messages: a token from a corrupt file may be long or binary.
std::string printable(std::string_view text);
// "vertices", "faces" or "'<name>' elements", for messages.
std::string plural(const Element& element);

// Parses the header of a PLY file's bytes; throws sls::Error (kFormat, kVersionMismatch)
// naming `source` and the header line.
Header parse_header(std::string_view bytes, const std::string& source);

}  // namespace sls::ply_detail
