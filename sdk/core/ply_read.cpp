// PLY reading (the format: ply.h): the data section of ASCII and binary files, from memory
// or from a file.
#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <new>
#include <type_traits>
#include <vector>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/ply.h"
#include "sdk/core/ply_format.h"

namespace sls {
namespace {

using namespace ply_detail;

// Integer colors are clamped to [0, 255]; floating-point colors are taken as [0, 1], the
// convention of the writers that use them.
template <typename T>
std::uint8_t to_color(T value) {
  if constexpr (std::is_floating_point_v<T>) {
    const double scaled = static_cast<double>(value) * 255.0;
    if (!(scaled > 0.0)) return 0;  // also NaN
    if (scaled >= 255.0) return 255;
    return static_cast<std::uint8_t>(std::lround(scaled));
  } else {
    return static_cast<std::uint8_t>(std::clamp<std::int64_t>(static_cast<std::int64_t>(value), 0, 255));
  }
}

std::uint8_t to_color(double value, Type declared) {
  if (is_integer(declared)) {
    if (!(value > 0.0)) return 0;
    if (value >= 255.0) return 255;
    return static_cast<std::uint8_t>(std::lround(value));
  }
  return to_color(value);
}

// ---------------------------------------------------------------------------------------------
// Vertex data: where each vertex property goes

struct Column {
  enum class Kind { kPosition, kNormal, kColor, kConfidence, kProperty };
  std::size_t property = 0;  // index in the element
  Type type = Type::kFloat32;
  std::size_t offset = 0;    // in a fixed-size binary record
  Kind kind = Kind::kProperty;
  int component = 0;         // x/y/z or r/g/b
  std::size_t slot = 0;      // index in PointCloud::properties
};

// Decides the columns and sizes the cloud's arrays for `count` points.
std::vector<Column> plan_vertices(const Element& element, std::size_t count, const std::string& source,
                                  PointCloud& cloud) {
  auto scalar = [&](std::string_view name) -> const Property* {
    const Property* property = element.find(name);
    return property != nullptr && !property->is_list ? property : nullptr;
  };
  std::vector<Column> columns;
  std::vector<bool> used(element.properties.size(), false);
  auto add = [&](const Property* property, Column::Kind kind, int component, std::size_t slot) {
    Column column;
    column.property = element.index_of(property);
    column.type = property->type;
    column.offset = property->offset;
    column.kind = kind;
    column.component = component;
    column.slot = slot;
    columns.push_back(column);
    used[column.property] = true;
  };
  auto add_triple = [&](const char* const (&names)[3], Column::Kind kind) {
    const Property* properties[3] = {scalar(names[0]), scalar(names[1]), scalar(names[2])};
    if (properties[0] == nullptr || properties[1] == nullptr || properties[2] == nullptr) return false;
    for (int k = 0; k < 3; ++k) add(properties[k], kind, k, 0);
    return true;
  };

  static constexpr const char* kPosition[3] = {"x", "y", "z"};
  static constexpr const char* kNormal[3] = {"nx", "ny", "nz"};
  static constexpr const char* kColor[3] = {"red", "green", "blue"};
  for (const char* name : kPosition) {
    if (scalar(name) == nullptr) {
      throw_error(ErrorCode::kFormat, "{}: the vertex element has no scalar property '{}'", source, name);
    }
  }
  add_triple(kPosition, Column::Kind::kPosition);
  cloud.positions.resize(count);
  if (add_triple(kNormal, Column::Kind::kNormal)) cloud.normals.resize(count);
  if (add_triple(kColor, Column::Kind::kColor)) cloud.colors.resize(count);
  if (const Property* confidence = scalar("confidence")) {
    add(confidence, Column::Kind::kConfidence, 0, 0);
    cloud.confidence.resize(count);
  }
  for (const Property& property : element.properties) {
    if (property.is_list || used[element.index_of(&property)]) continue;
    add(&property, Column::Kind::kProperty, 0, cloud.properties.size());
    cloud.properties.push_back(PointProperty{property.name, std::vector<float>(count)});
  }
  return columns;
}

// One column of a block of fixed-size records, with the type and byte order fixed at compile
// time so the loop is a load and a store per value.
template <typename T, bool Swap, typename Sink>
void extract(const char* block, std::size_t count, std::size_t record_bytes, std::size_t offset, Sink sink) {
  const char* p = block + offset;
  for (std::size_t i = 0; i < count; ++i, p += record_bytes) sink(i, load<T, Swap>(p));
}

template <bool Swap>
void extract_column(const Column& column, const char* block, std::size_t first, std::size_t count,
                    std::size_t record_bytes, PointCloud& cloud) {
  visit_type(column.type, [&](auto tag) {
    using T = decltype(tag);
    const int k = column.component;
    switch (column.kind) {
      case Column::Kind::kPosition:
      case Column::Kind::kNormal: {
        Eigen::Vector3f* out =
            (column.kind == Column::Kind::kPosition ? cloud.positions.data() : cloud.normals.data()) + first;
        extract<T, Swap>(block, count, record_bytes, column.offset,
                         [out, k](std::size_t i, T value) { out[i][k] = static_cast<float>(value); });
        break;
      }
      case Column::Kind::kColor: {
        std::array<std::uint8_t, 3>* out = cloud.colors.data() + first;
        const auto component = static_cast<std::size_t>(k);
        extract<T, Swap>(block, count, record_bytes, column.offset,
                         [out, component](std::size_t i, T value) { out[i][component] = to_color(value); });
        break;
      }
      case Column::Kind::kConfidence:
      case Column::Kind::kProperty: {
        float* out = (column.kind == Column::Kind::kConfidence ? cloud.confidence.data()
                                                               : cloud.properties[column.slot].values.data()) +
                     first;
        extract<T, Swap>(block, count, record_bytes, column.offset,
                         [out](std::size_t i, T value) { out[i] = static_cast<float>(value); });
        break;
      }
    }
  });
}

// Slow path (ASCII, or binary vertices with list properties): one value at a time.
void store_value(const Column& column, std::size_t i, double value, PointCloud& cloud) {
  const auto k = static_cast<Eigen::Index>(column.component);
  switch (column.kind) {
    case Column::Kind::kPosition: cloud.positions[i][k] = static_cast<float>(value); break;
    case Column::Kind::kNormal: cloud.normals[i][k] = static_cast<float>(value); break;
    case Column::Kind::kColor:
      cloud.colors[i][static_cast<std::size_t>(column.component)] = to_color(value, column.type);
      break;
    case Column::Kind::kConfidence: cloud.confidence[i] = static_cast<float>(value); break;
    case Column::Kind::kProperty: cloud.properties[column.slot].values[i] = static_cast<float>(value); break;
  }
}

// ---------------------------------------------------------------------------------------------
// Data section

using Faces = std::vector<std::array<std::int32_t, 3>>;

class Parser {
 public:
  Parser(std::string_view bytes, const Header& header, const std::string& source)
      : bytes_(bytes),
        position_(header.data_offset),
        ascii_(header.format == Format::kAscii),
        swap_((header.format == Format::kBinaryBigEndian) != kHostBigEndian),
        source_(source) {}

