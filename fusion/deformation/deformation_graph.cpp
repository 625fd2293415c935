#include "fusion/deformation/deformation_graph.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include <Eigen/Dense>

#include "fusion/deformation/normal_equations.h"
#include "fusion/deformation/residuals.h"
#include "fusion/deformation/sparse_cholesky.h"
#include "sdk/core/error.h"

namespace sls::fusion::deformation {
namespace {

Vec3T<double> to_vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Mat3T<double> to_mat(const Eigen::Matrix3d& m) {
  Mat3T<double> out{};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.m[r * 3 + c] = m(r, c);
  }
  return out;
}

bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }

double elapsed_ms(std::chrono::steady_clock::time_point from, std::chrono::steady_clock::time_point to) {
  return std::chrono::duration<double, std::milli>(to - from).count();
}

// The nearest rotation to a matrix (polar decomposition by SVD, det +1).
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& m) {
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

}  // namespace

void GraphOptions::validate() const {
  if (nearest_nodes < 1 || nearest_nodes > kMaxBoundNodes) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: nearest_nodes {} outside [1, {}]", nearest_nodes,
                kMaxBoundNodes);
  }
  if (temporal_window < nearest_nodes) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: temporal_window {} below nearest_nodes {}",
                temporal_window, nearest_nodes);
  }
  if (spatial_links < 0) throw_error(ErrorCode::kInvalidArgument, "deformation graph: spatial_links {} < 0", spatial_links);
  if (pinned_nodes < 1) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: pinned_nodes {} (at least 1 holds the world frame)",
                pinned_nodes);
  }
  const auto positive = [](double value) { return value > 0.0 && std::isfinite(value); };
  const auto non_negative = [](double value) { return value >= 0.0 && std::isfinite(value); };
  if (!positive(length_scale_m)) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: length_scale_m {} is not positive", length_scale_m);
  }
  if (!non_negative(region_radius_m)) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: region_radius_m {} < 0", region_radius_m);
  }
  if (!non_negative(link_radius_m) || !non_negative(max_link_distance_m)) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: link distances {} / {} m must be 0 or positive",
                link_radius_m, max_link_distance_m);
  }
  if (!non_negative(rotation_weight) || !positive(regularization_weight) || !positive(constraint_weight)) {
    throw_error(ErrorCode::kInvalidArgument,
                "deformation graph: weights rot {} reg {} con {} (rot >= 0, the others positive)", rotation_weight,
                regularization_weight, constraint_weight);
  }
  if (!non_negative(damping)) throw_error(ErrorCode::kInvalidArgument, "deformation graph: damping {} < 0", damping);
}

struct DeformationGraph::Impl {
  GraphOptions options;
  std::vector<Node> nodes;
  std::vector<std::pair<int, int>> edges;
  std::vector<std::vector<int>> neighbours;  // per node, both directions
  std::vector<Constraint> constraints;
  std::vector<PoseRotationPrior> rotation_priors;  // bound as bind_pose binds their pose
  NormalEquations equations;
  std::size_t structure_version = 1;  // ResidualModel::structure_version

  int pinned() const { return std::min(options.pinned_nodes, static_cast<int>(nodes.size())); }

  ResidualModel model() const {
    ResidualModel m;
    m.nodes = &nodes;
    m.neighbours = &neighbours;
    m.constraints = &constraints;
    m.rotation_priors = &rotation_priors;
    m.options = &options;
    m.pinned = pinned();
    m.structure_version = structure_version;
    return m;
  }

  // Nodes with no path of links to a pinned node, as "a-b, c" ranges; empty when connected.
  std::string unreachable_nodes() const {
    std::vector<char> reached(nodes.size(), 0);
    std::vector<int> stack;
    for (int j = 0; j < pinned(); ++j) {
      reached[static_cast<std::size_t>(j)] = 1;
      stack.push_back(j);
    }
    while (!stack.empty()) {
      const int j = stack.back();
      stack.pop_back();
      for (int k : neighbours[static_cast<std::size_t>(j)]) {
        if (!reached[static_cast<std::size_t>(k)]) {
          reached[static_cast<std::size_t>(k)] = 1;
          stack.push_back(k);
        }
      }
    }
    std::string list;
    for (std::size_t j = 0; j < nodes.size();) {
      if (reached[j]) {
        ++j;
        continue;
      }
      std::size_t end = j;
      while (end + 1 < nodes.size() && !reached[end + 1]) ++end;
      if (!list.empty()) list += ", ";
      list += end == j ? fmt::format("{} (frame {})", j, nodes[j].time)
                       : fmt::format("{}-{} (frames {}-{})", j, end, nodes[j].time, nodes[end].time);
      j = end + 1;
    }
    return list;
  }
};

