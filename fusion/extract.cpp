#include "fusion/extract.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "fusion/extract_internal.h"
#include "fusion/extract_shared.h"
#include "sdk/core/error.h"

namespace sls::fusion {
namespace {

// Voxel index ranges [begin, end) per axis.
struct GridRange {
  int begin[3] = {0, 0, 0};
  int end[3] = {0, 0, 0};
  bool empty() const { return end[0] <= begin[0] || end[1] <= begin[1] || end[2] <= begin[2]; }
};

void check_options(const ExtractOptions& options) {
  if (!std::isfinite(options.min_weight) || options.min_weight < 0.0f) {
    throw_error(ErrorCode::kInvalidArgument, "extract: min_weight {} is not a finite weight >= 0",
                static_cast<double>(options.min_weight));
  }
  if (!(options.full_confidence_weight > 0.0f) || !std::isfinite(options.full_confidence_weight)) {
    throw_error(ErrorCode::kInvalidArgument, "extract: full_confidence_weight {} is not positive and finite",
                static_cast<double>(options.full_confidence_weight));
  }
}

void check_view(const VolumeView& view) {
  const bool has_arrays = view.format == VoxelFormat::kFloat32 ? (view.u32 != nullptr && view.w32 != nullptr)
                                                               : (view.u16 != nullptr && view.w8 != nullptr);
  if (view.nx < 1 || view.ny < 1 || view.nz < 1 || !has_arrays || !(view.voxel_size_m > 0.0f)) {
    throw_error(ErrorCode::kInvalidArgument, "extract: the volume view ({} x {} x {} voxels) has no voxels", view.nx,
                view.ny, view.nz);
  }
}

VolumeView host_view(const Volume& volume) {
  if (volume.device().is_cuda()) {
    throw_error(ErrorCode::kInvalidArgument,
                "extract: the volume lives on {}; extraction reads host memory, call volume.to_host() first",
                volume.device().to_string());
  }
  return volume.view();
}

GridRange whole_grid(const VolumeView& view) {
  GridRange range;
  range.end[0] = view.nx;
  range.end[1] = view.ny;
  range.end[2] = view.nz;
  return range;
}

// The voxels whose +axis edges can hold a crossing inside the world box: the box's corners
// in grid coordinates (voxel centres at integers), widened by one edge and clipped.
GridRange grid_range_of(const VolumeView& view, const Pose& T_world_volume, const Box& box) {
  const Pose T_volume_world = T_world_volume.inverse();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(HUGE_VAL), hi = Eigen::Vector3d::Constant(-HUGE_VAL);
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner((c & 1) != 0 ? box.max.x() : box.min.x(), (c & 2) != 0 ? box.max.y() : box.min.y(),
                                 (c & 4) != 0 ? box.max.z() : box.min.z());
    const Eigen::Vector3d grid = (T_volume_world * corner) / static_cast<double>(view.voxel_size_m) -
                                 Eigen::Vector3d::Constant(0.5);
    if (!grid.allFinite()) return whole_grid(view);  // an unbounded box: filter every point
    lo = lo.cwiseMin(grid);
    hi = hi.cwiseMax(grid);
  }
  const int counts[3] = {view.nx, view.ny, view.nz};
  GridRange range;
  for (int axis = 0; axis < 3; ++axis) {
    const double begin = std::clamp(std::floor(lo[axis]) - 1.0, 0.0, static_cast<double>(counts[axis]));
    const double end = std::clamp(std::ceil(hi[axis]) + 1.0, 0.0, static_cast<double>(counts[axis]));
    range.begin[axis] = static_cast<int>(begin);
    range.end[axis] = static_cast<int>(end);
  }
  return range;
}

// The first voxel at or after i (before end) in the x row starting at `row` with W > 0.
// Most of a scan's volume was never observed; compact weights are skipped eight at a time.
int next_observed(const VolumeView& view, std::size_t row, int i, int end) {
  if (view.format == VoxelFormat::kCompact) {
    const std::uint8_t* w = view.w8 + row;
    for (; i + 8 <= end; i += 8) {
      std::uint64_t word = 0;
      std::memcpy(&word, w + i, sizeof word);
      if (word != 0) break;
    }
    while (i < end && w[i] == 0) ++i;
  } else {
    const float* w = view.w32 + row;
    while (i < end && !(w[i] > 0.0f)) ++i;
  }
  return i;
}

// Every crossing on the +x, +y, +z edges of the voxels in `range`, in edge-id order
// (each z slice on its own thread, then concatenated).
std::vector<EdgeCrossing> find_crossings(const VolumeView& view, const GridRange& range, float min_weight) {
  if (range.empty()) return {};
  const int slices = range.end[2] - range.begin[2];
  std::vector<std::vector<EdgeCrossing>> per_slice(static_cast<std::size_t>(slices));
#pragma omp parallel for schedule(dynamic, 1)
  for (int s = 0; s < slices; ++s) {
    const int k = range.begin[2] + s;
    std::vector<EdgeCrossing>& out = per_slice[static_cast<std::size_t>(s)];
    for (int j = range.begin[1]; j < range.end[1]; ++j) {
      const std::size_t row = view.index(0, j, k);
      for (int i = next_observed(view, row, range.begin[0], range.end[0]); i < range.end[0];
           i = next_observed(view, row, i + 1, range.end[0])) {
        if (!voxel_usable(view, row + static_cast<std::size_t>(i), min_weight)) continue;
        for (int axis = 0; axis < 3; ++axis) {
          EdgeCrossing found;
          if (edge_crossing(view, i, j, k, axis, min_weight, &found.crossing)) {
            found.edge_id = grid_edge_id(view, i, j, k, axis);
            out.push_back(found);
          }
        }
      }
    }
  }
  std::size_t total = 0;
  for (const std::vector<EdgeCrossing>& slice : per_slice) total += slice.size();
  std::vector<EdgeCrossing> all;
  all.reserve(total);
  for (const std::vector<EdgeCrossing>& slice : per_slice) all.insert(all.end(), slice.begin(), slice.end());
  return all;
}

// Volume frame -> world frame in double, so a far-away volume loses no precision to float.
struct ToWorld {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  explicit ToWorld(const Pose& T_world_volume)
      : rotation(T_world_volume.rotation()), translation(T_world_volume.translation()) {}
  Eigen::Vector3d point(const Vec3f& p) const {
    return rotation * Eigen::Vector3d(static_cast<double>(p.x), static_cast<double>(p.y), static_cast<double>(p.z)) +
           translation;
  }
  Eigen::Vector3f normal(const Vec3f& n) const {
    return (rotation * Eigen::Vector3d(static_cast<double>(n.x), static_cast<double>(n.y), static_cast<double>(n.z)))
        .normalized()
        .cast<float>();
  }
};

// A cloud of `count` points with normals, confidence and the "weight" property, to be set.
PointCloud sized_cloud(std::size_t count) {
  PointCloud cloud;
  cloud.positions.resize(count);
  cloud.normals.resize(count);
  cloud.confidence.resize(count);
  cloud.properties.push_back({"weight", std::vector<float>(count)});
  return cloud;
}

// Point i of a sized_cloud() from its crossing. Each point is its own crossing's alone, so the
// callers set them on threads (a move ships ~0.65 M of them at the paper's size; appended one
// at a time on one thread they were most of the move's host time).
void set_point(PointCloud* cloud, std::size_t i, const SurfaceCrossing& crossing, const ToWorld& to_world,
               const ExtractOptions& options) {
  cloud->positions[i] = to_world.point(crossing.point_volume).cast<float>();
  cloud->normals[i] = to_world.normal(crossing.normal_volume);
  cloud->confidence[i] = std::min(1.0f, crossing.weight / options.full_confidence_weight);
  cloud->properties.front().values[i] = crossing.weight;
}

// What a region keeps, one predicate for every filter: nothing set keeps everything; a world
// Box tests the world point (double); an oriented region tests the volume-frame point with
// region_keeps() (float, as the CUDA kernels do).
struct Region {
  const Box* box = nullptr;
  const RegionFilter* filter = nullptr;
  bool keeps(const Eigen::Vector3d& world, const Vec3f& point_volume) const {
    if (box != nullptr && !box->contains(world)) return false;
    return filter == nullptr || region_keeps(*filter, point_volume);
  }
  // A cell belongs to the region when its centre does (oriented regions only: Box filters
  // clouds alone).
  bool keeps_cell(const VolumeView& view, int i, int j, int k) const {
    return filter == nullptr || region_keeps(*filter, cell_centre(view, i, j, k));
  }
};

// The cloud of the crossings the region keeps.
PointCloud make_cloud(detail::ConstSpan<EdgeCrossing> crossings, const Pose& T_world_volume, const Region& region,
                      const ExtractOptions& options) {
  const ToWorld to_world(T_world_volume);
  // In chunks on threads: which crossings the region keeps and how many per chunk, then each
  // chunk's points from where the chunks before it end, in crossing order. Beside the cloud
  // only a byte per crossing: the extraction's transient memory is what the allocator keeps.
  constexpr std::size_t kChunk = std::size_t{1} << 16;
  const std::size_t chunks = (crossings.size() + kChunk - 1) / kChunk;
  std::vector<std::uint8_t> keeps(crossings.size());
  std::vector<std::size_t> chunk_start(chunks + 1, 0);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t c = 0; c < static_cast<std::ptrdiff_t>(chunks); ++c) {
    const std::size_t begin = static_cast<std::size_t>(c) * kChunk, end = std::min(crossings.size(), begin + kChunk);
    std::size_t kept = 0;
    for (std::size_t n = begin; n < end; ++n) {
      const Vec3f& point_volume = crossings[n].crossing.point_volume;
      keeps[n] = region.keeps(to_world.point(point_volume), point_volume) ? 1 : 0;
      kept += keeps[n];
    }
    chunk_start[static_cast<std::size_t>(c) + 1] = kept;
  }
  for (std::size_t c = 0; c < chunks; ++c) chunk_start[c + 1] += chunk_start[c];
  PointCloud cloud = sized_cloud(chunk_start[chunks]);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t c = 0; c < static_cast<std::ptrdiff_t>(chunks); ++c) {
    const std::size_t begin = static_cast<std::size_t>(c) * kChunk, end = std::min(crossings.size(), begin + kChunk);
    std::size_t out = chunk_start[static_cast<std::size_t>(c)];
    for (std::size_t n = begin; n < end; ++n) {
      if (keeps[n] != 0) set_point(&cloud, out++, crossings[n].crossing, to_world, options);
    }
  }
  return cloud;
}

