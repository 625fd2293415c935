#include "fusion/deformation/map_deformation.h"

#include <algorithm>

#include "sdk/core/error.h"

namespace sls::fusion::deformation {

void deform_cloud_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                       PointCloud* cloud, std::size_t begin, std::size_t end, std::vector<float>* displacement_m) {
  if (end > cloud->size() || begin > end) {
    throw_error(ErrorCode::kInvalidArgument, "map deformation: points [{}, {}) of a cloud of {}", begin, end,
                cloud->size());
  }
  if (transforms.size() != graph.size()) {
    throw_error(ErrorCode::kInvalidArgument, "map deformation: {} transforms for a graph of {} nodes",
                transforms.size(), graph.size());
  }
  if (displacement_m != nullptr) displacement_m->resize(cloud->size(), 0.0f);
  if (graph.size() == 0 || begin == end) return;
  const int last = graph.node_at_time(time);
  const int first = std::max(0, last - graph.options().temporal_window + 1);
  std::vector<Vec3T<double>> candidates;
  for (int j = first; j <= last; ++j) candidates.push_back(transforms[static_cast<std::size_t>(j)].g);
  const int count = static_cast<int>(candidates.size());
  const int k = graph.options().nearest_nodes;
  const bool normals = cloud->has_normals();
  const auto n = static_cast<std::ptrdiff_t>(end - begin);
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const std::size_t index = begin + static_cast<std::size_t>(i);
    Eigen::Vector3f& position = cloud->positions[index];
    const Vec3T<double> p{position.x(), position.y(), position.z()};
    const NodeBinding binding = bind_nearest(candidates.data(), first, count, k, p);
    const Vec3T<double> moved = deform_point(transforms.data(), binding, p);
    if (displacement_m != nullptr) (*displacement_m)[index] = static_cast<float>(norm(moved - p));
    position = Eigen::Vector3f(static_cast<float>(moved.x), static_cast<float>(moved.y), static_cast<float>(moved.z));
    if (normals) {
      Eigen::Vector3f& normal = cloud->normals[index];
      const Vec3T<double> turned = deform_normal(transforms.data(), binding, Vec3T<double>{normal.x(), normal.y(), normal.z()});
      normal = Eigen::Vector3f(static_cast<float>(turned.x), static_cast<float>(turned.y), static_cast<float>(turned.z));
    }
  }
}

}  // namespace sls::fusion::deformation
