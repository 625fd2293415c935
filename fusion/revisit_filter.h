// Keeps one copy of surface a moving volume ships more than once (MovingVolumeOptions::
// merge_revisits). A session that circles an object again and again fuses the same surface
// on every pass and ships it when the volume moves on; without this, each pass is kept and the
// model grows with time. With it, a shipped point or mesh vertex is dropped when an earlier
// move already shipped surface in its cell (a cube of cell_size_m in world coordinates) or a
// neighbouring one (a later pass drifts: its copy lies a little off the first), facing the same
// way (the dominant axis and sign of its normal: the two faces of a thin wall stay apart), so
// the model is bounded by the object's surface. The first pass's copy is the one
// kept: a later pass's drift, if any, is not mixed into it.
#pragma once

#include <cstdint>
#include <unordered_set>
#include <vector>

#include <Eigen/Core>

#include "fusion/extract.h"

namespace sls::fusion {

class RevisitFilter {
 public:
  explicit RevisitFilter(double cell_size_m);

  // `part` without what earlier parts already covered; then remembers what it covered. Mesh
  // faces are kept only when all three vertices are; unused vertices go.
  ExtractedSurface filter(const ExtractedSurface& part);
  // Remembers what `surface` covers without filtering it: surface shipped before merging began.
  void remember(const PointCloud& surface);
  void clear() { cells_.clear(); }
  std::size_t cells() const { return cells_.size(); }

 private:
  struct Cell {
    Eigen::Vector3i index;
    std::uint64_t facing = 0;  // 2 x dominant axis + (1 when its normal component is negative); 6: no normal
  };
  Cell cell_of(const Eigen::Vector3f& position, const Eigen::Vector3f* normal) const;
  // Whether an earlier part covered this cell or one of its 26 neighbours, facing the same way.
  bool taken(const Cell& cell) const;
  // Indices of the points of `cloud` whose cell is not taken yet; their keys added to `fresh`.
  std::vector<std::size_t> fresh_points(const PointCloud& cloud, std::vector<std::uint64_t>* fresh) const;

  double cell_size_m_;
  std::unordered_set<std::uint64_t> cells_;
};

}  // namespace sls::fusion
