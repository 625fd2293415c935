#include "fusion/deformation/map_deformation.h"

#include <algorithm>
#include <cstring>

#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"

namespace sls::fusion::deformation {

void deform_cloud_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                       PointCloud* cloud, std::size_t begin, std::size_t end, std::vector<float>* displacement_m) {
  deform_cloud_part(graph, transforms, time, *cloud, begin, end, cloud, begin, displacement_m);
}

namespace {

bool same_bits(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::memcmp(a.data(), b.data(), 3 * sizeof(float)) == 0;
}

// deform_cloud_part's and deform_vertices_part's checks and loop; same_point == nullptr: every
// point deformed.
void deform_range(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                  const PointCloud& from, std::size_t begin, std::size_t end, PointCloud* to, std::size_t to_begin,
                  std::vector<float>* displacement_m, const std::int64_t* same_point, const PointCloud* deformed) {
  if (end > from.size() || begin > end) {
    throw_error(ErrorCode::kInvalidArgument, "map deformation: points [{}, {}) of a cloud of {}", begin, end,
                from.size());
  }
  const bool normals = from.has_normals();
  if (to_begin > to->size() || end - begin > to->size() - to_begin ||
      (normals && to->normals.size() != to->positions.size())) {
    throw_error(ErrorCode::kInvalidArgument, "map deformation: {} points into [{}, ...) of a cloud of {}{}",
                end - begin, to_begin, to->size(), normals && !to->has_normals() ? " without normals" : "");
  }
  if (transforms.size() != graph.size()) {
    throw_error(ErrorCode::kInvalidArgument, "map deformation: {} transforms for a graph of {} nodes",
                transforms.size(), graph.size());
  }
  if (same_point != nullptr && normals && !deformed->has_normals()) {
    throw_error(ErrorCode::kInvalidArgument, "map deformation: vertices with normals share points without them");
  }
  if (displacement_m != nullptr) resize_populated(displacement_m, to->size());  // new values 0
  if (graph.size() == 0 || begin == end) {
    if (&from != to || begin != to_begin) {  // nothing to deform, still to be copied
      std::copy(from.positions.begin() + static_cast<std::ptrdiff_t>(begin),
                from.positions.begin() + static_cast<std::ptrdiff_t>(end),
                to->positions.begin() + static_cast<std::ptrdiff_t>(to_begin));
      if (normals) {
        std::copy(from.normals.begin() + static_cast<std::ptrdiff_t>(begin),
                  from.normals.begin() + static_cast<std::ptrdiff_t>(end),
                  to->normals.begin() + static_cast<std::ptrdiff_t>(to_begin));
      }
    }
    return;
  }
  const int last = graph.node_at_time(time);
  const int first = std::max(0, last - graph.options().temporal_window + 1);
  std::vector<Vec3T<double>> candidates;
  for (int j = first; j <= last; ++j) candidates.push_back(transforms[static_cast<std::size_t>(j)].g);
  const int count = static_cast<int>(candidates.size());
  const int k = graph.options().nearest_nodes;
  const auto n = static_cast<std::ptrdiff_t>(end - begin);
  const auto shared = deformed != nullptr ? static_cast<std::int64_t>(deformed->size()) : 0;
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const std::size_t source = begin + static_cast<std::size_t>(i);
    const std::size_t target = to_begin + static_cast<std::size_t>(i);
    // An index out of range is only a lost share: the vertex is deformed itself.
    const std::int64_t same = same_point != nullptr ? same_point[i] : -1;
    if (same >= 0 && same < shared) {
      to->positions[target] = deformed->positions[static_cast<std::size_t>(same)];
      if (normals) to->normals[target] = deformed->normals[static_cast<std::size_t>(same)];
      continue;
    }
    const Eigen::Vector3f& position = from.positions[source];
    const Vec3T<double> p{position.x(), position.y(), position.z()};
    const NodeBinding binding = bind_nearest(candidates.data(), first, count, k, p);
    const Vec3T<double> moved = deform_point(transforms.data(), binding, p);
    if (displacement_m != nullptr) (*displacement_m)[target] = static_cast<float>(norm(moved - p));
    Eigen::Vector3f normal_out;
    if (normals) {
      const Eigen::Vector3f& normal = from.normals[source];
      const Vec3T<double> turned = deform_normal(transforms.data(), binding, Vec3T<double>{normal.x(), normal.y(), normal.z()});
      normal_out = Eigen::Vector3f(static_cast<float>(turned.x), static_cast<float>(turned.y), static_cast<float>(turned.z));
    }
    // Written after reading: `from` may be `to` (in place).
    to->positions[target] = Eigen::Vector3f(static_cast<float>(moved.x), static_cast<float>(moved.y), static_cast<float>(moved.z));
    if (normals) to->normals[target] = normal_out;
  }
}

}  // namespace