  void skip(const Element& element) {
    if (element.properties.empty() || element.count == 0) return;
    if (!ascii_ && element.fixed_size) {
      check_fixed_size(element);
      position_ += static_cast<std::size_t>(element.count) * element.record_bytes;
      return;
    }
    // Record by record; a corrupt count stops at the end of the data.
    for (std::uint64_t i = 0; i < element.count; ++i) {
      for (const Property& property : element.properties) skip_value(element, property, i);
    }
  }

  void read_vertices(const Element& element, PointCloud& cloud) {
    check_count(element);
    const auto count = static_cast<std::size_t>(element.count);
    const std::vector<Column> columns = plan_vertices(element, count, source_, cloud);
    if (!ascii_ && element.fixed_size) {
      // Bulk path: blocks of records small enough to stay in cache while every column is
      // copied out of them.
      constexpr std::size_t kBlock = 4096;
      const char* data = bytes_.data() + position_;
      for (std::size_t first = 0; first < count; first += kBlock) {
        const std::size_t n = std::min(kBlock, count - first);
        const char* block = data + first * element.record_bytes;
        for (const Column& column : columns) {
          if (swap_) {
            extract_column<true>(column, block, first, n, element.record_bytes, cloud);
          } else {
            extract_column<false>(column, block, first, n, element.record_bytes, cloud);
          }
        }
      }
      position_ += count * element.record_bytes;
      return;
    }
    std::vector<const Column*> column_of(element.properties.size(), nullptr);
    for (const Column& column : columns) column_of[column.property] = &column;
    for (std::size_t i = 0; i < count; ++i) {
      for (std::size_t p = 0; p < element.properties.size(); ++p) {
        const Property& property = element.properties[p];
        if (column_of[p] == nullptr) {
          skip_value(element, property, i);
          continue;
        }
        double value;
        if (ascii_) {
          value = ascii_value(element, property, i);
        } else {
          const std::size_t size = type_size(property.type);
          need(element, size, i);
          value = load_as_double(bytes_.data() + position_, property.type, swap_);
          position_ += size;
        }
        store_value(*column_of[p], i, value, cloud);
      }
    }
  }

