// libFuzzer target: PLY files (ASCII and binary, any elements), read as a cloud and as a mesh.
// Whatever is accepted has finite positions and valid faces, and survives a write/read round
// trip unchanged.
#include <cstring>
#include <string>
#include <string_view>

#include "sdk/core/error.h"
#include "sdk/core/ply.h"
#include "tests/fuzz/fuzz_support.h"

using sls::fuzz::check;

namespace {

// Bitwise, so that NaN normals compare equal.
bool same_floats(const void* a, const void* b, std::size_t count) {
  return count == 0 || std::memcmp(a, b, count * sizeof(float)) == 0;
}

bool same_cloud(const sls::PointCloud& a, const sls::PointCloud& b) {
  if (a.size() != b.size() || a.normals.size() != b.normals.size() || a.colors != b.colors ||
      a.properties.size() != b.properties.size()) {
    return false;
  }
  if (!same_floats(a.positions.data(), b.positions.data(), 3 * a.size())) return false;
  if (!a.normals.empty() && !same_floats(a.normals.data(), b.normals.data(), 3 * a.size())) return false;
  if (a.confidence.size() != b.confidence.size() ||
      !same_floats(a.confidence.data(), b.confidence.data(), a.confidence.size())) {
    return false;
  }
  for (std::size_t k = 0; k < a.properties.size(); ++k) {
    if (a.properties[k].name != b.properties[k].name ||
        !same_floats(a.properties[k].values.data(), b.properties[k].values.data(), a.size())) {
      return false;
    }
  }
  return true;
}

void read_mesh(std::string_view bytes) {
  sls::TriangleMesh mesh;
  try {
    mesh = sls::decode_ply_mesh(bytes, "fuzz.ply");
  } catch (const sls::Error&) {
    return;
  }
  for (const Eigen::Vector3f& p : mesh.vertices.positions) check(p.allFinite());
  mesh.validate();  // faces in range: throws sls::Error, which escapes here and is reported
  std::string written;
  try {
    written = sls::encode_ply(mesh);
  } catch (const sls::Error&) {
    return;  // a property name the writer reserves or refuses ("nx" without "ny")
  }
  const sls::TriangleMesh again = sls::decode_ply_mesh(written, "again.ply");
  check(same_cloud(mesh.vertices, again.vertices));
  check(mesh.faces == again.faces);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  read_mesh(bytes);
  try {
    const sls::PointCloud cloud = sls::decode_ply_cloud(bytes, "fuzz.ply");
    for (const Eigen::Vector3f& p : cloud.positions) check(p.allFinite());
  } catch (const sls::Error&) {
  }
  return 0;
}
