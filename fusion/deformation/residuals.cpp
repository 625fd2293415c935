#include "fusion/deformation/residuals.h"

#include <cmath>

#include <Eigen/Dense>

#include "sdk/core/error.h"

namespace sls::fusion::deformation {
namespace {

constexpr double kSqrt2 = 1.41421356237309504880;

const Node& node_of(const ResidualModel& model, int index) { return (*model.nodes)[static_cast<std::size_t>(index)]; }

// Adds w · d(A (p − g) + g + t)/d(parameters) of node j, dotted with `direction` (1 row) or
// not (3 rows), times `scale`, to the block's rows.
void add_point_jacobian(const ResidualModel& model, int node, double weight, const Eigen::Vector3d& point,
                        const Eigen::Vector3d* direction, double scale, ResidualBlock* block) {
  if (!block->jacobian) return;
  const Node& n = node_of(model, node);
  const Eigen::Vector3d d = point - n.position;
  const double L = model.options->length_scale_m;
  const int slot = block->slot(node);
  double(*J)[12] = block->J[slot];
  if (direction != nullptr) {
    for (int i = 0; i < 3; ++i) {
      for (int c = 0; c < 3; ++c) J[0][3 * i + c] += scale * weight * (*direction)[i] * d[c];
      J[0][9 + i] += scale * weight * L * (*direction)[i];
    }
    return;
  }
  for (int i = 0; i < 3; ++i) {
    for (int c = 0; c < 3; ++c) J[i][3 * i + c] += scale * weight * d[c];
    J[i][9 + i] += scale * weight * L;
  }
}

Eigen::Vector3d deform_with(const ResidualModel& model, const Eigen::Vector3d& point, const NodeBinding& binding) {
  if (binding.count == 0) return point;
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  for (int i = 0; i < binding.count; ++i) {
    const Node& n = node_of(model, binding.nodes[i]);
    out += binding.weights[i] * (n.A * (point - n.position) + n.position + n.t);
  }
  return out;
}

// Every block writes each of its rows' residual, so r is not cleared.
void reset(ResidualBlock* block, Term term, int rows) {
  block->term = term;
  block->rows = rows;
  block->count = 0;
}

}  // namespace

int ResidualBlock::slot(int node) {
  for (int i = 0; i < count; ++i) {
    if (nodes[i] == node) return i;
  }
  if (count == kMaxBlockNodes) throw_error(ErrorCode::kInternal, "deformation residual: too many nodes in a block");
  nodes[count] = node;
  if (jacobian) {
    for (int row = 0; row < rows; ++row) {
      for (double& value : J[count][row]) value = 0.0;
    }
  }
  return count++;
}

void rotation_block(const ResidualModel& model, int node, ResidualBlock* block) {
  reset(block, Term::kRotation, 6);
  const Eigen::Matrix3d& A = node_of(model, node).A;
  const Eigen::Matrix3d C = A.transpose() * A - Eigen::Matrix3d::Identity();
  const double s = std::sqrt(model.options->rotation_weight);
  static constexpr int kA[6] = {0, 1, 2, 0, 0, 1};
  static constexpr int kB[6] = {0, 1, 2, 1, 2, 2};
  const int slot = block->jacobian ? block->slot(node) : 0;
  for (int row = 0; row < 6; ++row) {
    const int a = kA[row], b = kB[row];
    const double f = s * (a == b ? 1.0 : kSqrt2);
    block->r[row] = f * C(a, b);
    if (!block->jacobian) continue;
    // dC_ab / dA_ic = δ_ca A_ib + δ_cb A_ia.
    for (int i = 0; i < 3; ++i) {
      block->J[slot][row][3 * i + a] += f * A(i, b);
      block->J[slot][row][3 * i + b] += f * A(i, a);
    }
  }
}

void regularization_block(const ResidualModel& model, int from, int to, ResidualBlock* block) {
  reset(block, Term::kRegularization, 3);
  const Node& j = node_of(model, from);
  const Node& k = node_of(model, to);
  const double L = model.options->length_scale_m;
  const double s = std::sqrt(model.options->regularization_weight) / L;
  const Eigen::Vector3d d = k.position - j.position;
  const Eigen::Vector3d r = s * (j.A * d + j.position + j.t - k.position - k.t);
  for (int i = 0; i < 3; ++i) block->r[i] = r[i];
  if (!block->jacobian) return;  // the energy: no slots either
  const int a = block->slot(from);
  const int b = block->slot(to);
  for (int i = 0; i < 3; ++i) {
    for (int c = 0; c < 3; ++c) block->J[a][i][3 * i + c] = s * d[c];
    block->J[a][i][9 + i] = s * L;
    block->J[b][i][9 + i] = -s * L;
  }
}

void region_block(const ResidualModel& model, int from, int to, ResidualBlock* block) {
  reset(block, Term::kRegularization, 9);
  const Eigen::Matrix3d difference =
      node_of(model, from).A - node_of(model, to).A;
  const double s = std::sqrt(model.options->regularization_weight / 3.0) * model.options->region_radius_m /
                   model.options->length_scale_m;
  for (int i = 0; i < 9; ++i) block->r[i] = s * difference(i / 3, i % 3);
  if (!block->jacobian) return;
  const int a = block->slot(from);
  const int b = block->slot(to);
  for (int i = 0; i < 9; ++i) {
    block->J[a][i][i] = s;
    block->J[b][i][i] = -s;
  }
}

const Eigen::Matrix3d& NodeInverses::of(const ResidualModel& model, int node) {
  const auto index = static_cast<std::size_t>(node);
  if (known_.size() <= index) {
    known_.resize(model.nodes->size(), 0);
    inverses_.resize(model.nodes->size());
  }
  if (!known_[index]) {
    inverses_[index] = node_of(model, node).A.inverse();
    known_[index] = 1;
  }
  return inverses_[index];
}

void constraint_block(const ResidualModel& model, const Constraint& constraint, ResidualBlock* block,
                      NodeInverses* inverses) {
  const bool plane = constraint.normal.squaredNorm() > 0.0;
  reset(block, Term::kConstraint, plane ? 1 : 3);
  const double L = model.options->length_scale_m;
  const double s = std::sqrt(model.options->constraint_weight * constraint.weight) / L;
  const Eigen::Vector3d difference = deform_with(model, constraint.source, constraint.source_binding) -
                                     deform_with(model, constraint.target, constraint.target_binding);
  Eigen::Vector3d normal = constraint.normal;
  if (plane && constraint.target_binding.count > 0) {
    Eigen::Vector3d turned = Eigen::Vector3d::Zero();
    for (int i = 0; i < constraint.target_binding.count; ++i) {
      const Eigen::Matrix3d& A_inverse = inverses->of(model, constraint.target_binding.nodes[i]);
      turned += constraint.target_binding.weights[i] * (A_inverse.transpose() * constraint.normal);
    }
    if (turned.norm() > 0.0) normal = turned.normalized();
  }
  if (plane) {
    block->r[0] = s * normal.dot(difference);
  } else {
    for (int i = 0; i < 3; ++i) block->r[i] = s * difference[i];
  }
  const Eigen::Vector3d* direction = plane ? &normal : nullptr;
  for (int i = 0; i < constraint.source_binding.count; ++i) {
    add_point_jacobian(model, constraint.source_binding.nodes[i], constraint.source_binding.weights[i],
                       constraint.source, direction, s, block);
  }
  for (int i = 0; i < constraint.target_binding.count; ++i) {
    add_point_jacobian(model, constraint.target_binding.nodes[i], constraint.target_binding.weights[i],
                       constraint.target, direction, -s, block);
  }
}

PoseRotationPrior make_pose_rotation_prior(const Eigen::Vector3d& anchor, int time, const RotationPrior& prior) {
  PoseRotationPrior out;
  out.anchor = anchor;
  out.time = time;
  out.prior = prior;
  // U = diag(√λ) Vᵀ of Λ = V diag(λ) Vᵀ (λ clamped at 0: rounding of a semi-definite Λ).
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(0.5 * (prior.information + prior.information.transpose()));
  const Eigen::Vector3d root = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  out.sqrt_information = root.asDiagonal() * eigen.eigenvectors().transpose();
  return out;
}

void rotation_prior_block(const PoseRotationPrior& prior, const ResidualModel& model, ResidualBlock* block) {
  reset(block, Term::kRotationPrior, 3);
  const Eigen::Matrix3d& C = prior.prior.rotation;
  Eigen::Matrix3d blended = Eigen::Matrix3d::Zero();
  for (int i = 0; i < prior.binding.count; ++i) {
    blended += prior.binding.weights[i] * node_of(model, prior.binding.nodes[i]).A;
  }
  const Eigen::Matrix3d M = blended * C.transpose();
  // φ = vee(½(M − Mᵀ)): exact for M = I + [φ]×, linear in A.
  const Eigen::Vector3d phi(0.5 * (M(2, 1) - M(1, 2)), 0.5 * (M(0, 2) - M(2, 0)), 0.5 * (M(1, 0) - M(0, 1)));
  const Eigen::Vector3d r = prior.sqrt_information * phi;
  for (int i = 0; i < 3; ++i) block->r[i] = r[i];
  if (!block->jacobian) return;
  int slots[kMaxBoundNodes];
  for (int i = 0; i < prior.binding.count; ++i) slots[i] = block->slot(prior.binding.nodes[i]);
  // dM_ab/dA_ic = w δ_ai C_bc (A of a node of weight w), so dφ_p/dA_ic over the pairs (a, b)
  // of φ_p = ½(M_ab − M_ba), times w.
  static constexpr int kA[3] = {2, 0, 1};
  static constexpr int kB[3] = {1, 2, 0};
  Eigen::Matrix<double, 3, 9> dphi = Eigen::Matrix<double, 3, 9>::Zero();
  for (int p = 0; p < 3; ++p) {
    for (int c = 0; c < 3; ++c) {
      dphi(p, 3 * kA[p] + c) += 0.5 * C(kB[p], c);
      dphi(p, 3 * kB[p] + c) -= 0.5 * C(kA[p], c);
    }
  }
  const Eigen::Matrix<double, 3, 9> J = prior.sqrt_information * dphi;
  for (int i = 0; i < prior.binding.count; ++i) {
    for (int row = 0; row < 3; ++row) {
      for (int k = 0; k < 9; ++k) block->J[slots[i]][row][k] += prior.binding.weights[i] * J(row, k);
    }
  }
}

void add_block_energy(const ResidualBlock& block, EnergyTerms* energy) {
  double sum = 0.0;
  for (int row = 0; row < block.rows; ++row) sum += block.r[row] * block.r[row];
  switch (block.term) {
    case Term::kRotation: energy->rotation += sum; break;
    case Term::kRegularization: energy->regularization += sum; break;
    case Term::kConstraint: energy->constraints += sum; break;
    case Term::kRotationPrior: energy->rotation_priors += sum; break;
  }
}

EnergyTerms evaluate_energy(const ResidualModel& model, Terms terms) {
  EnergyTerms energy;
  for_each_residual_block(model, [&energy](const ResidualBlock& block) { add_block_energy(block, &energy); }, terms,
                          /*jacobian=*/false);
  return energy;
}

Eigen::VectorXd pack_parameters(const std::vector<Node>& nodes, int pinned, double length_scale_m) {
  const int free_nodes = static_cast<int>(nodes.size()) - pinned;
  Eigen::VectorXd x(12 * std::max(free_nodes, 0));
  for (int j = 0; j < free_nodes; ++j) {
    const Node& n = nodes[static_cast<std::size_t>(pinned + j)];
    for (int i = 0; i < 9; ++i) x[12 * j + i] = n.A(i / 3, i % 3);
    for (int i = 0; i < 3; ++i) x[12 * j + 9 + i] = n.t[i] / length_scale_m;
  }
  return x;
}

void unpack_parameters(const Eigen::VectorXd& parameters, std::vector<Node>* nodes, int pinned,
                       double length_scale_m) {
  const int free_nodes = static_cast<int>(nodes->size()) - pinned;
  if (parameters.size() != 12 * std::max(free_nodes, 0)) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: {} parameters for {} unpinned nodes",
                parameters.size(), free_nodes);
  }
  for (int j = 0; j < free_nodes; ++j) {
    Node& n = (*nodes)[static_cast<std::size_t>(pinned + j)];
    for (int i = 0; i < 9; ++i) n.A(i / 3, i % 3) = parameters[12 * j + i];
    for (int i = 0; i < 3; ++i) n.t[i] = parameters[12 * j + 9 + i] * length_scale_m;
  }
}

