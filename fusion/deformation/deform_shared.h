// The embedded deformation of one point or normal (paper eqs. 18–19, Sumner et al. 2007),
// one body of per-element math for every loop that deforms the map (DESIGN.md section 6):
//
//   ṽ = Σ_j w_j(v) [A_j (v − g_j) + g_j + t_j]            (18)
//   w_j(v) = (1 − ‖v − g_j‖ / d_max)², normalised to sum 1 (19)
//   ñ = normalise(Σ_j w_j(v) A_j⁻ᵀ n)                      (normals: the inverse transpose)
//
// over the k nodes bound to the point (NodeBinding: which nodes, with their weights), d_max
// the distance to the nearest candidate node after those k. Node j's transform is
// x ↦ A_j (x − g_j) + g_j + t_j, held with A_j⁻ᵀ precomputed (NodeTransform).
#pragma once

#include <cmath>

#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::fusion::deformation {

constexpr int kMaxBoundNodes = 8;

// The nodes that deform a point and their weights (eq. 19, normalised). count == 0: none
// (the point is not deformed: a fixed target).
struct NodeBinding {
  int count = 0;
  int nodes[kMaxBoundNodes] = {};
  double weights[kMaxBoundNodes] = {};
};

template <typename T>
struct NodeTransformT {
  Vec3T<T> g;          // the node's position
  Mat3T<T> A;          // its affine part
  Vec3T<T> t;          // its translation
  Mat3T<T> A_inv_t;    // (A⁻¹)ᵀ, for normals
};
using NodeTransform = NodeTransformT<double>;

// Eq. (19) for candidate distances sorted ascending: the weights of the first `count`
// (normalised), d_max = distances[count] (the next candidate) or, when there is none, the
// last distance times 1.5 (so the farthest bound node still counts). All weights zero (every
// node as far as d_max): equal weights.
SLS_HOST_DEVICE inline void blend_weights(const double* sorted_distances, int candidates, int count,
                                          double* weights) {
  double d_max = count < candidates ? sorted_distances[count] : 1.5 * sorted_distances[count - 1];
  if (!(d_max > 0.0)) d_max = 1.0;  // every candidate on the point: equal weights below
  double sum = 0.0;
  for (int i = 0; i < count; ++i) {
    const double f = 1.0 - sorted_distances[i] / d_max;
    weights[i] = f > 0.0 ? f * f : 0.0;
    sum += weights[i];
  }
  for (int i = 0; i < count; ++i) weights[i] = sum > 0.0 ? weights[i] / sum : 1.0 / count;
}

// The binding of point p among candidate nodes (positions `g` of `candidates` nodes with
// indices first .. first + candidates − 1): the k nearest, ties to the lower index, and eq.
// (19)'s weights with d_max the distance to the next nearest candidate.
template <typename T>
SLS_HOST_DEVICE inline NodeBinding bind_nearest(const Vec3T<T>* g, int first, int candidates, int k, Vec3T<T> p) {
  NodeBinding binding;
  if (candidates <= 0 || k <= 0) return binding;
  if (k > kMaxBoundNodes) k = kMaxBoundNodes;
  // Insertion into the k + 1 nearest so far (ascending distance; equal distances keep the
  // earlier, i.e. older, node first).
  double distances[kMaxBoundNodes + 1];
  int nodes[kMaxBoundNodes + 1];
  int kept = 0;
  for (int c = 0; c < candidates; ++c) {
    const double d = static_cast<double>(norm(g[c] - p));
    if (kept == k + 1 && !(d < distances[k])) continue;
    int at = kept < k + 1 ? kept++ : k;
    while (at > 0 && d < distances[at - 1]) {
      distances[at] = distances[at - 1];
      nodes[at] = nodes[at - 1];
      --at;
    }
    distances[at] = d;
    nodes[at] = first + c;
  }
  binding.count = kept < k ? kept : k;
  for (int i = 0; i < binding.count; ++i) binding.nodes[i] = nodes[i];
  blend_weights(distances, kept, binding.count, binding.weights);
  return binding;
}

// One node's transform of a point: A (v − g) + g + t.
template <typename T>
SLS_HOST_DEVICE inline Vec3T<T> node_apply(const NodeTransformT<T>& node, Vec3T<T> v) {
  return node.A * (v - node.g) + node.g + node.t;
}

// Eq. (18).
template <typename T>
SLS_HOST_DEVICE inline Vec3T<T> deform_point(const NodeTransformT<T>* nodes, const NodeBinding& binding, Vec3T<T> v) {
  if (binding.count == 0) return v;
  Vec3T<T> out{T(0), T(0), T(0)};
  for (int i = 0; i < binding.count; ++i) {
    out = out + static_cast<T>(binding.weights[i]) * node_apply(nodes[binding.nodes[i]], v);
  }
  return out;
}

// The blended inverse transpose applied to a normal, renormalised (a zero normal stays zero).
template <typename T>
SLS_HOST_DEVICE inline Vec3T<T> deform_normal(const NodeTransformT<T>* nodes, const NodeBinding& binding,
                                              Vec3T<T> n) {
  if (binding.count == 0) return n;
  Vec3T<T> out{T(0), T(0), T(0)};
  for (int i = 0; i < binding.count; ++i) {
    out = out + static_cast<T>(binding.weights[i]) * (nodes[binding.nodes[i]].A_inv_t * n);
  }
  const T length = norm(out);
  return length > T(0) ? (T(1) / length) * out : out;
}

}  // namespace sls::fusion::deformation