  void read_faces(const Element& element, std::uint64_t vertex_count, Faces& faces) {
    const Property* list = element.find("vertex_indices");
    if (list == nullptr) list = element.find("vertex_index");
    if (list == nullptr || !list->is_list) {
      throw_error(ErrorCode::kFormat, "{}: the face element has no 'vertex_indices' list", source_);
    }
    if (!is_integer(list->type)) {
      throw_error(ErrorCode::kFormat, "{}: the face element's '{}' list holds floating-point values", source_,
                  list->name);
    }
    check_count(element);
    faces.reserve(faces.size() + static_cast<std::size_t>(element.count));
    if (!ascii_ && element.properties.size() == 1) {
      // The usual layout: a typed loop per (count type, index type, byte order).
      visit_type(list->count_type, [&](auto count_tag) {
        visit_type(list->type, [&](auto index_tag) {
          using C = decltype(count_tag);
          using I = decltype(index_tag);
          if constexpr (std::is_integral_v<C> && std::is_integral_v<I>) {
            if (swap_) {
              read_faces_fast<C, I, true>(element, vertex_count, faces);
            } else {
              read_faces_fast<C, I, false>(element, vertex_count, faces);
            }
          }
        });
      });
      return;
    }
    const std::size_t list_index = element.index_of(list);
    std::vector<std::int64_t> polygon;
    for (std::uint64_t f = 0; f < element.count; ++f) {
      for (std::size_t p = 0; p < element.properties.size(); ++p) {
        const Property& property = element.properties[p];
        if (p != list_index) {
          skip_value(element, property, f);
          continue;
        }
        polygon.clear();
        if (ascii_) {
          const std::int64_t n = ascii_count(element, property, f);
          for (std::int64_t j = 0; j < n; ++j) polygon.push_back(ascii_integer(element, property, f));
        } else {
          const std::size_t n = binary_count(element, property, f);
          const std::size_t size = type_size(property.type);
          need(element, n * size, f);
          for (std::size_t j = 0; j < n; ++j, position_ += size) {
            polygon.push_back(load_as_integer(bytes_.data() + position_, property.type, swap_));
          }
        }
        add_polygon(polygon.data(), polygon.size(), f, vertex_count, faces);
      }
    }
  }

 private:
  std::size_t remaining() const { return bytes_.size() - position_; }

  [[noreturn]] void truncated(const Element& element, std::uint64_t complete) const {
    throw_error(ErrorCode::kFormat, "{}: truncated data: expected {} {}, the file ends after {}", source_,
                element.count, plural(element), complete);
  }

