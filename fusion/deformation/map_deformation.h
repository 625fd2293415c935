// Map deformation (paper section IV-D, eq. 18): the deformation graph applied to the map the
// scan made — the surface shipped by the moving volume part by part, the surface still in the
// volume at the end, and the poses — each part bound to the nodes of its own time
// (DeformationGraph::bind_before: the k nearest of the temporal_window nodes made up to the
// time the part was last observed). One per-point body (deform_shared.h), CPU threads.
//
//   const std::vector<NodeTransform> transforms = graph.transforms();
//   deform_cloud_part(graph, transforms, shipped_at_frame, &cloud, begin, end, &displacement);
#pragma once

#include <cstddef>
#include <vector>

#include "fusion/deformation/deformation_graph.h"
#include "sdk/core/point_cloud.h"

namespace sls::fusion::deformation {

// Points [begin, end) of `cloud` (positions, and normals when it has them), observed up to
// frame `time`, deformed in place. `displacement_m` (optional, resized to the cloud): how far
// each deformed point moved. A graph without nodes changes nothing.
void deform_cloud_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                       PointCloud* cloud, std::size_t begin, std::size_t end,
                       std::vector<float>* displacement_m = nullptr);
// The same read from `from` and written to `to` from point `to_begin` on (positions, and
// normals when `from` has them; `to` sized already, e.g. by join_clouds without its geometry):
// the model deformed as it is joined, one pass over its points. `displacement_m` indexed as `to`.
void deform_cloud_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                       const PointCloud& from, std::size_t begin, std::size_t end, PointCloud* to,
                       std::size_t to_begin, std::vector<float>* displacement_m = nullptr);

}  // namespace sls::fusion::deformation
