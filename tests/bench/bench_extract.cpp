// The host half of surface extraction (fusion/extract_internal.h), as a GPU extraction runs it
// after the kernels found the crossings and cells: the cloud of the crossings and the
// marching-cubes mesh assembled over them (each cell's edges found among the crossings), on
// all threads. Input: a sphere of radius N/2.5 voxels in an N³ grid, its crossings and
// surface cells in ascending order as the GPU's sort hands them over (N = 512: ~2.4 M
// crossings, ~4.7 M triangles; a paper-size ship is ~0.65 M points).
//   BM_AssembleCloud/N   detail::crossing_cloud (points/s)
//   BM_AssembleMesh/N    detail::cell_mesh (faces/s)
// Figures in docs/benchmarks.md with the machine and the date.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <vector>

#include "fusion/extract_internal.h"

namespace sls::fusion {
namespace {

struct SphereSurface {
  std::vector<EdgeCrossing> crossings;
  std::vector<CellCase> cells;
  std::size_t triangles = 0;
};

const SphereSurface& sphere(int n) {
  static std::map<int, SphereSurface> made;
  auto found = made.find(n);
  if (found != made.end()) return found->second;
  SphereSurface& out = made[n];
  const double centre = 0.5 * n, radius = n / 2.5, voxel_m = 1e-5;
  const auto u = [&](int i, int j, int k) {  // signed distance in voxels, clamped as a TSDF's
    const double d = std::sqrt((i - centre) * (i - centre) + (j - centre) * (j - centre) + (k - centre) * (k - centre));
    return static_cast<float>(std::fmax(-1.0, std::fmin(1.0, (d - radius) / 3.0)));
  };
  for (int k = 0; k < n; ++k) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const float here = u(i, j, k);
        if (here == 1.0f || here == -1.0f) continue;  // far from the shell: no crossing, no mixed cell
        for (int axis = 0; axis < 3; ++axis) {
          const int di = axis == 0 ? 1 : 0, dj = axis == 1 ? 1 : 0, dk = axis == 2 ? 1 : 0;
          if (i + di >= n || j + dj >= n || k + dk >= n) continue;
          const float next = u(i + di, j + dj, k + dk);
          if ((here < 0.0f) == (next < 0.0f)) continue;
          const double t = static_cast<double>(here / (here - next));
          EdgeCrossing crossing;
          crossing.edge_id = ((static_cast<std::uint64_t>(k) * static_cast<std::uint64_t>(n) +
                               static_cast<std::uint64_t>(j)) *
                                  static_cast<std::uint64_t>(n) +
                              static_cast<std::uint64_t>(i)) *
                                 3u +
                             static_cast<std::uint64_t>(axis);
          crossing.crossing.point_volume =
              Vec3f{static_cast<float>((i + 0.5 + t * di) * voxel_m), static_cast<float>((j + 0.5 + t * dj) * voxel_m),
                    static_cast<float>((k + 0.5 + t * dk) * voxel_m)};
          const double length =
              std::sqrt((i - centre) * (i - centre) + (j - centre) * (j - centre) + (k - centre) * (k - centre));
          crossing.crossing.normal_volume =
              Vec3f{static_cast<float>((i - centre) / length), static_cast<float>((j - centre) / length),
                    static_cast<float>((k - centre) / length)};
          crossing.crossing.weight = 10.0f;
          out.crossings.push_back(crossing);
        }
        if (i + 1 >= n || j + 1 >= n || k + 1 >= n) continue;
        int cube_case = 0;
        for (int c = 0; c < 8; ++c) {
          if (u(i + mc::corner_dx(c), j + mc::corner_dy(c), k + mc::corner_dz(c)) < 0.0f) cube_case |= 1 << c;
        }
        if (cube_case == 0 || cube_case == 255) continue;
        out.cells.push_back(CellCase{(static_cast<std::uint64_t>(k) * static_cast<std::uint64_t>(n) +
                                      static_cast<std::uint64_t>(j)) *
                                             static_cast<std::uint64_t>(n) +
                                         static_cast<std::uint64_t>(i),
                                     cube_case});
      }
    }
  }
  return out;
}

void BM_AssembleCloud(benchmark::State& state) {
  const SphereSurface& surface = sphere(static_cast<int>(state.range(0)));
  const ExtractOptions options;
  for (auto _ : state) {
    const PointCloud cloud = detail::crossing_cloud(surface.crossings, Pose{}, nullptr, options);
    benchmark::DoNotOptimize(cloud.positions.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(surface.crossings.size()));
  state.counters["crossings"] = static_cast<double>(surface.crossings.size());
}
BENCHMARK(BM_AssembleCloud)->Arg(512)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_AssembleMesh(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const SphereSurface& surface = sphere(n);
  const ExtractOptions options;
  std::size_t faces = 0;
  for (auto _ : state) {
    const TriangleMesh mesh = detail::cell_mesh(n, n, surface.crossings, surface.cells, Pose{}, options);
    faces = mesh.faces.size();
    benchmark::DoNotOptimize(mesh.faces.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(faces));
  state.counters["faces"] = static_cast<double>(faces);
  state.counters["cells"] = static_cast<double>(surface.cells.size());
}
BENCHMARK(BM_AssembleMesh)->Arg(512)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace sls::fusion
BENCHMARK_MAIN();
