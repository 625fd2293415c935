// PLY header parsing (the format: ply.h).
#include <charconv>
#include <set>

#include <fmt/format.h>

#include "sdk/core/ply_format.h"

namespace sls::ply_detail {
namespace {

bool parse_type(std::string_view name, Type& type) {
  struct Entry {
    std::string_view name;
    Type type;
  };
  static constexpr Entry kTypes[] = {
      {"char", Type::kInt8},     {"int8", Type::kInt8},     {"uchar", Type::kUint8},   {"uint8", Type::kUint8},
      {"short", Type::kInt16},   {"int16", Type::kInt16},   {"ushort", Type::kUint16}, {"uint16", Type::kUint16},
      {"int", Type::kInt32},     {"int32", Type::kInt32},   {"uint", Type::kUint32},   {"uint32", Type::kUint32},
      {"float", Type::kFloat32}, {"float32", Type::kFloat32}, {"double", Type::kFloat64}, {"float64", Type::kFloat64},
  };
  for (const Entry& entry : kTypes) {
    if (entry.name == name) {
      type = entry.type;
      return true;
    }
  }
  return false;
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_space(line[i])) ++i;
    const std::size_t start = i;
    while (i < line.size() && !is_space(line[i])) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

}  // namespace

std::string printable(std::string_view text) {
  std::string out;
  for (const char c : text.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  if (text.size() > 40) out += "...";
  return out;
}

std::string plural(const Element& element) {
  if (element.name == "vertex") return "vertices";
  if (element.name == "face") return "faces";
  return fmt::format("'{}' elements", element.name);
}

Header parse_header(std::string_view bytes, const std::string& source) {
  // Checked before looking for a newline, so a large non-PLY file is rejected at once.
  if (bytes.size() < 3 || bytes.substr(0, 3) != "ply") {
    throw_error(ErrorCode::kFormat, "{}: not a PLY file (bad magic: it does not start with 'ply')", source);
  }
  Header header;
  bool have_format = false;
  std::set<std::string_view> element_names;
  std::set<std::string_view> property_names;  // of the current element
  std::size_t position = 0;
  for (int line_number = 1;; ++line_number) {
    if (position >= bytes.size()) {
      throw_error(ErrorCode::kFormat, "{}: truncated header: the file ends before 'end_header' (line {})", source,
                  line_number);
    }
    const std::size_t newline = bytes.find('\n', position);
    const std::size_t line_end = newline == std::string_view::npos ? bytes.size() : newline;
    const std::string_view line = bytes.substr(position, line_end - position);
    position = newline == std::string_view::npos ? bytes.size() : newline + 1;
    const std::vector<std::string_view> tokens = split(line);

    auto fail = [&](const std::string& problem) {
      throw_error(ErrorCode::kFormat, "{}: header line {}: {}", source, line_number, problem);
    };
    if (line_number == 1) {
      if (tokens.size() != 1 || tokens[0] != "ply") {
        throw_error(ErrorCode::kFormat, "{}: not a PLY file (bad magic: the first line is not 'ply')", source);
      }
      continue;
    }
    // The last line of a cut header has no newline (and cannot be a whole end_header line).
    if (newline == std::string_view::npos && (tokens.size() != 1 || tokens[0] != "end_header")) {
      throw_error(ErrorCode::kFormat, "{}: truncated header: the file ends before 'end_header' (line {})", source,
                  line_number);
    }
    if (tokens.empty()) continue;
    const std::string_view keyword = tokens[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "end_header") break;
    if (keyword == "format") {
      if (have_format) fail("more than one format line");
      if (tokens.size() != 3) fail("expected 'format <type> 1.0'");
      if (tokens[1] == "ascii") {
        header.format = Format::kAscii;
      } else if (tokens[1] == "binary_little_endian") {
        header.format = Format::kBinaryLittleEndian;
      } else if (tokens[1] == "binary_big_endian") {
        header.format = Format::kBinaryBigEndian;
      } else {
        fail(fmt::format("unknown format '{}'", printable(tokens[1])));
      }
      if (tokens[2] != "1.0" && tokens[2] != "1") {
        throw_error(ErrorCode::kVersionMismatch, "{}: unsupported PLY version '{}' (only 1.0 is known)", source,
                    printable(tokens[2]));
      }
      have_format = true;
    } else if (keyword == "element") {
      if (tokens.size() != 3) fail("expected 'element <name> <count>'");
      Element element;
      element.name = std::string(tokens[1]);
      const std::string_view count = tokens[2];
      const auto [end, error] = std::from_chars(count.data(), count.data() + count.size(), element.count);
      if (error != std::errc() || end != count.data() + count.size()) {
        fail(fmt::format("bad count '{}' for element '{}'", printable(count), printable(element.name)));
      }
      if ((element.name == "vertex" || element.name == "face") && element_names.count(tokens[1]) != 0) {
        fail(fmt::format("more than one '{}' element", element.name));
      }
      element_names.insert(tokens[1]);
      property_names.clear();
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) fail("property before any element");
      Element& element = header.elements.back();
      Property property;
      if (tokens.size() == 3) {
        if (!parse_type(tokens[1], property.type)) fail(fmt::format("unknown type '{}'", printable(tokens[1])));
        property.name = std::string(tokens[2]);
      } else if (tokens.size() == 5 && tokens[1] == "list") {
        property.is_list = true;
        if (!parse_type(tokens[2], property.count_type) || !is_integer(property.count_type)) {
          fail(fmt::format("bad list count type '{}'", printable(tokens[2])));
        }
        if (!parse_type(tokens[3], property.type)) fail(fmt::format("unknown type '{}'", printable(tokens[3])));
        property.name = std::string(tokens[4]);
      } else {
        fail("expected 'property <type> <name>' or 'property list <count type> <item type> <name>'");
      }
      if (!property_names.insert(tokens.back()).second) {
        fail(fmt::format("property '{}' appears twice in element '{}'", printable(property.name), element.name));
      }
      property.offset = element.record_bytes;
      element.record_bytes += type_size(property.is_list ? property.count_type : property.type);
      element.fixed_size = element.fixed_size && !property.is_list;
      element.properties.push_back(std::move(property));
    } else {
      fail(fmt::format("unknown keyword '{}'", printable(keyword)));
    }
  }
  if (!have_format) throw_error(ErrorCode::kFormat, "{}: the header has no format line", source);
  header.data_offset = position;
  return header;
}

}  // namespace sls::ply_detail