DeformationGraph::DeformationGraph(const GraphOptions& options) : impl_(std::make_unique<Impl>()) {
  options.validate();
  impl_->options = options;
}
DeformationGraph::~DeformationGraph() = default;
DeformationGraph::DeformationGraph(DeformationGraph&&) noexcept = default;
DeformationGraph& DeformationGraph::operator=(DeformationGraph&&) noexcept = default;

const GraphOptions& DeformationGraph::options() const { return impl_->options; }

int DeformationGraph::add_node(const Eigen::Vector3d& position, int time) {
  Impl& s = *impl_;
  if (!finite(position)) throw_error(ErrorCode::kInvalidArgument, "deformation graph: a node position is not finite");
  if (!s.nodes.empty() && time < s.nodes.back().time) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: a node of frame {} after one of frame {}", time,
                s.nodes.back().time);
  }
  const int index = static_cast<int>(s.nodes.size());
  Node node;
  node.position = position;
  node.time = time;
  s.neighbours.emplace_back();
  const GraphOptions& o = s.options;
  const auto link = [&s](int a, int b) {
    s.edges.emplace_back(std::min(a, b), std::max(a, b));
    s.neighbours[static_cast<std::size_t>(a)].push_back(b);
    s.neighbours[static_cast<std::size_t>(b)].push_back(a);
  };
  const auto within_reach = [&](int other) {
    return o.max_link_distance_m <= 0.0 ||
           (s.nodes[static_cast<std::size_t>(other)].position - position).norm() <= o.max_link_distance_m;
  };
  if (index > 0) {
    const Node& previous = s.nodes.back();
    // Carry the predecessor's transform to the new node: A_prev, and where it takes g_new.
    node.A = previous.A;
    node.t = previous.A * (position - previous.position) + previous.position + previous.t - position;
    if (within_reach(index - 1)) link(index - 1, index);
    // Spatially close older nodes of the recent past (the combined rule).
    const double radius = o.link_radius_m > 0.0 ? o.link_radius_m : 1.5 * o.length_scale_m;
    std::vector<std::pair<double, int>> close;
    for (int k = std::max(0, index - o.temporal_window); k < index - 1; ++k) {
      const double d = (s.nodes[static_cast<std::size_t>(k)].position - position).norm();
      if (d <= radius && within_reach(k)) close.emplace_back(d, k);
    }
    std::sort(close.begin(), close.end());
    for (std::size_t i = 0; i < close.size() && static_cast<int>(i) < o.spatial_links; ++i) link(close[i].second, index);
  }
  s.nodes.push_back(node);
  ++s.structure_version;
  // Poses made after the last node had only it: the new one is their next (bind_pose).
  for (auto prior = s.rotation_priors.rbegin(); prior != s.rotation_priors.rend(); ++prior) {
    if (node_at_time(prior->time) + 1 < index) break;
    prior->binding = bind_pose(prior->anchor, prior->time);
  }
  return index;
}

std::size_t DeformationGraph::size() const { return impl_->nodes.size(); }

const Node& DeformationGraph::node(int index) const {
  if (index < 0 || static_cast<std::size_t>(index) >= impl_->nodes.size()) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: no node {} (it has {})", index, impl_->nodes.size());
  }
  return impl_->nodes[static_cast<std::size_t>(index)];
}

const std::vector<std::pair<int, int>>& DeformationGraph::edges() const { return impl_->edges; }
int DeformationGraph::pinned_count() const { return impl_->pinned(); }