// The cells that can hold surface: the (up to) four around each crossing edge, as the voxel
// index of their first corner, ascending and unique. Cells with no crossing edge are empty
// or fully inside / outside, so the mesh never visits the unobserved bulk of the volume.
std::vector<std::uint64_t> candidate_cells(const VolumeView& view, const std::vector<EdgeCrossing>& crossings) {
  std::vector<std::uint64_t> cells;
  cells.reserve(crossings.size() * 4);
  const auto nx = static_cast<std::uint64_t>(view.nx), ny = static_cast<std::uint64_t>(view.ny);
  for (const EdgeCrossing& found : crossings) {
    const std::uint64_t voxel = found.edge_id / 3u;
    const auto axis = static_cast<int>(found.edge_id % 3u);
    const int base[3] = {static_cast<int>(voxel % nx), static_cast<int>((voxel / nx) % ny),
                         static_cast<int>(voxel / (nx * ny))};
    const int u = (axis + 1) % 3, w = (axis + 2) % 3;  // the two axes across the edge
    for (int du = 0; du < 2; ++du) {
      for (int dw = 0; dw < 2; ++dw) {
        int cell[3] = {base[0], base[1], base[2]};
        cell[u] -= du;
        cell[w] -= dw;
        if (cell[0] < 0 || cell[1] < 0 || cell[2] < 0 || cell[0] + 1 >= view.nx || cell[1] + 1 >= view.ny ||
            cell[2] + 1 >= view.nz) {
          continue;
        }
        cells.push_back(static_cast<std::uint64_t>(view.index(cell[0], cell[1], cell[2])));
      }
    }
  }
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  return cells;
}

