// The embedded deformation graph of the paper's section IV (Sumner et al. 2007; DESIGN.md
// section 3): nodes made at keyframes, each with a position g_j (where the scan was looking:
// the volume's focus point), an affine A_j and a translation t_j; the graph deforms a point v
// near its nodes by eq. (18) (deform_shared.h). Its energy
//
//   E = w_rot Σ_j ‖A_jᵀA_j − I‖²_F                                          (14)
//     + γ Σ_j Σ_{k∈N(j)} (‖A_j(g_k − g_j) + g_j + t_j − (g_k + t_k)‖²
//                         + ρ²/3 ‖A_j − A_k‖²_F) / L²                       (15, 16)
//     + w_con Σ_l c_l ‖ṽ_l − q̃_l‖² / L²   (or (n_lᵀ(ṽ_l − q̃_l))² / L²)       (17)
//     + Σ_p φ_pᵀ Λ_p φ_p,  φ_p = vee(skew(B_p C_pᵀ)), B_p = Σ_i w_i A_i          (pose priors)
//
// The last term is not the paper's: a pose may carry a prior on its rotation, from a sensor
// that measures it without drift — a turntable's angle since the first frame, to the table's
// repeatability. B_p is the blend of A over the nodes that deform the pose (bind_pose at its
// anchor: what deform_pose turns it by, to first order), C_p the correction the sensor asks
// (left of the tracked pose) and Λ_p its information (rad⁻², PosePrior::information()); φ_p
// is B_p C_pᵀ's rotation vector to first order (exact as a function of A, and linear in it).
// Tracking's drift wanders slowly about the axis while the table's angles scatter
// independently by their σ, so the priors hold the middle of a revolution, which the loop
// closure's constraints at its end cannot (docs/benchmarks.md). The prior is on the blend,
// not on one node: at a scan's end the blend is one-sided, and a node pinned to its own
// keyframe's correction leaves the last poses short of theirs by the drift's slope.
//
// E_reg asks neighbouring nodes to deform their neighbour's surroundings alike: eq. (15)
// compares them at g_k alone; with a region radius ρ > 0 they are compared over the ball of
// radius ρ around g_k (the mean over its six points g_k ± ρ e_i is exactly the sum above).
// Eq. (15) alone (ρ = 0) prices a change of rotation only through the short offsets between
// nodes: a correction asked at the end of a chain then bends it like a beam, turning its
// middle by more than its end (tests/unit/fusion/test_deformation_graph.cpp) — harmless for
// the surface next to the nodes, wrong for a camera 100 mm from its node. A keyframe's pose
// is known from ICP over its view, so its rotation to about σ / (half the view) against a
// translation to σ: the session sets ρ to half the volume's extent, and a drift spreads
// along the scan as it accumulated, rotation and translation alike.
//
// is minimised by Gauss–Newton over the unpinned nodes' 12 parameters (the first
// `pinned_nodes` keep A = I, t = 0: they hold the world frame), each step one sparse
// normal-equation system factored by CHOLMOD (sparse_cholesky.h), its symbolic analysis
// reused while the system's pattern stays inside the analysed one. Lengths count in units of
// L = length_scale_m (the node spacing), so the three terms are unit-free and γ and w_con mean
// the same at every scale. E_reg and E_con are linear in the parameters; only E_rot is not.
//
// Connectivity N(j), the combined rule: a new node links to its temporal predecessor (the
// graph follows the scan's order, so it is connected) and to the spatially nearest older
// nodes within link_radius of it among the last temporal_window nodes (spatially aware: a
// scan that lingers or doubles back links what lies together). Nodes far apart in time are
// not linked even when they lie together — a revisit after drift: their rest positions come
// from poses that disagree by the drift, and a link would hold that disagreement in place.
// Revisits are point constraints (E_con), which is what corrects the drift.
//
// Which nodes deform a point (bind*): the k nearest by distance among the nodes made around
// the time the point was observed — a point, a pose or a part of the map is tied to the
// nodes of its own time, so the surface seen at the start and the same surface seen again at
// the end deform by their own nodes even where they overlap.
//
//   DeformationGraph graph(options);
//   per keyframe: graph.add_node(focus_point, frame_index);
//   graph.add_constraint({source, graph.bind_before(source, frame), target, {}, normal, 1.0});
//   SolveStats stats = graph.solve(2);
//   Eigen::Vector3d moved = graph.deform(p, graph.bind_before(p, frame));
//
// Thread safety: none; one thread uses a graph (the session's deformation worker).
#pragma once