int DeformationGraph::node_at_time(int time) const {
  const std::vector<Node>& nodes = impl_->nodes;
  if (nodes.empty()) return -1;
  const auto after = std::upper_bound(nodes.begin(), nodes.end(), time,
                                      [](int t, const Node& node) { return t < node.time; });
  return after == nodes.begin() ? 0 : static_cast<int>(after - nodes.begin()) - 1;
}

NodeBinding DeformationGraph::bind(const Eigen::Vector3d& point, int first_node, int last_node) const {
  const std::vector<Node>& nodes = impl_->nodes;
  if (nodes.empty()) return NodeBinding{};
  first_node = std::clamp(first_node, 0, static_cast<int>(nodes.size()) - 1);
  last_node = std::clamp(last_node, first_node, static_cast<int>(nodes.size()) - 1);
  std::vector<Vec3T<double>> positions;
  positions.reserve(static_cast<std::size_t>(last_node - first_node + 1));
  for (int j = first_node; j <= last_node; ++j) positions.push_back(to_vec(nodes[static_cast<std::size_t>(j)].position));
  return bind_nearest(positions.data(), first_node, static_cast<int>(positions.size()), impl_->options.nearest_nodes,
                      to_vec(point));
}

NodeBinding DeformationGraph::bind_before(const Eigen::Vector3d& point, int time) const {
  const int last = node_at_time(time);
  return bind(point, last - impl_->options.temporal_window + 1, last);
}

NodeBinding DeformationGraph::bind_pose(const Eigen::Vector3d& anchor, int time) const {
  const int node = node_at_time(time);
  return bind(anchor, node, node + 1);
}

NodeBinding DeformationGraph::bind_around(const Eigen::Vector3d& point, int time) const {
  const int centre = node_at_time(time);
  const int half = impl_->options.temporal_window / 2;
  return bind(point, centre - half, centre + half);
}

void DeformationGraph::add_constraint(const Constraint& constraint) {
  const int size = static_cast<int>(impl_->nodes.size());
  for (const NodeBinding* binding : {&constraint.source_binding, &constraint.target_binding}) {
    if (binding->count < 0 || binding->count > kMaxBoundNodes) {
      throw_error(ErrorCode::kInvalidArgument, "deformation constraint: a binding of {} nodes", binding->count);
    }
    for (int i = 0; i < binding->count; ++i) {
      if (binding->nodes[i] < 0 || binding->nodes[i] >= size || !std::isfinite(binding->weights[i])) {
        throw_error(ErrorCode::kInvalidArgument, "deformation constraint: node {} of a graph of {}", binding->nodes[i],
                    size);
      }
    }
  }
  if (constraint.source_binding.count == 0) {
    throw_error(ErrorCode::kInvalidArgument, "deformation constraint: its source is bound to no node");
  }
  if (!finite(constraint.source) || !finite(constraint.target) || !finite(constraint.normal)) {
    throw_error(ErrorCode::kInvalidArgument, "deformation constraint: a point or normal is not finite");
  }
  if (!(constraint.weight > 0.0) || !std::isfinite(constraint.weight)) {
    throw_error(ErrorCode::kInvalidArgument, "deformation constraint: weight {} is not positive", constraint.weight);
  }
  impl_->constraints.push_back(constraint);
  ++impl_->structure_version;
}

void DeformationGraph::clear_constraints() {
  impl_->constraints.clear();
  ++impl_->structure_version;
}
const std::vector<Constraint>& DeformationGraph::constraints() const { return impl_->constraints; }

