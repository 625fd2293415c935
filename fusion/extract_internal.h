// Internal: the host half of surface extraction (fusion/extract.cpp), for callers that find
// the crossings and cells elsewhere (the moving volume's CUDA kernels) and need the same
// clouds and meshes, point for point, as the CPU extraction.
#pragma once

#include <cstddef>
#include <vector>

#include "fusion/extract.h"
#include "fusion/extract_shared.h"

namespace sls::fusion::detail {

// A read-only run of values (C++17 has no std::span): the crossings and cells where the GPU's
// download left them (a page-locked buffer the moving volume reuses), or a vector's. Made
// implicitly from a vector.
template <typename T>
class ConstSpan {
 public:
  ConstSpan(const T* data, std::size_t count) : data_(data), count_(count) {}
  ConstSpan(const std::vector<T>& values) : data_(values.data()), count_(values.size()) {}  // NOLINT: implicit
  std::size_t size() const { return count_; }
  bool empty() const { return count_ == 0; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  const T* begin() const { return data_; }
  const T* end() const { return data_ + count_; }

 private:
  const T* data_;
  std::size_t count_;
};

// Throws sls::Error(kInvalidArgument) naming a bad option.
void check_extract_options(const ExtractOptions& options);

// The float filter of a world-placed oriented region, for points in the frame of a volume at
// T_world_volume.
RegionFilter region_filter(const OrientedRegion& region, const Pose& T_world_volume);

// World-frame cloud of crossings in edge-id order; with `filter`, only the points it keeps.
PointCloud crossing_cloud(ConstSpan<EdgeCrossing> crossings, const Pose& T_world_volume,
                          const RegionFilter* filter, const ExtractOptions& options);

// The marching-cubes mesh of `cells` (ascending cell index, cases 1..254) of a grid nx x ny
// wide, over `crossings` (ascending edge id; every edge the cells' triangles use must be
// among them): vertices the used crossings in edge-id order, faces in cell order.
TriangleMesh cell_mesh(int nx, int ny, ConstSpan<EdgeCrossing> crossings, ConstSpan<CellCase> cells,
                       const Pose& T_world_volume, const ExtractOptions& options);

}  // namespace sls::fusion::detail