// The surface cells among the candidates that the region keeps, with their cases, in cell
// order (chunks of cells on threads).
std::vector<CellCase> surface_cells(const VolumeView& view, const std::vector<std::uint64_t>& cells,
                                    const Region& region, float min_weight) {
  constexpr std::size_t kChunk = 4096;
  const std::size_t chunks = (cells.size() + kChunk - 1) / kChunk;
  std::vector<std::vector<CellCase>> per_chunk(chunks);
  const auto nx = static_cast<std::uint64_t>(view.nx), ny = static_cast<std::uint64_t>(view.ny);
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t c = 0; c < static_cast<std::ptrdiff_t>(chunks); ++c) {
    std::vector<CellCase>& out = per_chunk[static_cast<std::size_t>(c)];
    const std::size_t end = std::min(cells.size(), (static_cast<std::size_t>(c) + 1) * kChunk);
    for (std::size_t n = static_cast<std::size_t>(c) * kChunk; n < end; ++n) {
      const int i = static_cast<int>(cells[n] % nx), j = static_cast<int>((cells[n] / nx) % ny),
                k = static_cast<int>(cells[n] / (nx * ny));
      if (!region.keeps_cell(view, i, j, k)) continue;
      const int cube_case = cell_case(view, i, j, k, min_weight);
      if (cube_case <= 0 || cube_case == 255) continue;
      out.push_back(CellCase{cells[n], cube_case});
    }
  }
  std::vector<CellCase> all;
  for (const std::vector<CellCase>& chunk : per_chunk) all.insert(all.end(), chunk.begin(), chunk.end());
  return all;
}