void apply_step(std::vector<Node>* nodes, int pinned, const std::vector<double>& step, double scale,
                double length_scale_m) {
  const int free_nodes = static_cast<int>(nodes->size()) - pinned;
  for (int j = 0; j < free_nodes; ++j) {
    Node& n = (*nodes)[static_cast<std::size_t>(pinned + j)];
    const double* delta = &step[static_cast<std::size_t>(12 * j)];
    for (int i = 0; i < 9; ++i) n.A(i / 3, i % 3) += scale * delta[i];
    for (int i = 0; i < 3; ++i) n.t[i] += scale * delta[9 + i] * length_scale_m;
  }
}

Eigen::VectorXd residual_vector(const ResidualModel& model) {
  std::vector<double> values;
  for_each_residual_block(model, [&values](const ResidualBlock& block) {
    values.insert(values.end(), block.r, block.r + block.rows);
  });
  return Eigen::Map<Eigen::VectorXd>(values.data(), static_cast<Eigen::Index>(values.size()));
}

Eigen::MatrixXd dense_jacobian(const ResidualModel& model) {
  const int free_nodes = static_cast<int>(model.nodes->size()) - model.pinned;
  std::vector<Eigen::RowVectorXd> rows;
  for_each_residual_block(model, [&](const ResidualBlock& block) {
    for (int row = 0; row < block.rows; ++row) {
      Eigen::RowVectorXd line = Eigen::RowVectorXd::Zero(12 * std::max(free_nodes, 0));
      for (int i = 0; i < block.count; ++i) {
        const int var = block.nodes[i] - model.pinned;
        if (var < 0) continue;
        for (int p = 0; p < 12; ++p) line[12 * var + p] = block.J[i][row][p];
      }
      rows.push_back(line);
    }
  });
  Eigen::MatrixXd J(static_cast<Eigen::Index>(rows.size()), 12 * std::max(free_nodes, 0));
  for (std::size_t r = 0; r < rows.size(); ++r) J.row(static_cast<Eigen::Index>(r)) = rows[r];
  return J;
}

}  // namespace sls::fusion::deformation