  // Before anything is allocated for `count` records: the bytes left must be able to hold
  // them, so a corrupt count is an error and never a huge allocation.
  void check_count(const Element& element) const {
    if (!ascii_ && element.fixed_size) {
      check_fixed_size(element);
      return;
    }
    // Binary: a record with every list empty. ASCII: each value is at least one character
    // and a separator.
    const std::size_t per_record =
        ascii_ ? 2 * std::max<std::size_t>(element.properties.size(), 1)
               : std::max<std::size_t>(element.record_bytes, 1);
    const std::size_t available = ascii_ ? remaining() + 1 : remaining();
    if (element.count > available / per_record) {
      throw_error(ErrorCode::kFormat,
                  "{}: truncated data: expected {} {}, but only {} bytes follow the header, too few to hold them",
                  source_, element.count, plural(element), remaining());
    }
  }

  void check_fixed_size(const Element& element) const {
    if (element.record_bytes == 0) return;
    const std::size_t fit = remaining() / element.record_bytes;
    if (element.count > fit) {
      throw_error(ErrorCode::kFormat,
                  "{}: truncated data: expected {} {} of {} bytes, the file ends after {} ({} bytes follow the header)",
                  source_, element.count, plural(element), element.record_bytes, fit, remaining());
    }
  }

  void need(const Element& element, std::size_t bytes, std::uint64_t record) const {
    if (bytes > remaining()) truncated(element, record);
  }

  std::size_t binary_count(const Element& element, const Property& property, std::uint64_t record) {
    const std::size_t size = type_size(property.count_type);
    need(element, size, record);
    const std::int64_t count = load_as_integer(bytes_.data() + position_, property.count_type, swap_);
    position_ += size;
    if (count < 0) {
      throw_error(ErrorCode::kFormat, "{}: {} {} has a negative '{}' count {}", source_, element.name, record,
                  property.name, count);
    }
    return static_cast<std::size_t>(count);
  }

  void skip_value(const Element& element, const Property& property, std::uint64_t record) {
    if (ascii_) {
      const std::int64_t count = property.is_list ? ascii_count(element, property, record) : 1;
      for (std::int64_t j = 0; j < count; ++j) next_token(element, record);
      return;
    }
    if (!property.is_list) {
      need(element, type_size(property.type), record);
      position_ += type_size(property.type);
      return;
    }
    const std::size_t count = binary_count(element, property, record);
    const std::size_t size = type_size(property.type);
    if (count > remaining() / size) truncated(element, record);
    position_ += count * size;
  }

  std::string_view next_token(const Element& element, std::uint64_t record) {
    while (position_ < bytes_.size() && is_space(bytes_[position_])) ++position_;
    if (position_ >= bytes_.size()) truncated(element, record);
    const std::size_t start = position_;
    while (position_ < bytes_.size() && !is_space(bytes_[position_])) ++position_;
    return bytes_.substr(start, position_ - start);
  }

  [[noreturn]] void bad_value(const Element& element, const Property& property, std::uint64_t record,
                              std::string_view token) const {
    throw_error(ErrorCode::kFormat, "{}: bad value '{}' for property '{}' of {} {}", source_, printable(token),
                property.name, element.name, record);
  }

  double ascii_value(const Element& element, const Property& property, std::uint64_t record) {
    std::string_view token = next_token(element, record);
    if (token.size() > 1 && token[0] == '+') token.remove_prefix(1);  // from_chars takes no '+'
    const char* end = token.data() + token.size();
    // float32 values are parsed as float so that printed floats come back bit-exact.
    if (property.type == Type::kFloat32) {
      float value = 0.0f;
      const auto result = std::from_chars(token.data(), end, value);
      if (result.ec != std::errc() || result.ptr != end) bad_value(element, property, record, token);
      return static_cast<double>(value);
    }
    double value = 0.0;
    const auto result = std::from_chars(token.data(), end, value);
    if (result.ec != std::errc() || result.ptr != end) bad_value(element, property, record, token);
    return value;
  }

