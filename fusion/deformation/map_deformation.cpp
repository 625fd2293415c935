#include "fusion/deformation/map_deformation.h"

#include <algorithm>

#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"

namespace sls::fusion::deformation {

void deform_cloud_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                       PointCloud* cloud, std::size_t begin, std::size_t end, std::vector<float>* displacement_m) {
  deform_cloud_part(graph, transforms, time, *cloud, begin, end, cloud, begin, displacement_m);
}

void deform_cloud_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                       const PointCloud& from, std::size_t begin, std::size_t end, PointCloud* to,
                       std::size_t to_begin, std::vector<float>* displacement_m) {
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
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const std::size_t source = begin + static_cast<std::size_t>(i);
    const std::size_t target = to_begin + static_cast<std::size_t>(i);
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

}  // namespace sls::fusion::deformation