int DeformationGraph::add_rotation_prior(const Eigen::Vector3d& anchor, int time, const RotationPrior& prior) {
  Impl& s = *impl_;
  if (s.nodes.empty()) throw_error(ErrorCode::kInvalidArgument, "deformation graph: a rotation prior before any node");
  if (!finite(anchor)) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: a rotation prior's anchor is not finite");
  }
  const Eigen::Matrix3d& R = prior.rotation;
  if (!R.allFinite() || (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0.0) {
    throw_error(ErrorCode::kInvalidArgument, "deformation graph: the rotation prior of frame {} is not a rotation",
                time);
  }
  const Eigen::Matrix3d& L = prior.information;
  const double scale = L.cwiseAbs().maxCoeff();
  if (!L.allFinite() || (L - L.transpose()).norm() > 1e-9 * scale ||
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(L).eigenvalues().minCoeff() < -1e-9 * scale) {
    throw_error(ErrorCode::kInvalidArgument,
                "deformation graph: the rotation prior of frame {} has an information matrix that is not finite, "
                "symmetric and positive semi-definite",
                time);
  }
  PoseRotationPrior made = make_pose_rotation_prior(anchor, time, prior);
  made.binding = bind_pose(anchor, time);
  s.rotation_priors.push_back(std::move(made));
  ++s.structure_version;  // it couples the nodes of its binding
  return static_cast<int>(s.rotation_priors.size()) - 1;
}

std::size_t DeformationGraph::rotation_priors() const { return impl_->rotation_priors.size(); }

EnergyTerms DeformationGraph::energy() const { return evaluate_energy(impl_->model()); }

SolveStats DeformationGraph::solve(int iterations) {
  Impl& s = *impl_;
  const auto start = std::chrono::steady_clock::now();
  SolveStats stats;
  stats.constraints = s.constraints.size();
  const int pinned = s.pinned();
  const int free_nodes = static_cast<int>(s.nodes.size()) - pinned;
  if (free_nodes <= 0) {
    throw_error(ErrorCode::kInvalidArgument,
                "deformation graph: too few nodes: {} node(s), the first {} pinned, nothing to solve (a scan needs "
                "keyframes beyond the first {})",
                s.nodes.size(), s.options.pinned_nodes, s.options.pinned_nodes);
  }
  const std::string unreachable = s.unreachable_nodes();
  if (!unreachable.empty()) {
    throw_error(ErrorCode::kInvalidArgument,
                "deformation graph is disconnected: node(s) {} have no path of links to a pinned node (a jump "
                "beyond max_link_distance_m?)",
                unreachable);
  }
  const ResidualModel model = s.model();
  // The energy before the first step: the linear terms walked on their own, E_rot and the
  // constraints summed by the first assembly, which walks their blocks at the same
  // parameters: one walk fewer a solve.
  stats.before = evaluate_energy(model, iterations > 0 ? Terms::kLinear : Terms::kAll);
  stats.unknowns = 12 * free_nodes;
  const std::vector<Node> initial = s.nodes;
  EnergyTerms current = stats.before;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const auto assemble_start = std::chrono::steady_clock::now();
    const bool analysed = s.equations.prepare(model, &stats.factorize_ms);
    stats.analyzed = analysed || stats.analyzed;
    s.equations.assemble(model, iteration == 0 ? &stats.before : nullptr);
    if (iteration == 0) current = stats.before;
    const auto factorize_start = std::chrono::steady_clock::now();
    stats.assemble_ms += elapsed_ms(assemble_start, factorize_start);
    const int singular = s.equations.factorize(s.options.damping);
    if (singular >= 0) {
      const int node = pinned + singular / 12;
      const int parameter = singular % 12;
      s.nodes = initial;
      throw_error(ErrorCode::kInvalidArgument,
                  "deformation graph: singular system: nothing constrains node {} (frame {}) along {} (links: {}, "
                  "constraints: {}; set a damping > 0 or add links)",
                  node, s.nodes[static_cast<std::size_t>(node)].time,
                  parameter < 9 ? fmt::format("A({}, {})", parameter / 3, parameter % 3)
                                : fmt::format("t.{}", "xyz"[parameter - 9]),
                  s.neighbours[static_cast<std::size_t>(node)].size(), s.constraints.size());
    }
    const std::vector<double> step = s.equations.step();
    stats.factorize_ms += elapsed_ms(factorize_start, std::chrono::steady_clock::now());
    const std::vector<Node> before_step = s.nodes;
    double scale = 1.0;
    EnergyTerms trial;
    for (int halving = 0;; ++halving) {
      apply_step(&s.nodes, pinned, step, scale, s.options.length_scale_m);
      trial = evaluate_energy(model);
      if (trial.total() <= current.total() || halving == 8) break;
      s.nodes = before_step;
      scale *= 0.5;
      ++stats.step_halvings;
    }
    if (trial.total() > current.total()) {
      s.nodes = before_step;  // no step lowers the energy: at the minimum (to rounding)
      break;
    }
    current = trial;
    ++stats.iterations;
  }
  stats.after = current;
  stats.nonzeros = s.equations.nonzeros();
  for (std::size_t j = 0; j < s.nodes.size(); ++j) {
    stats.max_update_m = std::max(stats.max_update_m, (s.nodes[j].t - initial[j].t).norm());
  }
  stats.ms = elapsed_ms(start, std::chrono::steady_clock::now());
  return stats;
}