  std::int64_t ascii_integer(const Element& element, const Property& property, std::uint64_t record) {
    std::string_view token = next_token(element, record);
    if (token.size() > 1 && token[0] == '+') token.remove_prefix(1);
    std::int64_t value = 0;
    const char* end = token.data() + token.size();
    const auto result = std::from_chars(token.data(), end, value);
    if (result.ec != std::errc() || result.ptr != end) bad_value(element, property, record, token);
    return value;
  }

  std::int64_t ascii_count(const Element& element, const Property& property, std::uint64_t record) {
    const std::int64_t count = ascii_integer(element, property, record);
    if (count < 0) {
      throw_error(ErrorCode::kFormat, "{}: {} {} has a negative '{}' count {}", source_, element.name, record,
                  property.name, count);
    }
    return count;
  }

  std::int32_t checked_index(std::int64_t index, std::uint64_t face, std::uint64_t vertex_count) const {
    if (index < 0 || static_cast<std::uint64_t>(index) >= vertex_count ||
        index > std::numeric_limits<std::int32_t>::max()) {
      throw_error(ErrorCode::kFormat, "{}: face {} refers to vertex {} but the file has {} vertices", source_, face,
                  index, vertex_count);
    }
    return static_cast<std::int32_t>(index);
  }

  // Polygons become triangle fans around their first vertex; fewer than 3 vertices: dropped.
  void add_polygon(const std::int64_t* indices, std::size_t n, std::uint64_t face, std::uint64_t vertex_count,
                   Faces& faces) const {
    for (std::size_t j = 0; j < n; ++j) checked_index(indices[j], face, vertex_count);
    for (std::size_t j = 2; j < n; ++j) {
      faces.push_back({static_cast<std::int32_t>(indices[0]), static_cast<std::int32_t>(indices[j - 1]),
                       static_cast<std::int32_t>(indices[j])});
    }
  }

  template <typename C, typename I, bool Swap>
  void read_faces_fast(const Element& element, std::uint64_t vertex_count, Faces& faces) {
    const char* data = bytes_.data();
    std::size_t position = position_;
    const std::size_t size = bytes_.size();
    for (std::uint64_t f = 0; f < element.count; ++f) {
      if (size - position < sizeof(C)) truncated(element, f);
      const C count = load<C, Swap>(data + position);
      position += sizeof(C);
      if constexpr (std::is_signed_v<C>) {
        if (count < 0) {
          throw_error(ErrorCode::kFormat, "{}: face {} has a negative vertex count {}", source_, f,
                      static_cast<std::int64_t>(count));
        }
      }
      const auto n = static_cast<std::size_t>(count);
      if (n > (size - position) / sizeof(I)) truncated(element, f);
      const char* p = data + position;
      position += n * sizeof(I);
      if (n < 3) {
        for (std::size_t j = 0; j < n; ++j) {
          checked_index(static_cast<std::int64_t>(load<I, Swap>(p + j * sizeof(I))), f, vertex_count);
        }
        continue;
      }
      const std::int32_t first = checked_index(static_cast<std::int64_t>(load<I, Swap>(p)), f, vertex_count);
      std::int32_t previous =
          checked_index(static_cast<std::int64_t>(load<I, Swap>(p + sizeof(I))), f, vertex_count);
      for (std::size_t j = 2; j < n; ++j) {
        const std::int32_t current =
            checked_index(static_cast<std::int64_t>(load<I, Swap>(p + j * sizeof(I))), f, vertex_count);
        faces.push_back({first, previous, current});
        previous = current;
      }
    }
    position_ = position;
  }

