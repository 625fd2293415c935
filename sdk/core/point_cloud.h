// Point clouds with normals, confidence and extra per-point properties, and triangle meshes:
// what fusion extracts and what PLY files hold. Structure of arrays: every non-empty
// per-point array has the same length as `positions`.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace sls {

// A named float property per point (e.g. "weight", "frame"), written to PLY as a float.
struct PointProperty {
  std::string name;
  std::vector<float> values;
};

struct PointCloud {
  std::vector<Eigen::Vector3f> positions;        // metres, like every length in the SDK
  std::vector<Eigen::Vector3f> normals;          // unit length, or empty
  std::vector<float> confidence;                 // in [0, 1], or empty
  std::vector<std::array<std::uint8_t, 3>> colors;  // RGB, or empty
  std::vector<PointProperty> properties;         // further per-point floats

  std::size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool has_normals() const { return !normals.empty(); }
  bool has_confidence() const { return !confidence.empty(); }
  bool has_colors() const { return !colors.empty(); }
  // Returns the property with that name, or nullptr.
  const PointProperty* find_property(const std::string& name) const;
  // Throws sls::Error (invalid argument) if a per-point array's length differs from size().
  void validate() const;
};

// The points of `cloud` at `indices` (in that order), with every per-point array and property.
PointCloud select_points(const PointCloud& cloud, const std::vector<std::size_t>& indices);

struct TriangleMesh {
  PointCloud vertices;
  std::vector<std::array<std::int32_t, 3>> faces;  // indices into vertices, counter-clockwise seen from outside

  // Throws sls::Error if the vertex arrays are inconsistent or a face index is out of range.
  void validate() const;
};

// a's points then b's: every per-point array, and each of a's properties followed by b's of that
// name (an empty a takes b's layout). Sized once, its pages mapped and its values copied on all
// threads (a scan's model joins ~18 M points at the paper's size: resize_populated). With
// copy_geometry false, positions and normals are sized but left unwritten, for a caller that
// writes them in its own pass (the scan's deformed model).
// Throws sls::Error(kInvalidArgument) when b lacks one of a's properties.
PointCloud join_clouds(const PointCloud& a, const PointCloud& b, bool copy_geometry = true);
// a's vertices and triangles then b's, b's vertex indices moved past a's vertices.
TriangleMesh join_meshes(const TriangleMesh& a, const TriangleMesh& b, bool copy_geometry = true);

}  // namespace sls