// The crossings' edge ids (ascending) and where each grid row begins: a cell's edge is looked
// for among its row's few crossings, not by a binary search over all of them (the mesh's
// assembly of a 790 k-crossing sphere took 335 ms with it, 217-267 ms without, dev-2core).
// Row r (k * ny + j) holds edge ids [r, r + 1) * 3 nx.
class EdgeIndex {
 public:
  EdgeIndex(detail::ConstSpan<EdgeCrossing> crossings, int grid_nx, int grid_ny)
      : nx_(static_cast<std::uint64_t>(grid_nx)), ny_(static_cast<std::uint64_t>(grid_ny)) {
    ids_.resize(crossings.size());
    for (std::size_t n = 0; n < crossings.size(); ++n) ids_[n] = crossings[n].edge_id;
    const std::uint64_t row_edges = 3u * nx_;
    const std::uint64_t rows = ids_.empty() ? 0u : ids_.back() / row_edges + 1u;
    row_start_.assign(static_cast<std::size_t>(rows) + 1u, static_cast<std::uint32_t>(ids_.size()));
    row_start_.front() = 0u;
    // Sorted ids: each row's end passed once, no division per crossing.
    std::size_t row = 0;
    std::uint64_t row_end = row_edges;
    for (std::size_t n = 0; n < ids_.size(); ++n) {
      while (ids_[n] >= row_end) {
        row_start_[++row] = static_cast<std::uint32_t>(n);
        row_end += row_edges;
      }
    }
  }
  // The crossing on grid edge (i, j, k, axis), or -1.
  std::int32_t find(int i, int j, int k, int axis) const {
    const std::uint64_t row = static_cast<std::uint64_t>(k) * ny_ + static_cast<std::uint64_t>(j);
    if (row + 1u >= row_start_.size()) return -1;
    const std::uint64_t id = (row * nx_ + static_cast<std::uint64_t>(i)) * 3u + static_cast<std::uint64_t>(axis);
    const auto first = ids_.begin() + row_start_[static_cast<std::size_t>(row)];
    const auto last = ids_.begin() + row_start_[static_cast<std::size_t>(row) + 1u];
    const auto found = std::lower_bound(first, last, id);
    return found != last && *found == id ? static_cast<std::int32_t>(found - ids_.begin()) : -1;
  }

 private:
  std::uint64_t nx_, ny_;
  std::vector<std::uint64_t> ids_;
  std::vector<std::uint32_t> row_start_;  // rows + 1 entries; fewer crossings than 2^31 (assemble_mesh)
};

