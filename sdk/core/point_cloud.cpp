#include "sdk/core/point_cloud.h"

#include "sdk/core/error.h"

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
