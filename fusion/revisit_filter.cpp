#include "fusion/revisit_filter.h"

#include <cmath>

#include "sdk/core/error.h"

namespace sls::fusion {

RevisitFilter::RevisitFilter(double cell_size_m) : cell_size_m_(cell_size_m) {
  if (!(cell_size_m > 0.0) || !std::isfinite(cell_size_m)) {
    throw_error(ErrorCode::kInvalidArgument, "revisit filter: cell size {} m is not positive", cell_size_m);
  }
}

namespace {

// 20 bits a coordinate: cells repeat every 2^20 cells (20 m at 20 µm), far beyond a volume's
// reach; the facing in the top bits.
std::uint64_t pack(const Eigen::Vector3i& cell, std::uint64_t facing) {
  std::uint64_t key = 0;
  for (int axis = 0; axis < 3; ++axis) key |= (static_cast<std::uint64_t>(cell[axis]) & 0xFFFFFu) << (20 * axis);
  return key | (facing << 60);
}

}  // namespace

RevisitFilter::Cell RevisitFilter::cell_of(const Eigen::Vector3f& position, const Eigen::Vector3f* normal) const {
  Cell cell;
  for (int axis = 0; axis < 3; ++axis) {
    cell.index[axis] = static_cast<int>(std::floor(static_cast<double>(position[axis]) / cell_size_m_));
  }
  cell.facing = 6;  // no normal
  if (normal != nullptr) {
    int axis = 0;
    normal->cwiseAbs().maxCoeff(&axis);
    cell.facing = static_cast<std::uint64_t>(2 * axis + ((*normal)[axis] < 0.0f ? 1 : 0));
  }
  return cell;
}

bool RevisitFilter::taken(const Cell& cell) const {
  for (int dz = -1; dz <= 1; ++dz) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        if (cells_.count(pack(cell.index + Eigen::Vector3i(dx, dy, dz), cell.facing)) != 0) return true;
      }
    }
  }
  return false;
}

std::vector<std::size_t> RevisitFilter::fresh_points(const PointCloud& cloud, std::vector<std::uint64_t>* fresh) const {
  std::vector<std::size_t> kept;
  kept.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Cell cell = cell_of(cloud.positions[i], cloud.has_normals() ? &cloud.normals[i] : nullptr);
    if (taken(cell)) continue;
    kept.push_back(i);
    fresh->push_back(pack(cell.index, cell.facing));
  }
  return kept;
}

ExtractedSurface RevisitFilter::filter(const ExtractedSurface& part) {
  std::vector<std::uint64_t> fresh;
  ExtractedSurface out;
  out.cloud = select_points(part.cloud, fresh_points(part.cloud, &fresh));

  // The mesh: vertices of taken cells go, and every face that used one.
  std::vector<std::uint64_t> fresh_vertices;
  const std::vector<std::size_t> kept_vertices = fresh_points(part.mesh.vertices, &fresh_vertices);
  std::vector<std::int32_t> new_index(part.mesh.vertices.size(), -1);
  for (std::size_t i = 0; i < kept_vertices.size(); ++i) new_index[kept_vertices[i]] = static_cast<std::int32_t>(i);
  std::vector<bool> used(kept_vertices.size(), false);
  for (const auto& face : part.mesh.faces) {
    const std::array<std::int32_t, 3> mapped = {new_index[static_cast<std::size_t>(face[0])],
                                                new_index[static_cast<std::size_t>(face[1])],
                                                new_index[static_cast<std::size_t>(face[2])]};
    if (mapped[0] < 0 || mapped[1] < 0 || mapped[2] < 0) continue;
    out.mesh.faces.push_back(mapped);
    for (const std::int32_t v : mapped) used[static_cast<std::size_t>(v)] = true;
  }
  // Drop the vertices no kept face uses (renumbering the faces once more).
  std::vector<std::size_t> used_vertices;
  std::vector<std::int32_t> compact(kept_vertices.size(), -1);
  for (std::size_t i = 0; i < kept_vertices.size(); ++i) {
    if (!used[i]) continue;
    compact[i] = static_cast<std::int32_t>(used_vertices.size());
    used_vertices.push_back(kept_vertices[i]);
  }
  for (auto& face : out.mesh.faces) {
    for (std::int32_t& v : face) v = compact[static_cast<std::size_t>(v)];
  }
  out.mesh.vertices = select_points(part.mesh.vertices, used_vertices);

  // Remembered after both passes: points of one part never hide each other.
  cells_.insert(fresh.begin(), fresh.end());
  cells_.insert(fresh_vertices.begin(), fresh_vertices.end());
  return out;
}

void RevisitFilter::remember(const PointCloud& surface) {
  for (std::size_t i = 0; i < surface.size(); ++i) {
    const Cell cell = cell_of(surface.positions[i], surface.has_normals() ? &surface.normals[i] : nullptr);
    cells_.insert(pack(cell.index, cell.facing));
  }
}

}  // namespace sls::fusion
