// Little-endian byte writing and bounds-checked reading for the wire codecs of this folder.
// A reader never reads past its end: every read checks the remaining size first and throws
// sls::Error(kDevice) naming what it was reading, so a truncated or malformed message from a
// device is a clear error, never undefined behaviour.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "sdk/core/error.h"

namespace sls::fwif {

class ByteWriter {
 public:
  explicit ByteWriter(std::vector<std::uint8_t>& out) : out_(out) {}
  void u8(std::uint8_t value) { out_.push_back(value); }
  void u16(std::uint16_t value) {
    for (int shift = 0; shift < 16; shift += 8) out_.push_back(static_cast<std::uint8_t>(value >> shift));
  }
  void u32(std::uint32_t value) {
    for (int shift = 0; shift < 32; shift += 8) out_.push_back(static_cast<std::uint8_t>(value >> shift));
  }
  void u64(std::uint64_t value) {
    for (int shift = 0; shift < 64; shift += 8) out_.push_back(static_cast<std::uint8_t>(value >> shift));
  }
  void i16(std::int16_t value) { u16(static_cast<std::uint16_t>(value)); }
  void zeros(std::size_t count) { out_.insert(out_.end(), count, std::uint8_t{0}); }
  void bytes(const std::uint8_t* data, std::size_t size) { out_.insert(out_.end(), data, data + size); }
  // `text` then NUL padding to `field_size` (the caller checked that it fits).
  void padded_text(const std::string& text, std::size_t field_size) {
    out_.insert(out_.end(), text.begin(), text.end());
    zeros(field_size - text.size());
  }

 private:
  std::vector<std::uint8_t>& out_;
};

class ByteReader {
 public:
  // `context` names the message in errors, e.g. "headctl TURNTABLE_STATUS reply".
  ByteReader(const std::uint8_t* data, std::size_t size, std::string context)
      : data_(data), size_(size), context_(std::move(context)) {}

  std::size_t remaining() const { return size_ - position_; }
  const std::string& context() const { return context_; }

  std::uint8_t u8(const char* field) {
    need(1, field);
    return data_[position_++];
  }
  std::uint16_t u16(const char* field) {
    need(2, field);
    const auto value = static_cast<std::uint16_t>(data_[position_] | (data_[position_ + 1] << 8));
    position_ += 2;
    return value;
  }
  std::uint32_t u32(const char* field) {
    need(4, field);
    std::uint32_t value = 0;
    for (int i = 3; i >= 0; --i) value = (value << 8) | data_[position_ + static_cast<std::size_t>(i)];
    position_ += 4;
    return value;
  }
  std::uint64_t u64(const char* field) {
    need(8, field);
    std::uint64_t value = 0;
    for (int i = 7; i >= 0; --i) value = (value << 8) | data_[position_ + static_cast<std::size_t>(i)];
    position_ += 8;
    return value;
  }
  std::int16_t i16(const char* field) { return static_cast<std::int16_t>(u16(field)); }
  bool flag(const char* field) {
    const std::uint8_t value = u8(field);
    if (value > 1) throw_error(ErrorCode::kDevice, "{}: {} is {}, not 0 or 1", context_, field, value);
    return value == 1;
  }
  void reserved(std::size_t count, const char* field) {
    need(count, field);
    for (std::size_t i = 0; i < count; ++i) {
      if (data_[position_ + i] != 0) {
        throw_error(ErrorCode::kDevice, "{}: reserved byte {} of {} is 0x{:02x}, not 0", context_, i, field,
                    data_[position_ + i]);
      }
    }
    position_ += count;
  }
  // A NUL-padded printable-ASCII field: text first, only NULs after it.
  std::string padded_text(std::size_t field_size, const char* field) {
    need(field_size, field);
    std::string text;
    std::size_t i = 0;
    for (; i < field_size && data_[position_ + i] != 0; ++i) {
      check_printable(data_[position_ + i], field);
      text.push_back(static_cast<char>(data_[position_ + i]));
    }
    for (; i < field_size; ++i) {
      if (data_[position_ + i] != 0) {
        throw_error(ErrorCode::kDevice, "{}: {} has byte 0x{:02x} after its terminating NUL", context_, field,
                    data_[position_ + i]);
      }
    }
    position_ += field_size;
    return text;
  }
  std::string text(std::size_t size, const char* field) {
    need(size, field);
    std::string out;
    for (std::size_t i = 0; i < size; ++i) {
      check_printable(data_[position_ + i], field);
      out.push_back(static_cast<char>(data_[position_ + i]));
    }
    position_ += size;
    return out;
  }
  std::vector<std::uint8_t> rest() {
    std::vector<std::uint8_t> out(data_ + position_, data_ + size_);
    position_ = size_;
    return out;
  }
  void expect_end() const {
    if (position_ != size_) {
      throw_error(ErrorCode::kDevice, "{}: {} unexpected trailing byte(s) after {} bytes", context_, size_ - position_,
                  position_);
    }
  }

 private:
  void need(std::size_t count, const char* field) const {
    if (count > size_ - position_) {
      throw_error(ErrorCode::kDevice, "{}: truncated at {} ({} byte(s) left, {} needed, {} in all)", context_, field,
                  size_ - position_, count, size_);
    }
  }
  void check_printable(std::uint8_t c, const char* field) const {
    if (c < 0x20 || c > 0x7E) {
      throw_error(ErrorCode::kDevice, "{}: {} holds byte 0x{:02x}, which is not printable ASCII", context_, field, c);
    }
  }

  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t position_ = 0;
  std::string context_;
};

inline bool is_printable_ascii(const std::string& text) {
  for (const char c : text) {
    if (c < 0x20 || c > 0x7E) return false;
  }
  return true;
}

}  // namespace sls::fwif