#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "fusion/deformation/deform_shared.h"
#include "sdk/core/pose.h"

namespace sls::fusion::deformation {

struct GraphOptions {
  int nearest_nodes = 4;            // k: nodes bound to a point (eq. 18), 1 .. kMaxBoundNodes
  int temporal_window = 8;          // a point's candidate nodes, and a new node's link candidates
  int spatial_links = 2;            // at most this many links to older nodes besides the predecessor
  double link_radius_m = 0.0;       // ... within this distance (0: 1.5 length scales: nodes
                                    // are made a length scale apart, so the path turned or came back)
  double max_link_distance_m = 0.0; // no link at all beyond this (0: none): a jump makes a new,
                                    // unconnected part, which solve() refuses by name
  int pinned_nodes = 2;             // the first nodes, fixed (the world frame)
  double length_scale_m = 1e-3;     // L
  double rotation_weight = 1.0;     // w_rot
  double regularization_weight = 10.0;  // γ (eq. 16)
  double region_radius_m = 0.0;         // ρ (0: eq. 15 as printed)
  double constraint_weight = 100.0;     // w_con
  // Added to the normal matrix's diagonal (in the unit-free parameters): a node whose
  // neighbours lie on a line leaves its rotation about that line to E_rot alone, which does
  // not fix it; the damping keeps such a direction where it is. 0: none (such a system is
  // then singular and solve() says so).
  double damping = 1e-6;
  // Throws sls::Error(kInvalidArgument) naming the bad value.
  void validate() const;
};

struct Node {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // g_j (the frame the scan tracked in)
  int time = 0;                                        // the frame it was made at
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

// One E_con term: the source point, deformed by its nodes, should reach the target, deformed
// by its own (none: a fixed point). With a non-zero normal (unit, the target's, in the
// target's undeformed frame; it turns with the target's nodes) only the distance along it
// counts (point-to-plane, one residual); else the whole difference (three).
struct Constraint {
  Eigen::Vector3d source = Eigen::Vector3d::Zero();
  NodeBinding source_binding;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  NodeBinding target_binding;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double weight = 1.0;  // c_l
};

// A prior on a pose's rotation (see the energy above): the rotation the graph turns the pose by
// should be `rotation` (world frame, applied left of the pose), to `information` (rad⁻²,
// symmetric positive semi-definite; zero along a direction the prior leaves free).
struct RotationPrior {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
};

struct EnergyTerms {
  double rotation = 0.0;        // w_rot E_rot
  double regularization = 0.0;  // γ E_reg / L²
  double constraints = 0.0;     // w_con E_con / L²
  double rotation_priors = 0.0; // Σ φᵀΛφ
  double total() const { return rotation + regularization + constraints + rotation_priors; }
};

struct SolveStats {
  int iterations = 0;           // Gauss–Newton steps taken
  int step_halvings = 0;        // steps shortened because the full one raised the energy
  EnergyTerms before, after;
  int unknowns = 0;
  std::size_t nonzeros = 0;     // of the normal matrix's upper triangle
  bool analyzed = false;        // the pattern was (re-)analysed during this solve
  std::size_t constraints = 0;
  double max_update_m = 0.0;    // the largest change of a node's translation over the solve
  double ms = 0.0;              // wall time of the solve, of which:
  double assemble_ms = 0.0;     //   the normal equations' pattern and values
  double factorize_ms = 0.0;    //   CHOLMOD's analysis (when needed), factorisation and solve
};

class DeformationGraph {
 public:
  explicit DeformationGraph(const GraphOptions& options = {});
  ~DeformationGraph();
  DeformationGraph(DeformationGraph&&) noexcept;
  DeformationGraph& operator=(DeformationGraph&&) noexcept;

  const GraphOptions& options() const;