  std::string_view bytes_;
  std::size_t position_;
  bool ascii_;
  bool swap_;
  const std::string& source_;
};

// A NaN or infinite position is no point: every consumer (bounds, distances, fusion) would
// turn it into garbage, so the file is refused. Other properties, normals included, may
// hold NaN by convention (e.g. "no value") and are left alone.
void check_positions_finite(const PointCloud& cloud, const std::string& source) {
  for (std::size_t i = 0; i < cloud.positions.size(); ++i) {
    const Eigen::Vector3f& p = cloud.positions[i];
    if (!p.allFinite()) {
      throw_error(ErrorCode::kFormat, "{}: vertex {} (counting from 0) has a non-finite position ({}, {}, {})",
                  source, i, p.x(), p.y(), p.z());
    }
  }
}

void decode(std::string_view bytes, const std::string& source, PointCloud& cloud, Faces* faces) {
  const Header header = parse_header(bytes, source);
  const Element* vertex = nullptr;
  bool has_face = false;
  for (const Element& element : header.elements) {
    if (element.name == "vertex") vertex = &element;
    if (element.name == "face") has_face = true;
  }
  if (vertex == nullptr) throw_error(ErrorCode::kFormat, "{}: the file has no vertex element", source);

  Parser parser(bytes, header, source);
  bool vertices_done = false;
  bool faces_done = faces == nullptr || !has_face;
  try {
    for (const Element& element : header.elements) {
      if (vertices_done && faces_done) break;  // what follows is not needed
      if (&element == vertex) {
        parser.read_vertices(element, cloud);
        check_positions_finite(cloud, source);
        vertices_done = true;
      } else if (faces != nullptr && element.name == "face") {
        parser.read_faces(element, vertex->count, *faces);
        faces_done = true;
      } else {
        parser.skip(element);
      }
    }
  } catch (const std::bad_alloc&) {
    throw_error(ErrorCode::kOutOfMemory, "{}: out of memory reading {} vertices", source, vertex->count);
  }
}

// ---------------------------------------------------------------------------------------------
// Reading files: mapped, not copied, since clouds reach gigabytes; decoding then touches only
// the elements the header announces. (A file truncated by someone else while it is mapped
// would fault; our writers replace files by rename instead.)

// A bound on a PLY file, far above any cloud this SDK makes or reads (hundreds of millions of
// points), so that a sparse or absurd file is refused before anything is mapped or read.
constexpr std::uint64_t kMaxPlyFileBytes = std::uint64_t{64} << 30;

class FileBytes {
 public:
  explicit FileBytes(const std::string& path) {
    const RegularFile file(path);  // refuses FIFOs, devices, directories without blocking
    file.check_size(kMaxPlyFileBytes);
    if (file.size() > 0) {
      const auto size = static_cast<std::size_t>(file.size());
      void* map = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, file.fd(), 0);
      if (map != MAP_FAILED) {
        (void)::madvise(map, size, MADV_SEQUENTIAL);  // a hint only
        map_ = map;
        size_ = size;
        return;
      }
    }
    // Empty files, filesystems that cannot map: read it all.
    buffer_ = file.read_all(kMaxPlyFileBytes);
  }
  ~FileBytes() {
    if (map_ != nullptr) ::munmap(map_, size_);
  }
  FileBytes(const FileBytes&) = delete;
  FileBytes& operator=(const FileBytes&) = delete;

  std::string_view view() const {
    return map_ != nullptr ? std::string_view(static_cast<const char*>(map_), size_)
                           : std::string_view(reinterpret_cast<const char*>(buffer_.data()), buffer_.size());
  }

 private:
  void* map_ = nullptr;
  std::size_t size_ = 0;
  std::vector<std::uint8_t> buffer_;
};

}  // namespace

PointCloud decode_ply_cloud(std::string_view bytes, const std::string& source) {
  PointCloud cloud;
  decode(bytes, source, cloud, nullptr);
  return cloud;
}

TriangleMesh decode_ply_mesh(std::string_view bytes, const std::string& source) {
  TriangleMesh mesh;
  decode(bytes, source, mesh.vertices, &mesh.faces);
  return mesh;
}

PointCloud read_ply_cloud(const std::string& path) {
  const FileBytes file(path);
  return decode_ply_cloud(file.view(), path);
}

TriangleMesh read_ply_mesh(const std::string& path) {
  const FileBytes file(path);
  return decode_ply_mesh(file.view(), path);
}

}  // namespace sls
