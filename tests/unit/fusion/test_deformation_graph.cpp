// The embedded deformation graph (fusion/deformation) against known answers: a rigid motion
// and a bend recovered from point constraints, a loop's correction spread along a chain,
// the Jacobians the solver uses against finite differences of its residuals, determinism,
// CHOLMOD's analysis reused while the pattern holds, map deformation equal to the graph's own
// per-point deformation, poses turned to their rotation priors (a turntable's angles), and the
// errors a caller can cause (too few nodes, a disconnected graph, a singular system, bad
// constraints or priors). CHOLMOD's wrapper: test_sparse_cholesky.cpp.
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "fusion/deformation/deformation_graph.h"
#include "fusion/deformation/map_deformation.h"
#include "sdk/core/error.h"
#include "tests/support/test_support.h"

namespace sls::fusion::deformation {
namespace {

constexpr double kSpacing = 1e-3;  // 1 mm between nodes

GraphOptions options_for_tests() {
  GraphOptions options;
  options.length_scale_m = kSpacing;
  return options;
}

// Nodes along an arc of radius 16 mm (a turntable's focus points), one per `step_deg`.
DeformationGraph arc_graph(int nodes, const GraphOptions& options, double radius_m = 16e-3) {
  DeformationGraph graph(options);
  const double step = kSpacing / radius_m;
  for (int j = 0; j < nodes; ++j) {
    graph.add_node(Eigen::Vector3d(radius_m * std::cos(j * step), radius_m * std::sin(j * step), 0.0), 3 * j);
  }
  return graph;
}

// Points scattered around node j (within half a spacing), deterministic.
std::vector<Eigen::Vector3d> points_near(const DeformationGraph& graph, int j, int count) {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < count; ++i) {
    const double a = 0.7 * i, b = 1.3 * i;
    points.push_back(graph.node(j).position +
                     0.5 * kSpacing * Eigen::Vector3d(std::sin(a), std::cos(b), std::sin(a + b)));
  }
  return points;
}

Pose rigid_motion() {
  return Pose(Eigen::AngleAxisd(0.02, Eigen::Vector3d(0.3, -0.5, 1.0).normalized()).toRotationMatrix(),
              Eigen::Vector3d(120e-6, -80e-6, 40e-6));
}

TEST(DeformationGraph, RecoversARigidMotion) {
  DeformationGraph graph = arc_graph(12, options_for_tests());
  const Pose motion = rigid_motion();
  // The pinned nodes hold the motion; constraints pull every other node's surroundings.
  for (int j = 0; j < graph.pinned_count(); ++j) {
    graph.set_transform(j, motion.rotation(), motion * graph.node(j).position - graph.node(j).position);
  }
  for (int j = 2; j < 12; ++j) {
    for (const Eigen::Vector3d& p : points_near(graph, j, 6)) {
      Constraint c;
      c.source = p;
      c.source_binding = graph.bind_around(p, graph.node(j).time);
      c.target = motion * p;
      graph.add_constraint(c);
    }
  }
  const SolveStats stats = graph.solve(5);
  EXPECT_GT(stats.iterations, 0);
  EXPECT_LT(stats.after.total(), 1e-16);
  for (int j = 0; j < 12; ++j) {
    const Node& node = graph.node(j);
    EXPECT_LT((node.A - motion.rotation()).norm(), 1e-7) << "node " << j;
    EXPECT_LT((node.position + node.t - motion * node.position).norm(), 1e-10) << "node " << j;
  }
  // Deformed points, normals and poses follow the motion exactly.
  const Eigen::Vector3d p = graph.node(7).position + Eigen::Vector3d(1e-4, 2e-4, -3e-4);
  const NodeBinding binding = graph.bind_around(p, graph.node(7).time);
  EXPECT_LT((graph.deform(p, binding) - motion * p).norm(), 1e-10);
  const Eigen::Vector3d n = Eigen::Vector3d(0.2, 0.3, 0.9).normalized();
  EXPECT_LT((graph.deform_normal(n, binding) - motion.rotation() * n).norm(), 1e-7);
  const Pose camera(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()).toRotationMatrix(), Eigen::Vector3d(0, 0, -0.1));
  const Pose deformed = graph.deform_pose(camera, p, binding);
  EXPECT_TRUE(deformed.is_approx(motion * camera, 1e-8));
}

// A beam along x bent about z: rotation θ(x) = κ x, the exact field x ↦ bend(x). Constraints
// sample it; node 0 (θ = 0, no displacement) is the only pin.
Eigen::Vector3d bend(const Eigen::Vector3d& p, double curvature) {
  const double theta = curvature * p.x();
  const double r = 1.0 / curvature;
  return Eigen::Vector3d(std::sin(theta) * (r - p.y()), r - std::cos(theta) * (r - p.y()), p.z());
}

