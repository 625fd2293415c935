// The deformation graph's solver (fusion/deformation) at the size: a turntable scan's
// graph of N nodes on its focus circle (16 mm radius, 1 mm apart: several turns at 500), with
// the turntable's rotation prior on every frame's pose (2 N), CPU.
//   BM_OnlineStep/N           one Gauss–Newton step with 256 point-to-plane constraints from the
//                             newest view to the map seen a turn earlier (both sides deformed),
//                             the analysis reused (the pattern is unchanged since the last step)
//   BM_OnlineStepNewNode/N    a node added, then one step: the pattern grows, analysed again
//   BM_LoopClosure/N          2000 point-to-point constraints from the last view to the first
//                             frame's surface, then the steps the session's loop closure runs
//                             (3), from the analysis to the last step
//   BM_DeformMap/N            the final model's deformation (eqs. 18-19): N points with normals
//                             scattered around the nodes, each bound to its 4 nearest of the
//                             last 8 nodes and moved, on all threads (points/s)
//   BM_MatchVertices/N        the walk that finds a mesh's vertices among its cloud's N points
//                             (one thread; every 40th point the cloud's own, every 50th vertex
//                             the mesh's own), so that they are deformed once (vertices/s)
// Figures in docs/benchmarks.md with the machine and the date.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "fusion/deformation/deformation_graph.h"
#include "fusion/deformation/map_deformation.h"