std::size_t DeformationGraph::analyses() const { return impl_->equations.analyses(); }
std::size_t DeformationGraph::factorizations() const { return impl_->equations.factorizations(); }

std::vector<NodeTransform> DeformationGraph::transforms() const {
  std::vector<NodeTransform> out;
  out.reserve(impl_->nodes.size());
  for (const Node& node : impl_->nodes) {
    NodeTransform transform;
    transform.g = to_vec(node.position);
    transform.A = to_mat(node.A);
    transform.t = to_vec(node.t);
    const double det = node.A.determinant();
    transform.A_inv_t = to_mat(std::abs(det) > 1e-12 ? Eigen::Matrix3d(node.A.inverse().transpose()) : node.A);
    out.push_back(transform);
  }
  return out;
}

Eigen::Vector3d DeformationGraph::deform(const Eigen::Vector3d& point, const NodeBinding& binding) const {
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  if (binding.count == 0) return point;
  for (int i = 0; i < binding.count; ++i) {
    const Node& node = impl_->nodes[static_cast<std::size_t>(binding.nodes[i])];
    out += binding.weights[i] * (node.A * (point - node.position) + node.position + node.t);
  }
  return out;
}

Eigen::Vector3d DeformationGraph::deform_normal(const Eigen::Vector3d& normal, const NodeBinding& binding) const {
  if (binding.count == 0) return normal;
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  for (int i = 0; i < binding.count; ++i) {
    const Node& node = impl_->nodes[static_cast<std::size_t>(binding.nodes[i])];
    out += binding.weights[i] * (node.A.inverse().transpose() * normal);
  }
  const double length = out.norm();
  return length > 0.0 ? Eigen::Vector3d(out / length) : out;
}

Pose DeformationGraph::deform_pose(const Pose& T_world_camera, const Eigen::Vector3d& anchor,
                                   const NodeBinding& binding) const {
  if (binding.count == 0) return T_world_camera;
  Eigen::Matrix3d blended = Eigen::Matrix3d::Zero();
  for (int i = 0; i < binding.count; ++i) {
    blended += binding.weights[i] * impl_->nodes[static_cast<std::size_t>(binding.nodes[i])].A;
  }
  const Eigen::Matrix3d rotation = nearest_rotation(blended);
  const Eigen::Vector3d moved_anchor = deform(anchor, binding);
  // x ↦ R (x − anchor) + moved_anchor, applied after the pose.
  const Pose correction(rotation, moved_anchor - rotation * anchor);
  return correction * T_world_camera;
}

void DeformationGraph::set_transform(int index, const Eigen::Matrix3d& A, const Eigen::Vector3d& t) {
  (void)node(index);  // range check
  impl_->nodes[static_cast<std::size_t>(index)].A = A;
  impl_->nodes[static_cast<std::size_t>(index)].t = t;
}

Eigen::VectorXd DeformationGraph::parameters() const {
  return pack_parameters(impl_->nodes, impl_->pinned(), impl_->options.length_scale_m);
}

void DeformationGraph::set_parameters(const Eigen::VectorXd& parameters) {
  unpack_parameters(parameters, &impl_->nodes, impl_->pinned(), impl_->options.length_scale_m);
}

Eigen::VectorXd DeformationGraph::residuals() const { return residual_vector(impl_->model()); }
Eigen::MatrixXd DeformationGraph::jacobian_dense() const { return dense_jacobian(impl_->model()); }

}  // namespace sls::fusion::deformation