TEST(DeformationGraph, RecoversABend) {
  GraphOptions options = options_for_tests();
  options.pinned_nodes = 1;
  DeformationGraph graph(options);
  const int nodes = 16;
  for (int j = 0; j < nodes; ++j) graph.add_node(Eigen::Vector3d(j * kSpacing, 0.0, 0.0), j);
  const double curvature = 10.0;  // 1/m: a radius of 0.1 m, the 15 mm beam's tip turns 8.6°
  double max_displacement = 0.0;
  for (int j = 1; j < nodes; ++j) {
    for (const Eigen::Vector3d& p : points_near(graph, j, 8)) {
      Constraint c;
      c.source = p;
      c.source_binding = graph.bind_around(p, j);
      c.target = bend(p, curvature);
      max_displacement = std::max(max_displacement, (c.target - p).norm());
      graph.add_constraint(c);
    }
  }
  graph.solve(6);
  double worst = 0.0;
  for (const Constraint& c : graph.constraints()) {
    worst = std::max(worst, (graph.deform(c.source, c.source_binding) - c.target).norm());
  }
  // E_reg is not zero on the exact bend (a chord against a rotated tangent), so the fit is
  // close, not exact: within 1 % of the largest displacement (1.1 mm here).
  EXPECT_LT(worst, 0.01 * max_displacement) << "worst " << worst << " of " << max_displacement;
  for (int j = 1; j < nodes; ++j) {
    const Eigen::AngleAxisd turned(Eigen::Matrix3d(graph.node(j).A));
    const double expected = curvature * graph.node(j).position.x();
    // The ends have neighbours on one side only: the tip turns 6 % further (E_reg's chord
    // mismatch), node 1 30 % less (the pinned node 0 holds its part of the bend at zero).
    const double tolerance = j == nodes - 1 ? 0.08 : j == 1 ? 0.35 : 0.02;
    EXPECT_NEAR(turned.angle() * turned.axis().z(), expected, tolerance * expected + 1e-4) << "node " << j;
  }
}

// A turntable's loop: nodes on an arc about the axis, the first two pinned, a rotation about
// the axis asked of the view around the last node only (what a loop closure finds). With the
// region term (ρ = 5 mm, half a view) E_reg spreads the rotation along the chain as a drift
// accumulates, nearly linearly; eq. (15) alone (ρ = 0) bends the chain like a beam instead,
// turning its middle nodes by more than the end's share.
TEST(DeformationGraph, SpreadsALoopCorrectionAlongTheChain) {
  const double total = 0.003;  // rad about the arc's axis (z through the origin)
  const Pose correction(Eigen::AngleAxisd(total, Eigen::Vector3d::UnitZ()).toRotationMatrix(), Eigen::Vector3d::Zero());
  const int last = 29;
  const auto solve = [&](double region_radius_m) {
    GraphOptions options = options_for_tests();
    options.region_radius_m = region_radius_m;
    DeformationGraph graph = arc_graph(last + 1, options);
    for (int i = 0; i < 60; ++i) {
      const double a = 0.7 * i, b = 1.3 * i;
      const Eigen::Vector3d p =
          graph.node(last).position + 5e-3 * Eigen::Vector3d(std::sin(a), std::cos(b), 0.3 * std::sin(a + b));
      Constraint c;
      c.source = p;
      c.source_binding = graph.bind_before(p, graph.node(last).time);
      c.target = correction * p;
      graph.add_constraint(c);
    }
    const SolveStats stats = graph.solve(3);
    EXPECT_LT(stats.after.total(), 0.01 * stats.before.total());
    std::vector<double> turned;
    for (int j = 0; j <= last; ++j) {
      const Eigen::AngleAxisd angle_axis(Eigen::Matrix3d(graph.node(j).A));
      turned.push_back(angle_axis.angle() * angle_axis.axis().z());
    }
    const Eigen::Vector3d g = graph.node(last).position;
    EXPECT_LT((g + graph.node(last).t - correction * g).norm(), 1e-6);
    return turned;
  };
  const std::vector<double> spread = solve(5e-3);
  double worst_share = 0.0;
  for (int j = 2; j <= last; ++j) {
    EXPECT_GE(spread[static_cast<std::size_t>(j)], spread[static_cast<std::size_t>(j) - 1]) << "node " << j;
    const double linear = total * (j - 1) / (last - 1);
    worst_share = std::max(worst_share, std::abs(spread[static_cast<std::size_t>(j)] - linear) / total);
  }
  EXPECT_LT(worst_share, 0.12);
  EXPECT_NEAR(spread.back(), total, 0.02 * total);
  // Eq. (15) alone: somewhere in the middle the chain turns further than a linear share.
  const std::vector<double> beam = solve(0.0);
  double beam_share = 0.0;
  for (int j = 2; j <= last; ++j) {
    beam_share = std::max(beam_share, std::abs(beam[static_cast<std::size_t>(j)] - total * (j - 1) / (last - 1)) / total);
  }
  EXPECT_GT(beam_share, 2.0 * worst_share);
}