// The marching-cubes mesh of the cells over the crossings (in edge-id order, so a cell finds
// its edge's vertex in its row's crossings and all cells around an edge agree on it). Reads no
// voxel.
TriangleMesh assemble_mesh(int grid_nx, int grid_ny, detail::ConstSpan<EdgeCrossing> crossings,
                           detail::ConstSpan<CellCase> cells, const Pose& T_world_volume,
                           const ExtractOptions& options) {
  if (crossings.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw_error(ErrorCode::kUnsupported, "extract_mesh: {} vertices, more than a PLY int index holds",
                crossings.size());
  }
  const EdgeIndex edges(crossings, grid_nx, grid_ny);

  // Cells in chunks on threads, faces in the cells' order: each chunk's triangles counted from
  // its cases first, so that each chunk writes its faces where they go, in the one array.
  constexpr std::size_t kChunk = 4096;
  const std::size_t chunks = (cells.size() + kChunk - 1) / kChunk;
  std::vector<std::size_t> chunk_start(chunks + 1, 0);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t c = 0; c < static_cast<std::ptrdiff_t>(chunks); ++c) {
    const std::size_t end = std::min(cells.size(), (static_cast<std::size_t>(c) + 1) * kChunk);
    std::size_t triangles = 0;
    for (std::size_t n = static_cast<std::size_t>(c) * kChunk; n < end; ++n) {
      for (int t = 0; t < 15 && mc::triangle_edge(cells[n].cube_case, t) >= 0; t += 3) ++triangles;
    }
    chunk_start[static_cast<std::size_t>(c) + 1] = triangles;
  }
  for (std::size_t c = 0; c < chunks; ++c) chunk_start[c + 1] += chunk_start[c];
  TriangleMesh mesh;
  mesh.faces.resize(chunk_start[chunks]);
  const auto nx = static_cast<std::uint64_t>(grid_nx), ny = static_cast<std::uint64_t>(grid_ny);
  bool missing_vertex = false;
#pragma omp parallel for schedule(dynamic, 1) reduction(|| : missing_vertex)
  for (std::ptrdiff_t c = 0; c < static_cast<std::ptrdiff_t>(chunks); ++c) {
    std::size_t out = chunk_start[static_cast<std::size_t>(c)];
    const std::size_t end = std::min(cells.size(), (static_cast<std::size_t>(c) + 1) * kChunk);
    for (std::size_t n = static_cast<std::size_t>(c) * kChunk; n < end; ++n) {
      const std::uint64_t cell = cells[n].cell;
      const int i = static_cast<int>(cell % nx), j = static_cast<int>((cell / nx) % ny),
                k = static_cast<int>(cell / (nx * ny));
      const int cube_case = cells[n].cube_case;
      for (int t = 0; t < 15 && mc::triangle_edge(cube_case, t) >= 0; t += 3) {
        std::array<std::int32_t, 3>& face = mesh.faces[out++];
        for (int corner = 0; corner < 3; ++corner) {
          int gi = 0, gj = 0, gk = 0, axis = 0;
          cell_grid_edge(i, j, k, mc::triangle_edge(cube_case, t + corner), &gi, &gj, &gk, &axis);
          const std::int32_t found = edges.find(gi, gj, gk, axis);
          missing_vertex = missing_vertex || found < 0;
          face[static_cast<std::size_t>(corner)] = found < 0 ? 0 : found;
        }
      }
    }
  }
  if (missing_vertex) {
    // A sign change between usable corners is always a crossing; this would be a table bug.
    throw_error(ErrorCode::kInternal, "extract_mesh: a marching-cubes edge has no zero crossing");
  }

  // Keep the crossings some face uses (a crossing at the rim of the observed region has no
  // complete cell around it), renumbered in order.
  std::vector<std::int32_t> remap(crossings.size(), -1);
  for (const auto& face : mesh.faces) {
    for (const std::int32_t v : face) remap[static_cast<std::size_t>(v)] = 0;
  }
  std::int32_t next = 0;
  for (std::int32_t& index : remap) {
    if (index >= 0) index = next++;
  }
  mesh.vertices = sized_cloud(static_cast<std::size_t>(next));
  const ToWorld to_world(T_world_volume);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t n = 0; n < static_cast<std::ptrdiff_t>(crossings.size()); ++n) {
    const std::int32_t index = remap[static_cast<std::size_t>(n)];
    if (index >= 0) {
      set_point(&mesh.vertices, static_cast<std::size_t>(index), crossings[static_cast<std::size_t>(n)].crossing,
                to_world, options);
    }
  }
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t f = 0; f < static_cast<std::ptrdiff_t>(mesh.faces.size()); ++f) {
    for (std::int32_t& v : mesh.faces[static_cast<std::size_t>(f)]) v = remap[static_cast<std::size_t>(v)];
  }
  return mesh;
}

// The mesh of the region's cells over every crossing of the volume (in edge-id order).
TriangleMesh make_mesh(const VolumeView& view, const std::vector<EdgeCrossing>& crossings, const Pose& T_world_volume,
                       const Region& region, const ExtractOptions& options) {
  const std::vector<CellCase> cells =
      surface_cells(view, candidate_cells(view, crossings), region, options.min_weight);
  return assemble_mesh(view.nx, view.ny, crossings, cells, T_world_volume, options);
}

}  // namespace

