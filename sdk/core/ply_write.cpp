// PLY writing (the format: ply.h): binary little-endian, written atomically.
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <set>

#include <fmt/format.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/ply.h"
#include "sdk/core/ply_format.h"

namespace sls {
namespace {

using namespace ply_detail;
using Faces = std::vector<std::array<std::int32_t, 3>>;

// ---------------------------------------------------------------------------------------------
// Writing

void check_property_names(const PointCloud& cloud) {
  static constexpr std::string_view kReserved[] = {"x",   "y",     "z",    "nx",        "ny",
                                                   "nz",  "red",   "green", "blue",     "confidence"};
  std::set<std::string_view> names;
  for (const PointProperty& property : cloud.properties) {
    for (const char c : property.name) {
      if (c <= 0x20 || c >= 0x7f) {
        throw_error(ErrorCode::kInvalidArgument, "point property name '{}' is not printable ASCII without spaces",
                    printable(property.name));
      }
    }
    if (std::find(std::begin(kReserved), std::end(kReserved), property.name) != std::end(kReserved)) {
      throw_error(ErrorCode::kInvalidArgument, "point property name '{}' is reserved for a PLY standard property",
                  property.name);
    }
    if (!names.insert(property.name).second) {
      throw_error(ErrorCode::kInvalidArgument, "point property name '{}' appears twice", property.name);
    }
  }
}

std::string encode(const PointCloud& cloud, const Faces* faces) {
  cloud.validate();
  check_property_names(cloud);
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment written by slscan\n";
  header += fmt::format("element vertex {}\nproperty float x\nproperty float y\nproperty float z\n", cloud.size());
  std::size_t record_bytes = 3 * sizeof(float);
  if (cloud.has_normals()) {
    header += "property float nx\nproperty float ny\nproperty float nz\n";
    record_bytes += 3 * sizeof(float);
  }
  if (cloud.has_confidence()) {
    header += "property float confidence\n";
    record_bytes += sizeof(float);
  }
  if (cloud.has_colors()) {
    header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    record_bytes += 3;
  }
  for (const PointProperty& property : cloud.properties) {
    header += fmt::format("property float {}\n", property.name);
    record_bytes += sizeof(float);
  }
  constexpr std::size_t kFaceBytes = 1 + 3 * sizeof(std::int32_t);
  if (faces != nullptr) {
    header += fmt::format("element face {}\nproperty list uchar int vertex_indices\n", faces->size());
  }
  header += "end_header\n";

  const std::size_t n = cloud.size();
  std::string out(header.size() + n * record_bytes + (faces != nullptr ? faces->size() * kFaceBytes : 0), '\0');
  std::memcpy(out.data(), header.data(), header.size());
  char* p = out.data() + header.size();
  for (std::size_t i = 0; i < n; ++i) {
    for (Eigen::Index k = 0; k < 3; ++k) store(p, cloud.positions[i][k]);
    if (cloud.has_normals()) {
      for (Eigen::Index k = 0; k < 3; ++k) store(p, cloud.normals[i][k]);
    }
    if (cloud.has_confidence()) store(p, cloud.confidence[i]);
    if (cloud.has_colors()) {
      for (const std::uint8_t c : cloud.colors[i]) store(p, c);
    }
    for (const PointProperty& property : cloud.properties) store(p, property.values[i]);
  }
  if (faces != nullptr) {
    for (const std::array<std::int32_t, 3>& face : *faces) {
      store(p, std::uint8_t{3});
      for (const std::int32_t index : face) store(p, index);
    }
  }
  return out;
}

}  // namespace

std::string encode_ply(const PointCloud& cloud) { return encode(cloud, nullptr); }

std::string encode_ply(const TriangleMesh& mesh) {
  mesh.validate();
  return encode(mesh.vertices, &mesh.faces);
}

void write_ply(const std::string& path, const PointCloud& cloud) {
  std::string bytes;
  try {
    bytes = encode_ply(cloud);
  } catch (const Error& error) {
    throw Error(error.code(), path + ": " + error.what());
  }
  write_file_atomic(path, bytes);
}

void write_ply(const std::string& path, const TriangleMesh& mesh) {
  std::string bytes;
  try {
    bytes = encode_ply(mesh);
  } catch (const Error& error) {
    throw Error(error.code(), path + ": " + error.what());
  }
  write_file_atomic(path, bytes);
}

}  // namespace sls