// The residuals' Jacobian against central differences, in both the fixed-target and the
// two-sided form of E_con (point-to-point), and point-to-plane with a fixed target.
TEST(DeformationGraph, JacobiansMatchFiniteDifferences) {
  GraphOptions options = options_for_tests();
  options.region_radius_m = 4e-3;
  DeformationGraph graph = arc_graph(9, options);
  // Start away from the identity, so that E_rot's and E_reg's Jacobians are general.
  for (int j = 2; j < 9; ++j) {
    Eigen::Matrix3d A = Eigen::AngleAxisd(0.05 * j, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    A(0, 1) += 0.01 * j;
    A(2, 2) *= 1.0 + 0.02 * j;
    graph.set_transform(j, A, Eigen::Vector3d(1e-5 * j, -2e-5, 3e-6 * j));
  }
  for (int j = 1; j < 9; ++j) {
    const std::vector<Eigen::Vector3d> points = points_near(graph, j, 3);
    Constraint fixed;
    fixed.source = points[0];
    fixed.source_binding = graph.bind_around(points[0], graph.node(j).time);
    fixed.target = points[0] + Eigen::Vector3d(1e-5, 2e-5, -1e-5);
    graph.add_constraint(fixed);
    Constraint plane = fixed;
    plane.source = points[1];
    plane.source_binding = graph.bind_around(points[1], graph.node(j).time);
    plane.normal = Eigen::Vector3d(0.3, -0.2, 0.93).normalized();
    plane.weight = 2.5;
    graph.add_constraint(plane);
    Constraint two_sided;
    two_sided.source = points[2];
    two_sided.source_binding = graph.bind_around(points[2], graph.node(j).time);
    two_sided.target = points[2] + Eigen::Vector3d(-3e-5, 1e-5, 0.0);
    two_sided.target_binding = graph.bind_around(two_sided.target, graph.node(8 - j).time);
    graph.add_constraint(two_sided);
  }
  // Pose rotation priors with a full information matrix (a turntable's: stiff about its axis,
  // weaker across), each on the blend of the nodes around its pose, one of them pinned.
  for (int j : {1, 3, 6, 8}) {
    RotationPrior prior;
    prior.rotation = Eigen::AngleAxisd(0.04 * j, Eigen::Vector3d(-1, 2, 1).normalized()).toRotationMatrix();
    const Eigen::Vector3d axis = Eigen::Vector3d(0.2, 0.1, 1.0).normalized();
    prior.information = 4e2 * axis * axis.transpose() + 25.0 * (Eigen::Matrix3d::Identity() - axis * axis.transpose());
    graph.add_rotation_prior(graph.node(j).position + Eigen::Vector3d(2e-4, -1e-4, 3e-4), graph.node(j).time, prior);
  }
  EXPECT_EQ(graph.rotation_priors(), 4u);
  const Eigen::VectorXd x = graph.parameters();
  const Eigen::MatrixXd J = graph.jacobian_dense();
  ASSERT_EQ(J.cols(), x.size());
  ASSERT_EQ(J.rows(), graph.residuals().size());
  const double h = 1e-6;
  double worst = 0.0;
  for (Eigen::Index p = 0; p < x.size(); ++p) {
    Eigen::VectorXd plus = x, minus = x;
    plus[p] += h;
    minus[p] -= h;
    graph.set_parameters(plus);
    const Eigen::VectorXd r_plus = graph.residuals();
    graph.set_parameters(minus);
    const Eigen::VectorXd r_minus = graph.residuals();
    const Eigen::VectorXd numeric = (r_plus - r_minus) / (2.0 * h);
    worst = std::max(worst, (numeric - J.col(p)).cwiseAbs().maxCoeff() / std::max(1.0, J.col(p).cwiseAbs().maxCoeff()));
  }
  graph.set_parameters(x);
  EXPECT_LT(worst, 1e-6);
}

// Rotation priors alone fix what no constraint sees: a chain of poses whose turntable angles
// (stiff about its z axis, free across) disagree with the tracking by a drift that grows
// along the chain: each pose, deformed as deform_pose does (the blend of the nodes around it),
// turns to its table's rotation, the last one too although its blend is one-sided (nodes
// before it only), and the directions the priors leave free stay put.
TEST(DeformationGraph, RotationPriorsTurnThePosesToTheirRotations) {
  constexpr int kNodes = 12;
  const DeformationGraph arc = arc_graph(kNodes, options_for_tests());
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  const double sigma_rad = 3.5e-5;  // a turntable's 0.002°
  const auto drift_rad = [](int j) { return 2e-4 * j + 1e-5 * j * j; };  // faster towards the end
  const auto prior_of = [&](int j) {
    RotationPrior prior;
    prior.rotation = Eigen::AngleAxisd(drift_rad(j), z).toRotationMatrix();
    prior.information = z * z.transpose() / (sigma_rad * sigma_rad);
    return prior;
  };
  // As a scan makes them: each keyframe's node, then its pose's prior (bound again as the
  // nodes after it come) ...
  DeformationGraph graph(options_for_tests());
  for (int j = 0; j < kNodes; ++j) {
    graph.add_node(arc.node(j).position, arc.node(j).time);
    EXPECT_EQ(graph.add_rotation_prior(arc.node(j).position, arc.node(j).time, prior_of(j)), j);
  }
  EXPECT_EQ(graph.rotation_priors(), static_cast<std::size_t>(kNodes));
  const SolveStats stats = graph.solve(4);
  EXPECT_GT(stats.before.rotation_priors, 1e3);
  // ... the same as every prior added once all nodes exist.
  DeformationGraph afterwards = arc_graph(kNodes, options_for_tests());
  for (int j = 0; j < kNodes; ++j) afterwards.add_rotation_prior(arc.node(j).position, arc.node(j).time, prior_of(j));
  afterwards.solve(4);
  EXPECT_EQ(graph.parameters(), afterwards.parameters());
  for (int j = 3; j < kNodes; ++j) {  // the first poses bind the pinned nodes (A = I), which cannot turn
    const Eigen::Vector3d anchor = graph.node(j).position;
    const Pose camera(Eigen::Matrix3d::Identity(), anchor + Eigen::Vector3d(0.116, 0.0, 0.0));
    const Pose deformed = graph.deform_pose(camera, anchor, graph.bind_pose(anchor, graph.node(j).time));
    const Eigen::Matrix3d table = Eigen::AngleAxisd(drift_rad(j), z).toRotationMatrix();
    const Eigen::AngleAxisd off(Eigen::Matrix3d(deformed.rotation() * table.transpose()));
    // Within 2e-4° of the table's, about the axis and (left free, nothing turns it) across.
    EXPECT_LT(off.angle(), 0.1 * sigma_rad) << "pose " << j;
  }
}

// The linear terms' share of the normal equations (E_reg's and the rotation priors') is kept
// while the graph's structure stays: priors added between solves, the nodes and the pattern
// unchanged, count in the next solve as if they had been there from the start.
TEST(DeformationGraph, RotationPriorsAddedBetweenSolvesCountInTheNext) {
  constexpr int kNodes = 12;
  RotationPrior prior;
  prior.information = Eigen::Vector3d::UnitZ() * Eigen::Vector3d::UnitZ().transpose() / (3.5e-5 * 3.5e-5);
  const auto add_priors = [&](DeformationGraph* graph) {
    for (int j = 0; j < kNodes; ++j) {
      prior.rotation = Eigen::AngleAxisd(2e-4 * j, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      graph->add_rotation_prior(graph->node(j).position, graph->node(j).time, prior);
    }
  };
  DeformationGraph graph = arc_graph(kNodes, options_for_tests());
  const Eigen::VectorXd rest = graph.parameters();
  graph.solve(2);  // nothing to correct: analysed, and the linear share kept, at rest
  EXPECT_EQ(graph.parameters(), rest);
  add_priors(&graph);
  const SolveStats stats = graph.solve(4);
  EXPECT_GT(stats.before.rotation_priors, 1e3);
  EXPECT_LT(stats.after.rotation_priors, 1e-2 * stats.before.rotation_priors);
  DeformationGraph from_the_start = arc_graph(kNodes, options_for_tests());
  add_priors(&from_the_start);
  from_the_start.solve(4);
  EXPECT_EQ(graph.parameters(), from_the_start.parameters());
}

// A solve's energy before its first step comes from two walks (the linear terms' alone, and the first
// assembly's of the other terms): it is the graph's energy, term by term and bit for bit, for
// every term at once (point-to-plane constraints with deformed targets, rotation priors), and
// after a step as before it.
TEST(DeformationGraph, TheEnergyBeforeAStepIsTheGraphsToTheLastBit) {
  constexpr int kNodes = 16;
  DeformationGraph graph = arc_graph(kNodes, options_for_tests());
  RotationPrior prior;
  prior.information = Eigen::Matrix3d::Identity() * 1e6;
  for (int j = 0; j < kNodes; ++j) {
    prior.rotation = Eigen::AngleAxisd(1e-4 * j, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    graph.add_rotation_prior(graph.node(j).position, graph.node(j).time, prior);
  }
  for (int i = 0; i < 40; ++i) {
    const double a = 0.7 * i, b = 1.3 * i;
    Constraint c;
    c.source = graph.node(kNodes - 1).position + 3e-3 * Eigen::Vector3d(std::sin(a), std::cos(b), 0.3 * std::sin(a + b));
    c.source_binding = graph.bind_before(c.source, graph.node(kNodes - 1).time);
    c.target = c.source + Eigen::Vector3d(20e-6, -10e-6, 5e-6);
    c.target_binding = graph.bind_around(c.target, graph.node(kNodes / 2).time);
    c.normal = Eigen::Vector3d(std::cos(a), std::sin(a), 0.2).normalized();
    graph.add_constraint(c);
  }
  for (int solve = 0; solve < 2; ++solve) {
    const EnergyTerms expected = graph.energy();
    const SolveStats stats = graph.solve(1);
    EXPECT_EQ(stats.before.rotation, expected.rotation) << "solve " << solve;
    EXPECT_EQ(stats.before.regularization, expected.regularization) << "solve " << solve;
    EXPECT_EQ(stats.before.constraints, expected.constraints) << "solve " << solve;
    EXPECT_EQ(stats.before.rotation_priors, expected.rotation_priors) << "solve " << solve;
    EXPECT_GT(expected.constraints, 0.0);
    EXPECT_GT(expected.rotation_priors, 0.0);
    EXPECT_LT(stats.after.total(), stats.before.total());
  }
}

TEST(DeformationGraph, RefusesBadRotationPriors) {
  DeformationGraph empty(options_for_tests());
  RotationPrior good;
  good.information = Eigen::Matrix3d::Identity();
  EXPECT_THROW(empty.add_rotation_prior(Eigen::Vector3d::Zero(), 0, good), Error);  // no node yet
  DeformationGraph graph = arc_graph(4, options_for_tests());
  const Eigen::Vector3d anchor = graph.node(2).position;
  EXPECT_THROW(graph.add_rotation_prior(Eigen::Vector3d(0.0, std::nan(""), 0.0), 6, good), Error);
  RotationPrior scaled = good;
  scaled.rotation *= 1.01;
  EXPECT_THROW(graph.add_rotation_prior(anchor, 6, scaled), Error);
  RotationPrior reflected = good;
  reflected.rotation(2, 2) = -1.0;
  EXPECT_THROW(graph.add_rotation_prior(anchor, 6, reflected), Error);
  RotationPrior indefinite = good;
  indefinite.information(1, 1) = -1.0;
  EXPECT_THROW(graph.add_rotation_prior(anchor, 6, indefinite), Error);
  RotationPrior asymmetric = good;
  asymmetric.information(0, 1) = 0.5;
  EXPECT_THROW(graph.add_rotation_prior(anchor, 6, asymmetric), Error);
  RotationPrior infinite = good;
  infinite.information(0, 0) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(graph.add_rotation_prior(anchor, 6, infinite), Error);
  EXPECT_EQ(graph.rotation_priors(), 0u);
  EXPECT_EQ(graph.add_rotation_prior(anchor, 6, good), 0);
  EXPECT_EQ(graph.rotation_priors(), 1u);
}

// Two graphs built and solved the same way give the same bits.
TEST(DeformationGraph, IsDeterministic) {
  const auto run = [] {
    DeformationGraph graph = arc_graph(40, options_for_tests());
    const Pose correction(Eigen::AngleAxisd(0.002, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                          Eigen::Vector3d(100e-6, 0, 0));
    for (int j = 20; j < 40; j += 3) {
      for (const Eigen::Vector3d& p : points_near(graph, j, 10)) {
        Constraint c;
        c.source = p;
        c.source_binding = graph.bind_before(p, graph.node(j).time);
        c.target = correction * p;
        c.normal = Eigen::Vector3d(p.x(), p.y(), 0.0).normalized();
        graph.add_constraint(c);
      }
      graph.solve(2);
    }
    return graph.parameters();
  };
  const Eigen::VectorXd a = run(), b = run();
  ASSERT_EQ(a.size(), b.size());
  for (Eigen::Index i = 0; i < a.size(); ++i) ASSERT_EQ(a[i], b[i]) << "parameter " << i;
}

TEST(DeformationGraph, ReusesTheAnalysisWhileThePatternHolds) {
  DeformationGraph graph = arc_graph(20, options_for_tests());
  const Eigen::Vector3d p = graph.node(19).position;
  Constraint c;
  c.source = p;
  c.source_binding = graph.bind_before(p, graph.node(19).time);
  c.target = p + Eigen::Vector3d(1e-5, 0, 0);
  graph.add_constraint(c);
  EXPECT_TRUE(graph.solve(2).analyzed);
  EXPECT_EQ(graph.analyses(), 1u);
  // Same structure, other values: no new analysis.
  graph.clear_constraints();
  c.target = p + Eigen::Vector3d(0, 2e-5, 0);
  graph.add_constraint(c);
  EXPECT_FALSE(graph.solve(2).analyzed);
  EXPECT_EQ(graph.analyses(), 1u);
  EXPECT_GE(graph.factorizations(), 3u);
  // A constraint coupling the end to the start (a loop) needs new blocks: analysed again,
  // then reused.
  Constraint loop = c;
  loop.target = graph.node(2).position;
  loop.target_binding = graph.bind_before(loop.target, graph.node(3).time);
  graph.add_constraint(loop);
  EXPECT_TRUE(graph.solve(1).analyzed);
  EXPECT_FALSE(graph.solve(1).analyzed);
  // A new node: more unknowns, analysed again.
  graph.add_node(graph.node(19).position + Eigen::Vector3d(kSpacing, 0, 0), 100);
  EXPECT_TRUE(graph.solve(1).analyzed);
  EXPECT_EQ(graph.analyses(), 3u);
}

// Constraints replaced by others whose blocks lie inside the kept pattern (no new analysis)
// count in full: the blocks a step assembles follow the constraints of that step, not those of
// the step that analysed the pattern.
TEST(DeformationGraph, ConstraintsReplacedWithinThePatternCountInFull) {
  const auto constraints_near = [](DeformationGraph* graph, int j) {
    graph->clear_constraints();
    for (const Eigen::Vector3d& p : points_near(*graph, j, 12)) {
      Constraint c;
      c.source = p;
      c.source_binding = graph->bind_before(p, graph->node(j).time);
      c.target = p + Eigen::Vector3d(12e-6, -6e-6, 3e-6);
      graph->add_constraint(c);
    }
  };
  DeformationGraph graph = arc_graph(20, options_for_tests());
  constraints_near(&graph, 10);  // the pattern holds node 10's neighbourhood's blocks...
  graph.solve(1);
  constraints_near(&graph, 19);  // ...and then node 19's
  graph.solve(1);
  constraints_near(&graph, 10);  // node 10's again: inside the pattern
  DeformationGraph fresh = arc_graph(20, options_for_tests());
  constraints_near(&fresh, 10);
  fresh.set_parameters(graph.parameters());
  const SolveStats stats = graph.solve(1);
  EXPECT_FALSE(stats.analyzed);
  EXPECT_EQ(stats.iterations, 1);
  fresh.solve(1);
  const Eigen::VectorXd a = graph.parameters(), b = fresh.parameters();
  ASSERT_EQ(a.size(), b.size());
  // The same step up to the rounding of another pattern's order.
  for (Eigen::Index i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i], b[i], 1e-10) << "parameter " << i;
}

TEST(DeformationGraph, LinksFollowTimeAndSpace) {
  GraphOptions options = options_for_tests();
  DeformationGraph graph(options);
  // Back and forth along x: node 4 comes back next to node 0..2 but only the recent window's
  // close nodes link; node 12, far later and next to node 0, does not link to it.
  const double xs[] = {0, 1, 2, 3, 2.2, 1.1, 0.1, 1, 2, 3, 4, 5, 0.05};
  for (int j = 0; j < 13; ++j) graph.add_node(Eigen::Vector3d(xs[j] * kSpacing, 0, 0), j);
  const auto linked = [&graph](int a, int b) {
    for (const auto& [j, k] : graph.edges()) {
      if ((j == a && k == b) || (j == b && k == a)) return true;
    }
    return false;
  };
  for (int j = 1; j < 13; ++j) EXPECT_TRUE(linked(j - 1, j)) << "temporal link " << j;
  EXPECT_TRUE(linked(2, 4));    // 0.2 mm apart, two nodes back
  EXPECT_TRUE(linked(1, 5));    // 0.1 mm apart, four back
  EXPECT_FALSE(linked(0, 12));  // 0.05 mm apart but 12 nodes back: a revisit, not a link
  EXPECT_FALSE(linked(3, 12));
}

// An arc of 16 nodes bent more and more along it (the first two pinned), and points with
// normals near each node: a map to deform.
struct BentMap {
  DeformationGraph graph;
  PointCloud cloud;
};
BentMap bent_map() {
  BentMap map{arc_graph(16, options_for_tests()), {}};
  for (int j = 2; j < 16; ++j) {
    map.graph.set_transform(j, Eigen::AngleAxisd(0.001 * j, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                            Eigen::Vector3d(2e-6 * j * j, -1e-6 * j, 0.0));
  }
  for (int j = 0; j < 16; ++j) {
    for (const Eigen::Vector3d& p : points_near(map.graph, j, 5)) {
      map.cloud.positions.push_back(p.cast<float>());
      map.cloud.normals.push_back(Eigen::Vector3f(0.0f, 0.6f, 0.8f));
    }
  }
  return map;
}

TEST(DeformationGraph, MapDeformationEqualsThePerPointDeformation) {
  BentMap map = bent_map();
  const DeformationGraph& graph = map.graph;
  PointCloud& cloud = map.cloud;
  const PointCloud original = cloud;
  const int time = graph.node(11).time;
  std::vector<float> displacement;
  deform_cloud_part(graph, graph.transforms(), time, &cloud, 10, 60, &displacement);
  ASSERT_EQ(displacement.size(), cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = original.positions[i].cast<double>();
    if (i < 10 || i >= 60) {
      EXPECT_EQ(cloud.positions[i], original.positions[i]);
      EXPECT_EQ(displacement[i], 0.0f);
      continue;
    }
    const NodeBinding binding = graph.bind_before(p, time);
    const Eigen::Vector3d expected = graph.deform(p, binding);
    EXPECT_LT((cloud.positions[i].cast<double>() - expected).norm(), 1e-9) << i;
    EXPECT_NEAR(displacement[i], (expected - p).norm(), 1e-9);
    const Eigen::Vector3d n = graph.deform_normal(original.normals[i].cast<double>(), binding);
    EXPECT_LT((cloud.normals[i].cast<double>() - n).norm(), 1e-6) << i;
  }
}

// The model deformed as it is joined (ScanSession's final model): read from one cloud, written
// into another at an offset, the same points to the bit as deformed in place; a destination
// too small, or without normals for a source that has them, is refused.
TEST(DeformationGraph, MapDeformationIntoAnotherCloudEqualsInPlace) {
  const BentMap map = bent_map();
  const DeformationGraph& graph = map.graph;
  const PointCloud& source = map.cloud;
  const int time = graph.node(11).time;
  const std::vector<NodeTransform> transforms = graph.transforms();
  PointCloud in_place = source;
  std::vector<float> displacement_in_place;
  deform_cloud_part(graph, transforms, time, &in_place, 10, 60, &displacement_in_place);
  PointCloud into;
  into.positions.assign(source.size() + 7, Eigen::Vector3f::Constant(-1.0f));
  into.normals.assign(source.size() + 7, Eigen::Vector3f::Zero());
  std::vector<float> displacement;
  deform_cloud_part(graph, transforms, time, source, 10, 60, &into, 17, &displacement);
  ASSERT_EQ(displacement.size(), into.size());
  for (std::size_t i = 0; i < into.size(); ++i) {
    if (i < 17 || i >= 67) {
      EXPECT_EQ(into.positions[i], Eigen::Vector3f::Constant(-1.0f)) << i;  // outside the range: untouched
      EXPECT_EQ(displacement[i], 0.0f);
      continue;
    }
    EXPECT_EQ(into.positions[i], in_place.positions[i - 7]) << i;
    EXPECT_EQ(into.normals[i], in_place.normals[i - 7]) << i;
    EXPECT_EQ(displacement[i], displacement_in_place[i - 7]) << i;
  }
  PointCloud small;
  small.positions.resize(40);
  small.normals.resize(40);
  EXPECT_EQ(test::code_of([&] { deform_cloud_part(graph, transforms, time, source, 10, 60, &small, 0); }),
            ErrorCode::kInvalidArgument);
  PointCloud no_normals;
  no_normals.positions.resize(source.size());
  EXPECT_EQ(test::code_of([&] { deform_cloud_part(graph, transforms, time, source, 10, 60, &no_normals, 0); }),
            ErrorCode::kInvalidArgument);
}

// A mesh's vertices are mostly its cloud's points (ScanSession's final model): one walk finds
// every one, across single gaps and runs of 5 and 50 of either side's own, never pairs two
// that differ (a normal differing alone), and the vertices deformed through the shared points
// are, to the bit, what deforming each vertex gives.
TEST(DeformationGraph, VerticesThatArePointsTakeThePointsDeformedValues) {
  BentMap map = bent_map();
  const DeformationGraph& graph = map.graph;
  const int time = graph.node(11).time;
  const std::vector<NodeTransform> transforms = graph.transforms();
  // One extraction's crossings in order: 40 around each node.
  std::vector<Eigen::Vector3f> crossings;
  for (int j = 0; j < 16; ++j) {
    for (const Eigen::Vector3d& p : points_near(graph, j, 40)) crossings.push_back(p.cast<float>());
  }
  const auto normal_of = [](std::size_t n) {
    return Eigen::Vector3f(0.0f, 0.6f, 0.8f + 1e-3f * static_cast<float>(n % 7)).normalized();
  };
  // The cloud's own: a single one, a run of 5, a run of 50; the mesh's own likewise elsewhere;
  // one crossing in both with a different normal in the mesh.
  const auto in = [](std::size_t n, std::size_t from, std::size_t count) { return n >= from && n < from + count; };
  PointCloud cloud, vertices;
  std::vector<std::size_t> cloud_crossing, vertex_crossing;  // each point's and vertex's crossing
  const std::size_t odd_normal = 300;
  for (std::size_t n = 0; n < crossings.size(); ++n) {
    const bool cloud_only = n == 17 || in(n, 100, 5) || in(n, 200, 50);
    const bool mesh_only = n == 23 || in(n, 400, 5) || in(n, 500, 50);
    if (!mesh_only) {
      cloud.positions.push_back(crossings[n]);
      cloud.normals.push_back(normal_of(n));
      cloud_crossing.push_back(n);
    }
    if (!cloud_only) {
      vertices.positions.push_back(crossings[n]);
      vertices.normals.push_back(n == odd_normal ? Eigen::Vector3f(1.0f, 0.0f, 0.0f) : normal_of(n));
      vertex_crossing.push_back(n);
    }
  }
  // The parts sit at offsets in their arrays and in the model, as the shipped parts do.
  const std::size_t cloud_from = 3, cloud_end = cloud.size() - 2, mesh_from = 5, mesh_end = vertices.size() - 4;
  const std::size_t cloud_to = 11;
  std::vector<std::int64_t> same(mesh_end - mesh_from, -7);
  match_vertices_to_points(vertices, mesh_from, mesh_end, cloud, cloud_from, cloud_end, cloud_to, same.data());
  std::size_t matched = 0;
  for (std::size_t i = 0; i < same.size(); ++i) {
    if (same[i] < 0) {
      EXPECT_EQ(same[i], -1) << i;
      continue;
    }
    ++matched;
    const auto c = static_cast<std::size_t>(same[i]) - cloud_to + cloud_from;
    ASSERT_GE(c, cloud_from);
    ASSERT_LT(c, cloud_end);
    EXPECT_EQ(vertices.positions[mesh_from + i], cloud.positions[c]) << i;
    EXPECT_EQ(vertices.normals[mesh_from + i], cloud.normals[c]) << i;
  }
  // Every crossing both parts hold is found (but the one whose normal differs).
  std::size_t shared = 0;
  for (std::size_t v = mesh_from; v < mesh_end; ++v) {
    for (std::size_t c = cloud_from; c < cloud_end; ++c) {
      shared += cloud_crossing[c] == vertex_crossing[v] && vertex_crossing[v] != odd_normal ? 1u : 0u;
    }
  }
  EXPECT_EQ(matched, shared);
  EXPECT_GT(shared, 500u);

  // Deformed through the shares and deformed one by one: the same bits; a share out of range
  // only costs the share.
  PointCloud model;
  model.positions.assign(cloud.size() + cloud_to, Eigen::Vector3f::Zero());
  model.normals.assign(cloud.size() + cloud_to, Eigen::Vector3f::Zero());
  deform_cloud_part(graph, transforms, time, cloud, cloud_from, cloud_end, &model, cloud_to);
  same[1] = static_cast<std::int64_t>(model.size()) + 5;
  PointCloud shared_mesh = vertices, each_mesh = vertices;
  deform_vertices_part(graph, transforms, time, vertices, mesh_from, mesh_end, &shared_mesh, mesh_from, same.data(),
                       model);
  deform_cloud_part(graph, transforms, time, vertices, mesh_from, mesh_end, &each_mesh, mesh_from);
  for (std::size_t v = 0; v < vertices.size(); ++v) {
    EXPECT_EQ(shared_mesh.positions[v], each_mesh.positions[v]) << v;
    EXPECT_EQ(shared_mesh.normals[v], each_mesh.normals[v]) << v;
  }
  EXPECT_NE(shared_mesh.positions[mesh_from + 10], vertices.positions[mesh_from + 10]);  // moved at all

  EXPECT_EQ(test::code_of([&] {
              match_vertices_to_points(vertices, mesh_from, vertices.size() + 1, cloud, cloud_from, cloud_end, 0,
                                       same.data());
            }),
            ErrorCode::kInvalidArgument);
  EXPECT_EQ(test::code_of([&] {
              match_vertices_to_points(vertices, mesh_from, mesh_end, cloud, cloud_end, cloud_from, 0, same.data());
            }),
            ErrorCode::kInvalidArgument);
  PointCloud no_normals;
  no_normals.positions = model.positions;
  EXPECT_EQ(test::code_of([&] {
              deform_vertices_part(graph, transforms, time, vertices, mesh_from, mesh_end, &shared_mesh, mesh_from,
                                   same.data(), no_normals);
            }),
            ErrorCode::kInvalidArgument);
}

TEST(DeformationGraph, BindsToTheNodesOfItsTime) {
  DeformationGraph graph = arc_graph(40, options_for_tests(), 5e-3);  // about one turn
  // A point next to node 1 (and to the turn's last nodes): bound before frame 9 it takes
  // the first nodes, bound at the end the last ones.
  const Eigen::Vector3d p = graph.node(1).position;
  const NodeBinding early = graph.bind_before(p, graph.node(3).time);
  const NodeBinding late = graph.bind_before(p, graph.node(39).time);
  for (int i = 0; i < early.count; ++i) EXPECT_LE(early.nodes[i], 3);
  for (int i = 0; i < late.count; ++i) EXPECT_GE(late.nodes[i], 32);
  double sum = 0.0;
  for (int i = 0; i < early.count; ++i) sum += early.weights[i];
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_EQ(early.count, options_for_tests().nearest_nodes);
}

TEST(DeformationGraph, RefusesTooFewNodes) {
  DeformationGraph graph(options_for_tests());
  EXPECT_THROW(graph.solve(1), Error);
  graph.add_node(Eigen::Vector3d::Zero(), 0);
  graph.add_node(Eigen::Vector3d(kSpacing, 0, 0), 1);
  try {
    graph.solve(1);
    FAIL() << "solved a graph whose nodes are all pinned";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("too few nodes"), std::string::npos) << error.what();
  }
}

TEST(DeformationGraph, RefusesADisconnectedGraph) {
  GraphOptions options = options_for_tests();
  options.max_link_distance_m = 5 * kSpacing;
  DeformationGraph graph(options);
  for (int j = 0; j < 4; ++j) graph.add_node(Eigen::Vector3d(j * kSpacing, 0, 0), j);
  for (int j = 0; j < 3; ++j) graph.add_node(Eigen::Vector3d(50e-3 + j * kSpacing, 0, 0), 10 + j);  // a jump of 47 mm
  try {
    graph.solve(1);
    FAIL() << "solved a disconnected graph";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("disconnected"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("4-6"), std::string::npos) << error.what();
  }
}

TEST(DeformationGraph, RefusesASingularSystemAndKeepsItsNodes) {
  GraphOptions options = options_for_tests();
  options.pinned_nodes = 1;
  options.damping = 0.0;
  DeformationGraph graph(options);
  graph.add_node(Eigen::Vector3d::Zero(), 0);
  graph.add_node(Eigen::Vector3d(kSpacing, 0, 0), 1);  // its rotation about the link: free
  const Eigen::VectorXd before = graph.parameters();
  try {
    graph.solve(1);
    FAIL() << "solved a singular system";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(std::string(error.what()).find("singular"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("node 1"), std::string::npos) << error.what();
  }
  EXPECT_EQ(graph.parameters(), before);
  // With the default damping the same graph solves (the free rotation stays where it is).
  GraphOptions damped = options;
  damped.damping = GraphOptions{}.damping;
  DeformationGraph fine(damped);
  fine.add_node(Eigen::Vector3d::Zero(), 0);
  fine.add_node(Eigen::Vector3d(kSpacing, 0, 0), 1);
  EXPECT_NO_THROW(fine.solve(1));
}

TEST(DeformationGraph, RefusesBadInput) {
  GraphOptions no_nodes;
  no_nodes.nearest_nodes = 0;
  EXPECT_THROW(DeformationGraph{no_nodes}, Error);
  GraphOptions bad_scale;
  bad_scale.length_scale_m = 0.0;
  EXPECT_THROW(DeformationGraph{bad_scale}, Error);
  DeformationGraph graph = arc_graph(4, options_for_tests());
  EXPECT_THROW(graph.add_node(Eigen::Vector3d::Zero(), 0), Error);  // time goes back
  EXPECT_THROW(graph.add_node(Eigen::Vector3d(NAN, 0, 0), 100), Error);
  Constraint c;
  c.source_binding = graph.bind_before(Eigen::Vector3d::Zero(), 100);
  c.weight = 0.0;
  EXPECT_THROW(graph.add_constraint(c), Error);
  c.weight = 1.0;
  c.source_binding.nodes[0] = 17;
  EXPECT_THROW(graph.add_constraint(c), Error);
  c.source_binding.count = 0;
  EXPECT_THROW(graph.add_constraint(c), Error);  // bound to nothing
}

}  // namespace
}  // namespace sls::fusion::deformation