namespace detail {

void check_extract_options(const ExtractOptions& options) { check_options(options); }

RegionFilter region_filter(const OrientedRegion& region, const Pose& T_world_volume) {
  RegionFilter filter;
  filter.T_box_volume = (region.T_world_box.inverse() * T_world_volume).to_rigid3f();
  filter.lo = Vec3f{static_cast<float>(region.min.x()), static_cast<float>(region.min.y()),
                    static_cast<float>(region.min.z())};
  filter.hi = Vec3f{static_cast<float>(region.max.x()), static_cast<float>(region.max.y()),
                    static_cast<float>(region.max.z())};
  filter.keep_outside = region.keep_outside ? 1 : 0;
  return filter;
}

PointCloud crossing_cloud(ConstSpan<EdgeCrossing> crossings, const Pose& T_world_volume,
                          const RegionFilter* filter, const ExtractOptions& options) {
  Region region;
  region.filter = filter;
  return make_cloud(crossings, T_world_volume, region, options);
}

TriangleMesh cell_mesh(int nx, int ny, ConstSpan<EdgeCrossing> crossings, ConstSpan<CellCase> cells,
                       const Pose& T_world_volume, const ExtractOptions& options) {
  return assemble_mesh(nx, ny, crossings, cells, T_world_volume, options);
}

}  // namespace detail

PointCloud extract_points(const VolumeView& view, const Pose& T_world_volume, const Box* region,
                          const ExtractOptions& options) {
  check_options(options);
  check_view(view);
  const GridRange range = region != nullptr ? grid_range_of(view, T_world_volume, *region) : whole_grid(view);
  Region filter;
  filter.box = region;
  return make_cloud(find_crossings(view, range, options.min_weight), T_world_volume, filter, options);
}

PointCloud extract_points(const VolumeView& view, const Pose& T_world_volume, const OrientedRegion& region,
                          const ExtractOptions& options) {
  check_options(options);
  check_view(view);
  const RegionFilter filter = detail::region_filter(region, T_world_volume);
  return detail::crossing_cloud(find_crossings(view, whole_grid(view), options.min_weight), T_world_volume, &filter,
                                options);
}

ExtractedSurface extract_surface(const VolumeView& view, const Pose& T_world_volume, const OrientedRegion& region,
                                 const ExtractOptions& options) {
  check_options(options);
  check_view(view);
  const RegionFilter filter = detail::region_filter(region, T_world_volume);
  Region part;
  part.filter = &filter;
  // Every crossing, not only the region's: the region's cells at its rim use vertices across it.
  const std::vector<EdgeCrossing> crossings = find_crossings(view, whole_grid(view), options.min_weight);
  ExtractedSurface surface;
  surface.cloud = make_cloud(crossings, T_world_volume, part, options);
  surface.mesh = make_mesh(view, crossings, T_world_volume, part, options);
  return surface;
}

PointCloud extract_points(const Volume& volume, const Box* region, const ExtractOptions& options) {
  return extract_points(host_view(volume), volume.geometry().T_world_volume, region, options);
}

TriangleMesh extract_mesh(const VolumeView& view, const Pose& T_world_volume, const ExtractOptions& options) {
  check_options(options);
  check_view(view);
  return make_mesh(view, find_crossings(view, whole_grid(view), options.min_weight), T_world_volume, Region{}, options);
}

TriangleMesh extract_mesh(const Volume& volume, const ExtractOptions& options) {
  return extract_mesh(host_view(volume), volume.geometry().T_world_volume, options);
}

ExtractedSurface extract_surface(const VolumeView& view, const Pose& T_world_volume, const ExtractOptions& options) {
  check_options(options);
  check_view(view);
  const std::vector<EdgeCrossing> crossings = find_crossings(view, whole_grid(view), options.min_weight);
  ExtractedSurface surface;
  surface.cloud = make_cloud(crossings, T_world_volume, Region{}, options);
  surface.mesh = make_mesh(view, crossings, T_world_volume, Region{}, options);
  return surface;
}

ExtractedSurface extract_surface(const Volume& volume, const ExtractOptions& options) {
  return extract_surface(host_view(volume), volume.geometry().T_world_volume, options);
}

}  // namespace sls::fusion