void deform_cloud_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                       const PointCloud& from, std::size_t begin, std::size_t end, PointCloud* to,
                       std::size_t to_begin, std::vector<float>* displacement_m) {
  deform_range(graph, transforms, time, from, begin, end, to, to_begin, displacement_m, nullptr, nullptr);
}

void deform_vertices_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                          const PointCloud& from, std::size_t begin, std::size_t end, PointCloud* to,
                          std::size_t to_begin, const std::int64_t* same_point, const PointCloud& deformed) {
  deform_range(graph, transforms, time, from, begin, end, to, to_begin, nullptr, same_point, &deformed);
}

void match_vertices_to_points(const PointCloud& vertices, std::size_t begin, std::size_t end,
                              const PointCloud& cloud, std::size_t cloud_begin, std::size_t cloud_end,
                              std::size_t cloud_to_begin, std::int64_t* same_point) {
  if (end > vertices.size() || begin > end || cloud_end > cloud.size() || cloud_begin > cloud_end) {
    throw_error(ErrorCode::kInvalidArgument, "map deformation: vertices [{}, {}) of {} against points [{}, {}) of {}",
                begin, end, vertices.size(), cloud_begin, cloud_end, cloud.size());
  }
  const bool normals = vertices.has_normals() && cloud.has_normals();
  if (vertices.has_normals() != cloud.has_normals()) {  // a point without the vertex's normal is not the same
    std::fill(same_point, same_point + (end - begin), std::int64_t{-1});
    return;
  }
  const auto same = [&](std::size_t v, std::size_t c) {
    return same_bits(vertices.positions[v], cloud.positions[c]) &&
           (!normals || same_bits(vertices.normals[v], cloud.normals[c]));
  };
  const auto record = [&](std::size_t v, std::size_t c) {
    same_point[v - begin] = static_cast<std::int64_t>(cloud_to_begin) + static_cast<std::int64_t>(c) -
                            static_cast<std::int64_t>(cloud_begin);
  };
  // A miss is resolved by the nearest of the vertex further on in the cloud (the points before
  // it are the cloud's own) and the point further on among the vertices (the vertices before
  // it are the mesh's own), looked for at growing distances up to kMaxGap. The comparisons
  // that costs are bounded by a budget in proportion to the walk, so that two clouds that
  // share little cost a walk, not a search.
  constexpr std::size_t kMaxGap = 1024;
  std::size_t budget = 16 * (end - begin) + kMaxGap;
  std::size_t c = cloud_begin;
  std::size_t v = begin;
  for (; v < end && c < cloud_end; ++v) {
    if (same(v, c)) {
      record(v, c++);
      continue;
    }
    bool resolved = false;
    for (std::size_t d = 1; d <= kMaxGap && budget > 0 && !resolved; ++d, --budget) {
      if (c + d < cloud_end && same(v, c + d)) {  // points c .. c + d - 1: the cloud's own
        c += d;
        record(v, c++);
        resolved = true;
      } else if (v + d < end && same(v + d, c)) {  // vertices v .. v + d - 1: the mesh's own
        std::fill(same_point + (v - begin), same_point + (v + d - begin), std::int64_t{-1});
        v += d;
        record(v, c++);
        resolved = true;
      }
    }
    if (!resolved) {  // neither within reach: both passed
      same_point[v - begin] = -1;
      ++c;
    }
  }
  std::fill(same_point + (v - begin), same_point + (end - begin), std::int64_t{-1});  // past the cloud's end
}

}  // namespace sls::fusion::deformation
