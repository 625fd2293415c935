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
#include <cstdint>
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

// A mesh's vertices are mostly the points of the cloud extracted with it (the same crossings,
// the same bits), and deforming a point twice gives the same result twice. For each of
// vertices[begin, end): the index, shifted to where they are written (cloud_to_begin +
// (c - cloud_begin)), of the point c of cloud[cloud_begin, cloud_end) equal to it bit for bit
// (position, and normal when both have them), or -1. One walk over both: a part's cloud (the
// crossings its region keeps) and its mesh's vertices (those its cells use) are the same
// crossings in the same order, each with a few of its own (the region's rim); runs of
// either's own up to 1 024 long are passed over, longer ones (or a walk's comparisons past 16
// a vertex) cost matches, never a wrong one.
void match_vertices_to_points(const PointCloud& vertices, std::size_t begin, std::size_t end,
                              const PointCloud& cloud, std::size_t cloud_begin, std::size_t cloud_end,
                              std::size_t cloud_to_begin, std::int64_t* same_point);
// deform_cloud_part for mesh vertices: vertex begin + i with same_point[i] >= 0 takes the
// position and normal of point same_point[i] of `deformed` (the cloud, deformed already at
// the same time), the others are deformed themselves: the same values as deform_cloud_part's,
// bit for bit, with about half of a model's deformation work.
void deform_vertices_part(const DeformationGraph& graph, const std::vector<NodeTransform>& transforms, int time,
                          const PointCloud& from, std::size_t begin, std::size_t end, PointCloud* to,
                          std::size_t to_begin, const std::int64_t* same_point, const PointCloud& deformed);

}  // namespace sls::fusion::deformation