namespace sls::fusion::deformation {
namespace {

constexpr double kRadius = 16e-3, kSpacing = 1e-3, kFocus = 0.1;

GraphOptions bench_options() {
  GraphOptions options;
  options.length_scale_m = kSpacing;
  options.region_radius_m = 5e-3;
  return options;
}

// N nodes along a helix of turns 4 mm apart (a scan that climbs as it turns), a keyframe every
// two frames, each frame's pose with the turntable's rotation prior (σ √2 · 0.002° about the
// axis and across it), as the session gives them.
DeformationGraph make_graph(int nodes) {
  DeformationGraph graph(bench_options());
  const double step = kSpacing / kRadius;
  const double turn = 2.0 * M_PI / step;
  const double sigma_rad = std::sqrt(2.0) * 0.002 * M_PI / 180.0;
  RotationPrior prior;
  prior.information = Eigen::Matrix3d::Identity() / (sigma_rad * sigma_rad);
  for (int j = 0; j < nodes; ++j) {
    const Eigen::Vector3d focus(kRadius * std::cos(j * step), kRadius * std::sin(j * step), 4e-3 * j / turn);
    graph.add_node(focus, 2 * j);
    for (int frame : {2 * j, 2 * j + 1}) {
      prior.rotation = Eigen::AngleAxisd(1e-5 * frame, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      graph.add_rotation_prior(focus, frame, prior);
    }
  }
  return graph;
}

Eigen::Vector3d scatter(const Eigen::Vector3d& centre, int i, double radius) {
  const double a = 0.7 * i, b = 1.3 * i;
  return centre + radius * Eigen::Vector3d(std::sin(a), std::cos(b), 0.3 * std::sin(a + b));
}

// The newest node's view against the surface seen about one turn before.
void add_online_constraints(DeformationGraph* graph, int count) {
  const int last = static_cast<int>(graph->size()) - 1;
  const int earlier = std::max(0, last - static_cast<int>(2.0 * M_PI * kRadius / kSpacing) + 3);
  for (int i = 0; i < count; ++i) {
    Constraint c;
    c.source = scatter(graph->node(last).position, i, 4e-3);
    c.source_binding = graph->bind_before(c.source, graph->node(last).time);
    c.target = c.source + Eigen::Vector3d(20e-6, -10e-6, 5e-6);
    c.target_binding = graph->bind_around(c.target, graph->node(earlier).time);
    c.normal = Eigen::Vector3d(c.source.x(), c.source.y(), 0.0).normalized();
    graph->add_constraint(c);
  }
}

void BM_OnlineStep(benchmark::State& state) {
  DeformationGraph graph = make_graph(static_cast<int>(state.range(0)));
  add_online_constraints(&graph, 256);
  graph.solve(1);  // analyses the pattern
  SolveStats stats;
  for (auto _ : state) {
    stats = graph.solve(1);
    benchmark::DoNotOptimize(stats.after.total());
  }
  state.counters["nodes"] = static_cast<double>(graph.size());
  state.counters["analyses"] = static_cast<double>(graph.analyses());
  state.counters["assemble_ms"] = stats.assemble_ms;
  state.counters["factorize_ms"] = stats.factorize_ms;
  state.counters["nonzeros"] = static_cast<double>(stats.nonzeros);
}
BENCHMARK(BM_OnlineStep)->Arg(100)->Arg(500)->Arg(1000)->Unit(benchmark::kMillisecond);

void BM_OnlineStepNewNode(benchmark::State& state) {
  for (auto _ : state) {
    state.PauseTiming();
    DeformationGraph graph = make_graph(static_cast<int>(state.range(0)) - 1);
    add_online_constraints(&graph, 256);
    graph.solve(1);
    const Eigen::Vector3d next = graph.node(static_cast<int>(graph.size()) - 1).position + Eigen::Vector3d(0, kSpacing, 0);
    state.ResumeTiming();
    graph.add_node(next, 1 << 20);
    const SolveStats stats = graph.solve(1);
    benchmark::DoNotOptimize(stats.after.total());
  }
}
BENCHMARK(BM_OnlineStepNewNode)->Arg(500)->Unit(benchmark::kMillisecond);

void BM_LoopClosure(benchmark::State& state) {
  const int nodes = static_cast<int>(state.range(0));
  const Pose correction(Eigen::AngleAxisd(0.0025, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                        Eigen::Vector3d(30e-6, -20e-6, 10e-6));
  for (auto _ : state) {
    state.PauseTiming();
    DeformationGraph graph = make_graph(nodes);
    add_online_constraints(&graph, 256);
    graph.solve(1);
    state.ResumeTiming();
    const int last = nodes - 1;
    for (int i = 0; i < 2000; ++i) {
      Constraint c;
      c.source = scatter(graph.node(last).position, i, 5e-3);
      c.source_binding = graph.bind_before(c.source, graph.node(last).time);
      c.target = correction * c.source;
      graph.add_constraint(c);
    }
    const SolveStats stats = graph.solve(3);
    benchmark::DoNotOptimize(stats.after.total());
  }
  state.counters["nodes"] = nodes;
}
BENCHMARK(BM_LoopClosure)->Arg(100)->Arg(500)->Unit(benchmark::kMillisecond);

void BM_DeformMap(benchmark::State& state) {
  DeformationGraph graph = make_graph(500);
  add_online_constraints(&graph, 256);
  graph.solve(2);
  const std::vector<NodeTransform> transforms = graph.transforms();
  const auto count = static_cast<std::size_t>(state.range(0));
  const int last = static_cast<int>(graph.size()) - 1;
  PointCloud from;
  from.positions.resize(count);
  from.normals.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    // Around the last 8 nodes, as a part of the map observed there is.
    const Eigen::Vector3d p = scatter(graph.node(last - static_cast<int>(i % 8)).position, static_cast<int>(i), 2e-3);
    from.positions[i] = p.cast<float>();
    from.normals[i] = Eigen::Vector3d(p.x(), p.y(), 0.0).normalized().cast<float>();
  }
  PointCloud to = from;
  std::vector<float> moved;
  for (auto _ : state) {
    deform_cloud_part(graph, transforms, graph.node(last).time, from, 0, count, &to, 0, &moved);
    benchmark::DoNotOptimize(to.positions.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(count));
}
BENCHMARK(BM_DeformMap)->Arg(1 << 20)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_MatchVertices(benchmark::State& state) {
  const auto count = static_cast<std::size_t>(state.range(0));
  PointCloud cloud, vertices;
  for (std::size_t i = 0; i < count; ++i) {
    const Eigen::Vector3f p = scatter(Eigen::Vector3d::Zero(), static_cast<int>(i), 5e-3).cast<float>();
    const Eigen::Vector3f n = Eigen::Vector3f(p.x(), p.y(), 1.0f).normalized();
    if (i % 50 != 7) {
      cloud.positions.push_back(p);
      cloud.normals.push_back(n);
    }
    if (i % 40 != 3) {
      vertices.positions.push_back(p);
      vertices.normals.push_back(n);
    }
  }
  std::vector<std::int64_t> same(vertices.size());
  for (auto _ : state) {
    match_vertices_to_points(vertices, 0, vertices.size(), cloud, 0, cloud.size(), 0, same.data());
    benchmark::DoNotOptimize(same.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(vertices.size()));
}
BENCHMARK(BM_MatchVertices)->Arg(1 << 20)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace sls::fusion::deformation

BENCHMARK_MAIN();