  // A node at `position` made at frame `time` (not before the last node's), linked by the
  // combined rule; its transform starts as its predecessor's carried to it (A_prev, and the
  // translation that puts it where the predecessor's transform takes it), so the correction
  // found so far continues. Returns its index. sls::Error(kInvalidArgument) for a time going
  // back or a position that is not finite.
  int add_node(const Eigen::Vector3d& position, int time);
  std::size_t size() const;
  const Node& node(int index) const;
  // Undirected links (j < k), in the order they were made.
  const std::vector<std::pair<int, int>>& edges() const;
  int pinned_count() const;  // min(pinned_nodes, size())

  // The last node made at or before `time` (the first node for an earlier time; -1 without nodes).
  int node_at_time(int time) const;
  // The k nearest of nodes [first_node, last_node] (clamped to the graph) with eq. (19)'s
  // weights; ties go to the older node. count 0 without nodes.
  NodeBinding bind(const Eigen::Vector3d& point, int first_node, int last_node) const;
  // Among the temporal_window nodes made up to `time` (a surface shipped, or a frame's
  // points when only the past exists).
  NodeBinding bind_before(const Eigen::Vector3d& point, int time) const;
  // Among the temporal_window + 1 nodes centred on node_at_time(time).
  NodeBinding bind_around(const Eigen::Vector3d& point, int time) const;
  // A pose of frame `time` looking at `anchor`: the two nodes of its time, node_at_time(time)
  // and the next (one after the last node), weighed by eq. (19). Two linked nodes, so that a
  // prior on the pose's rotation couples nothing the links do not (bind_around's four would
  // widen the normal equations' band threefold, and their factorisation with it).
  NodeBinding bind_pose(const Eigen::Vector3d& anchor, int time) const;

  // E_con. sls::Error(kInvalidArgument) for a binding naming a node that does not exist, a
  // weight that is not positive and finite, or a point that is not finite.
  void add_constraint(const Constraint& constraint);
  void clear_constraints();
  const std::vector<Constraint>& constraints() const;

  // A prior on the rotation of a pose of frame `time` looking at `anchor` (deform_pose with
  // bind_pose(anchor, time); its binding follows as nodes are added). Returns its index.
  // sls::Error(kInvalidArgument) before any node, for an anchor that is not finite, a rotation
  // that is not one (‖RᵀR − I‖ > 1e-6, det < 0), an information matrix that is not finite,
  // symmetric and positive semi-definite.
  int add_rotation_prior(const Eigen::Vector3d& anchor, int time, const RotationPrior& prior);
  std::size_t rotation_priors() const;

  // `iterations` Gauss–Newton steps (a step that raises the energy is halved, up to 8 times;
  // one that still raises it ends the solve). sls::Error(kInvalidArgument): no node to solve
  // (every node pinned: "too few nodes"), a node with no path of links to a pinned node (a
  // disconnected graph, named), a singular system (the node and parameter named); the nodes
  // keep their transforms then.
  SolveStats solve(int iterations);
  EnergyTerms energy() const;
  // How often the normal equations' pattern was analysed / a matrix factored, over the
  // graph's life.
  std::size_t analyses() const;
  std::size_t factorizations() const;

  // The deformation (eq. 18) of a point and a normal by a binding; a pose: the rigid part of
  // the deformation at `anchor` (a world point the pose looks at, e.g. its focus point): the
  // blended A made a rotation (polar decomposition) about the anchor's deformed position.
  Eigen::Vector3d deform(const Eigen::Vector3d& point, const NodeBinding& binding) const;
  Eigen::Vector3d deform_normal(const Eigen::Vector3d& normal, const NodeBinding& binding) const;
  Pose deform_pose(const Pose& T_world_camera, const Eigen::Vector3d& anchor, const NodeBinding& binding) const;
  // Every node's transform for deform_shared.h's loops (A⁻ᵀ computed once).
  std::vector<NodeTransform> transforms() const;

  // For tests and tools: a node's transform set directly; the unpinned nodes' parameters
  // (A row-major, then t, per node) and the weighted residuals and their Jacobian (dense:
  // small graphs only) that solve() linearises.
  void set_transform(int index, const Eigen::Matrix3d& A, const Eigen::Vector3d& t);
  Eigen::VectorXd parameters() const;
  void set_parameters(const Eigen::VectorXd& parameters);
  Eigen::VectorXd residuals() const;
  Eigen::MatrixXd jacobian_dense() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::fusion::deformation
