#include "sdk/core/point_cloud.h"

#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"

namespace sls {

const PointProperty* PointCloud::find_property(const std::string& name) const {
  for (const PointProperty& property : properties) {
    if (property.name == name) return &property;
  }
  return nullptr;
}

void PointCloud::validate() const {
  const std::size_t n = positions.size();
  auto check = [n](std::size_t count, const char* what) {
    if (count != 0 && count != n) {
      throw_error(ErrorCode::kInvalidArgument, "point cloud has {} points but {} {}", n, count, what);
    }
  };
  check(normals.size(), "normals");
  check(confidence.size(), "confidence values");
  check(colors.size(), "colors");
  for (const PointProperty& property : properties) {
    if (property.name.empty()) throw_error(ErrorCode::kInvalidArgument, "point property with an empty name");
    if (property.values.size() != n) {
      throw_error(ErrorCode::kInvalidArgument, "point cloud has {} points but property '{}' has {} values", n,
                  property.name, property.values.size());
    }
  }
}

namespace {

// a's values then b's in one array sized once, its pages mapped on all threads; copied on all
// threads unless `copy` is false.
template <typename T>
std::vector<T> joined(const std::vector<T>& a, const std::vector<T>& b, bool copy = true) {
  std::vector<T> out;
  resize_populated(&out, a.size() + b.size());
  if (copy && !a.empty()) copy_bytes_parallel(out.data(), a.data(), a.size() * sizeof(T));
  if (copy && !b.empty()) copy_bytes_parallel(out.data() + a.size(), b.data(), b.size() * sizeof(T));
  return out;
}

}  // namespace

PointCloud join_clouds(const PointCloud& a, const PointCloud& b, bool copy_geometry) {
  PointCloud out;
  out.positions = joined(a.positions, b.positions, copy_geometry);
  out.normals = joined(a.normals, b.normals, copy_geometry);
  out.confidence = joined(a.confidence, b.confidence);
  out.colors = joined(a.colors, b.colors);
  for (const PointProperty& property : a.empty() ? b.properties : a.properties) {
    const PointProperty* first = a.empty() ? nullptr : &property;
    const PointProperty* second = a.empty() ? &property : b.find_property(property.name);
    if (second == nullptr && !b.empty()) {
      throw_error(ErrorCode::kInvalidArgument, "joining point clouds: the second lacks the property '{}'",
                  property.name);
    }
    static const std::vector<float> none;
    out.properties.push_back(
        {property.name, joined(first != nullptr ? first->values : none, second != nullptr ? second->values : none)});
  }
  return out;
}

TriangleMesh join_meshes(const TriangleMesh& a, const TriangleMesh& b, bool copy_geometry) {
  TriangleMesh out;
  out.vertices = join_clouds(a.vertices, b.vertices, copy_geometry);
  out.faces = joined(a.faces, b.faces);
  const auto offset = static_cast<std::int32_t>(a.vertices.size());
  std::array<std::int32_t, 3>* const moved = out.faces.data() + a.faces.size();
  const auto count = static_cast<std::ptrdiff_t>(b.faces.size());
#if defined(_OPENMP)
#pragma omp parallel for schedule(static) if (count > 65536)
#endif
  for (std::ptrdiff_t i = 0; i < count; ++i) {
    for (std::int32_t& index : moved[i]) index += offset;
  }
  return out;
}

PointCloud select_points(const PointCloud& cloud, const std::vector<std::size_t>& indices) {
  PointCloud out;
  const auto pick = [&indices](const auto& from, auto* to) {
    if (from.empty()) return;
    to->reserve(indices.size());
    for (const std::size_t i : indices) to->push_back(from[i]);
  };
  pick(cloud.positions, &out.positions);
  pick(cloud.normals, &out.normals);
  pick(cloud.confidence, &out.confidence);
  pick(cloud.colors, &out.colors);
  for (const PointProperty& property : cloud.properties) {
    out.properties.push_back({property.name, {}});
    pick(property.values, &out.properties.back().values);
  }
  return out;
}

void TriangleMesh::validate() const {
  vertices.validate();
  const auto vertex_count = static_cast<std::int64_t>(vertices.size());
  for (std::size_t f = 0; f < faces.size(); ++f) {
    for (const std::int32_t index : faces[f]) {
      if (index < 0 || index >= vertex_count) {
        throw_error(ErrorCode::kInvalidArgument, "face {} refers to vertex {} of {}", f, index, vertex_count);
      }
    }
  }
}

}  // namespace sls
