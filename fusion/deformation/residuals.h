// The deformation graph's residuals and their Jacobians (deformation_graph.h gives the
// energy), one block at a time: E_rot per node (6 rows), E_reg per directed link (3 rows, and
// 9 for its region part), E_con per constraint (3 rows, or 1 along a normal), a pose's
// rotation prior (3 rows: Λ^½ φ). Every consumer — the energy, the normal equations, the
// dense Jacobian the tests compare with finite differences — walks the same blocks
// (for_each_residual_block), so what is checked is what is solved.
//
// Parameters per node: A row-major (9), then t / L (3): unit-free, as the residuals are.
// The normal of a point-to-plane constraint with a deformed target is turned by the target's
// nodes as they are when the block is made, and held: the Jacobian leaves its turning out
// (a Gauss–Newton step linearises it away; it is second order in the correction).
#pragma once

#include <utility>
#include <vector>

#include <Eigen/Core>

#include "fusion/deformation/deformation_graph.h"

namespace sls::fusion::deformation {

// A pose's rotation prior: the nodes that deform the pose, and the square root of the
// prior's information (UᵀU = Λ, made once).
struct PoseRotationPrior {
  Eigen::Vector3d anchor = Eigen::Vector3d::Zero();
  int time = 0;
  NodeBinding binding;
  RotationPrior prior;
  Eigen::Matrix3d sqrt_information = Eigen::Matrix3d::Zero();
};
PoseRotationPrior make_pose_rotation_prior(const Eigen::Vector3d& anchor, int time, const RotationPrior& prior);

// What the residuals are computed from (the graph's state, borrowed).
struct ResidualModel {
  const std::vector<Node>* nodes = nullptr;
  const std::vector<std::vector<int>>* neighbours = nullptr;
  const std::vector<Constraint>* constraints = nullptr;
  const std::vector<PoseRotationPrior>* rotation_priors = nullptr;  // may be null
  const GraphOptions* options = nullptr;
  int pinned = 0;  // the first `pinned` nodes have no parameters
  // Changes whenever nodes, links or constraints are added or removed (not when parameters
  // change): the normal equations' pattern depends on nothing else.
  std::size_t structure_version = 0;
};

enum class Term { kRotation, kRegularization, kConstraint, kRotationPrior };

constexpr int kMaxBlockNodes = 2 * kMaxBoundNodes;
constexpr int kMaxBlockRows = 9;

struct ResidualBlock {
  Term term = Term::kRotation;
  int rows = 0;
  double r[kMaxBlockRows] = {};
  int count = 0;                                 // distinct nodes
  int nodes[kMaxBlockNodes] = {};
  double J[kMaxBlockNodes][kMaxBlockRows][12];   // d r / d parameters of each node (pinned ones too)

  // false: residuals only (the energy): J, nodes and count are left alone (count 0).
  bool jacobian = true;

  // The slot of a node in the block (appended, its rows' Jacobian zeroed, when new).
  int slot(int node);
};

void rotation_block(const ResidualModel& model, int node, ResidualBlock* block);
void regularization_block(const ResidualModel& model, int from, int to, ResidualBlock* block);
// E_reg's agreement over the ball of radius ρ (GraphOptions::region_radius_m): ρ/√3 (A_j − A_k).
void region_block(const ResidualModel& model, int from, int to, ResidualBlock* block);
// Nodes' A⁻¹ as a walk needs them (a point-to-plane constraint turns its normal by its
// target's nodes): each computed once a walk, where many constraints share a node.
class NodeInverses {
 public:
  const Eigen::Matrix3d& of(const ResidualModel& model, int node);

 private:
  std::vector<Eigen::Matrix3d> inverses_;
  std::vector<char> known_;
};
void constraint_block(const ResidualModel& model, const Constraint& constraint, ResidualBlock* block,
                      NodeInverses* inverses);
void rotation_prior_block(const PoseRotationPrior& prior, const ResidualModel& model, ResidualBlock* block);

// Which blocks a walk visits. E_reg (with its region part) and the rotation priors are
// linear in the parameters with a Jacobian fixed by the node positions, the priors' rotations
// and their bindings, so their share of JᵀJ changes only with the graph's structure; E_rot and
// the constraints (whose normals turn with A⁻¹) are not.
enum class Terms { kAll, kLinear, kNonlinear };

// Every block once, in a fixed order: E_rot of each unpinned node, E_reg of each directed
// link with an unpinned end (and its region part when ρ > 0), every constraint, then every
// pose's rotation prior.
template <typename Visit>
void for_each_residual_block(const ResidualModel& model, Visit&& visit, Terms terms = Terms::kAll,
                             bool jacobian = true) {
  ResidualBlock block;
  block.jacobian = jacobian;
  const int size = static_cast<int>(model.nodes->size());
  if (terms != Terms::kLinear) {
    for (int j = model.pinned; j < size; ++j) {
      rotation_block(model, j, &block);
      visit(block);
    }
  }
  if (terms != Terms::kNonlinear) {
    for (int j = 0; j < size; ++j) {
      for (int k : (*model.neighbours)[static_cast<std::size_t>(j)]) {
        if (j < model.pinned && k < model.pinned) continue;
        regularization_block(model, j, k, &block);
        visit(block);
        if (model.options->region_radius_m > 0.0) {
          region_block(model, j, k, &block);
          visit(block);
        }
      }
    }
  }
  if (terms != Terms::kLinear) {
    NodeInverses inverses;
    for (const Constraint& constraint : *model.constraints) {
      constraint_block(model, constraint, &block, &inverses);
      visit(block);
    }
  }
  if (terms != Terms::kNonlinear) {
    if (model.rotation_priors != nullptr) {
      for (const PoseRotationPrior& prior : *model.rotation_priors) {
        rotation_prior_block(prior, model, &block);
        visit(block);
      }
    }
  }
}

// A block's Σ r² added to its term (what evaluate_energy sums, block by block in walk order).
void add_block_energy(const ResidualBlock& block, EnergyTerms* energy);
// The energy of the blocks `terms` selects (the others' terms stay 0).
EnergyTerms evaluate_energy(const ResidualModel& model, Terms terms = Terms::kAll);

Eigen::VectorXd pack_parameters(const std::vector<Node>& nodes, int pinned, double length_scale_m);
void unpack_parameters(const Eigen::VectorXd& parameters, std::vector<Node>* nodes, int pinned, double length_scale_m);
// nodes += scale * step (the unpinned nodes' parameters, as pack_parameters orders them).
void apply_step(std::vector<Node>* nodes, int pinned, const std::vector<double>& step, double scale,
                double length_scale_m);

Eigen::VectorXd residual_vector(const ResidualModel& model);
Eigen::MatrixXd dense_jacobian(const ResidualModel& model);

}  // namespace sls::fusion::deformation
