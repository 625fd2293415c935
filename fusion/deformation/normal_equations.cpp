#include "fusion/deformation/normal_equations.h"

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstring>

#include "sdk/core/error.h"

namespace sls::fusion::deformation {
namespace {

// The pairs (a <= b) of unknown blocks that nodes coupled by one residual block make.
void couple(const int* nodes, int count, int pinned, std::vector<std::pair<int, int>>* pairs) {
  for (int i = 0; i < count; ++i) {
    const int a = nodes[i] - pinned;
    if (a < 0) continue;
    for (int k = 0; k < count; ++k) {
      const int b = nodes[k] - pinned;
      if (b >= a) pairs->emplace_back(a, b);
    }
  }
}

// The outer products are most of a step's own work (CHOLMOD's factorisation aside): on
// x86-64 a clone built for AVX2, twice SSE2's lanes, is chosen at load time where the CPU has
// it. AVX2 alone, without FMA: every product and sum rounds as in the default clone.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define SLS_OUTER_PRODUCT_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SLS_OUTER_PRODUCT_CLONES
#endif

// H += Σ_rows J_iᵀ J_k over a block's rows (12 x 12, row-major), vectorisable. Within a
// block the Jacobians are sparse: E_rot, the rotation priors and E_reg's region part leave t
// alone, so the rows (J_i) and columns (J_k) of t are skipped where a Jacobian is zero there
// over every row (their products are zeros), and so is any other row of J_i that is zero.
// A one-row block (a point-to-plane constraint) adds its products to H directly; one of
// several rows sums them in a local array first (the compiler then knows nothing aliases) and
// adds the sum, as the rows' sum is rounded.
template <int kRows, int kColumns>
SLS_OUTER_PRODUCT_CLONES void add_outer_products_to(const ResidualBlock& block, int i, int k, double* __restrict H) {
  if (block.rows == 1) {
    const double* __restrict Ji = block.J[i][0];
    const double* __restrict Jk = block.J[k][0];
    for (int r = 0; r < kRows; ++r) {
      const double a = Ji[r];
      if (a == 0.0) continue;
      double* __restrict line = H + 12 * r;
      for (int c = 0; c < kColumns; ++c) line[c] += a * Jk[c];
    }
    return;
  }
  double local[static_cast<std::size_t>(kRows * kColumns)] = {};
  for (int row = 0; row < block.rows; ++row) {
    const double* __restrict Ji = block.J[i][row];
    const double* __restrict Jk = block.J[k][row];
    for (int r = 0; r < kRows; ++r) {
      const double a = Ji[r];
      if (a == 0.0) continue;
      double* __restrict line = local + kColumns * r;
      for (int c = 0; c < kColumns; ++c) line[c] += a * Jk[c];
    }
  }
  for (int r = 0; r < kRows; ++r) {
    for (int c = 0; c < kColumns; ++c) H[12 * r + c] += local[kColumns * r + c];
  }
}

// Whether a node's Jacobian in the block is zero in t (columns 9-11) over every row.
bool leaves_t_alone(const ResidualBlock& block, int slot) {
  for (int row = 0; row < block.rows; ++row) {
    const double* J = block.J[slot][row];
    if (J[9] != 0.0 || J[10] != 0.0 || J[11] != 0.0) return false;
  }
  return true;
}

void add_outer_products(const ResidualBlock& block, int i, int k, double* H) {
  const bool rows_t_free = leaves_t_alone(block, i);
  const bool columns_t_free = i == k ? rows_t_free : leaves_t_alone(block, k);
  if (rows_t_free) {
    if (columns_t_free) {
      add_outer_products_to<9, 9>(block, i, k, H);
    } else {
      add_outer_products_to<9, 12>(block, i, k, H);
    }
  } else if (columns_t_free) {
    add_outer_products_to<12, 9>(block, i, k, H);
  } else {
    add_outer_products_to<12, 12>(block, i, k, H);
  }
}

}  // namespace

int NormalEquations::block_offset(int row_block, int column_block) const {
  const std::vector<int>& rows = rows_[static_cast<std::size_t>(column_block)];
  const auto found = std::lower_bound(rows.begin(), rows.end(), row_block);
  if (found == rows.end() || *found != row_block) return -1;
  return offsets_[static_cast<std::size_t>(column_block)][static_cast<std::size_t>(found - rows.begin())];
}

int NormalEquations::pattern_offset(int row_block, int column_block) const {
  const int offset = block_offset(row_block, column_block);
  if (offset < 0) {
    throw_error(ErrorCode::kInternal, "deformation normal equations: block ({}, {}) not in the pattern", row_block,
                column_block);
  }
  return offset;
}

bool NormalEquations::prepare(const ResidualModel& model, double* analyze_ms) {
  const int blocks = static_cast<int>(model.nodes->size()) - model.pinned;
  if (solver_.analyzed() && blocks == blocks_ && model.structure_version == prepared_version_) return false;
  prepared_version_ = model.structure_version;
  // A structure changed (a rotation prior added, or rebound to a new node) changes the linear
  // terms' share, also where the pattern stays.
  linear_valid_ = false;
  std::vector<std::pair<int, int>> needed;
  for (int b = 0; b < blocks; ++b) needed.emplace_back(b, b);
  // The blocks each residual couples (as for_each_residual_block makes them, without
  // computing them).
  for (std::size_t j = 0; j < model.nodes->size(); ++j) {
    for (int k : (*model.neighbours)[j]) {
      const int link[2] = {static_cast<int>(j), k};
      couple(link, 2, model.pinned, &needed);
    }
  }
  const std::size_t constraints_begin = needed.size();
  for (const Constraint& constraint : *model.constraints) {
    int nodes[kMaxBlockNodes];
    int count = 0;
    for (const NodeBinding* binding : {&constraint.source_binding, &constraint.target_binding}) {
      for (int i = 0; i < binding->count; ++i) nodes[count++] = binding->nodes[i];
    }
    couple(nodes, count, model.pinned, &needed);
  }
  // E_rot's blocks (the diagonal) and the constraints' (their pairs, many repeated, kept before
  // the pattern's sort) are assembled every step; the others are the linear terms' alone.
  const std::vector<std::pair<int, int>> constraint_pairs(needed.begin() + static_cast<std::ptrdiff_t>(constraints_begin),
                                                          needed.end());
  const auto find_nonlinear_offsets = [&] {
    std::vector<char> touched(block_values_.size() / 144, 0);  // one per stored block
    for (int b = 0; b < blocks; ++b) touched[static_cast<std::size_t>(pattern_offset(b, b))] = 1;
    for (const auto& [a, b] : constraint_pairs) touched[static_cast<std::size_t>(pattern_offset(a, b))] = 1;
    nonlinear_offsets_.clear();
    for (std::size_t offset = 0; offset < touched.size(); ++offset) {
      if (touched[offset]) nonlinear_offsets_.push_back(static_cast<int>(offset));
    }
  };
  if (model.rotation_priors != nullptr) {
    for (const PoseRotationPrior& prior : *model.rotation_priors) {
      couple(prior.binding.nodes, prior.binding.count, model.pinned, &needed);
    }
  }
  std::sort(needed.begin(), needed.end());
  needed.erase(std::unique(needed.begin(), needed.end()), needed.end());
  bool inside = blocks == blocks_ && solver_.analyzed();
  for (std::size_t i = 0; inside && i < needed.size(); ++i) inside = block_offset(needed[i].first, needed[i].second) >= 0;
  if (inside) {
    find_nonlinear_offsets();
    return false;
  }

  // Grow: the union of the kept pattern (same unknowns only) and the needed one.
  std::vector<std::vector<int>> rows(static_cast<std::size_t>(blocks));
  if (blocks == blocks_) rows = rows_;
  rows.resize(static_cast<std::size_t>(blocks));
  for (const auto& [a, b] : needed) rows[static_cast<std::size_t>(b)].push_back(a);
  offsets_.assign(static_cast<std::size_t>(blocks), {});
  int count = 0;
  for (std::size_t b = 0; b < rows.size(); ++b) {
    std::sort(rows[b].begin(), rows[b].end());
    rows[b].erase(std::unique(rows[b].begin(), rows[b].end()), rows[b].end());
    for (std::size_t i = 0; i < rows[b].size(); ++i) offsets_[b].push_back(count++);
  }
  rows_ = std::move(rows);
  blocks_ = blocks;
  block_values_.assign(static_cast<std::size_t>(count) * 144, 0.0);
  find_nonlinear_offsets();
  linear_values_.assign(block_values_.size(), 0.0);
  gradient_.assign(static_cast<std::size_t>(blocks) * 12, 0.0);

  // The order the blocks are factored in: AMD on the block pattern (one entry per block), so
  // the scalar matrix is handed to CHOLMOD already ordered and whole blocks stay together.
  std::vector<int> block_starts(1, 0), block_rows;
  for (int b = 0; b < blocks; ++b) {
    block_rows.insert(block_rows.end(), rows_[static_cast<std::size_t>(b)].begin(), rows_[static_cast<std::size_t>(b)].end());
    block_starts.push_back(static_cast<int>(block_rows.size()));
  }
  order_ = SparseCholesky::fill_reducing_order(blocks, block_starts, block_rows);
  std::vector<int> position(static_cast<std::size_t>(blocks));
  for (int p = 0; p < blocks; ++p) position[static_cast<std::size_t>(order_[static_cast<std::size_t>(p)])] = p;
  // Per ordered block column P: its ordered row blocks Q <= P, with the stored block (a <= b)
  // each comes from and whether it is read transposed.
  struct OrderedBlock {
    int row = 0;             // ordered row block, <= its column
    int offset = 0;          // into block_values_ (/ 144)
    bool transposed = false; // the stored block (a <= b) is read as its transpose
  };
  std::vector<std::vector<OrderedBlock>> ordered(static_cast<std::size_t>(blocks));
  for (int b = 0; b < blocks; ++b) {
    for (std::size_t i = 0; i < rows_[static_cast<std::size_t>(b)].size(); ++i) {
      const int a = rows_[static_cast<std::size_t>(b)][i];
      const int offset = offsets_[static_cast<std::size_t>(b)][i];
      const int pa = position[static_cast<std::size_t>(a)], pb = position[static_cast<std::size_t>(b)];
      if (pa <= pb) {
        ordered[static_cast<std::size_t>(pb)].push_back({pa, offset, false});
      } else {
        ordered[static_cast<std::size_t>(pa)].push_back({pb, offset, true});
      }
    }
  }
  placements_.assign(static_cast<std::size_t>(count), {});
  for (int P = 0; P < blocks; ++P) {
    auto& column = ordered[static_cast<std::size_t>(P)];
    std::sort(column.begin(), column.end(), [](const OrderedBlock& x, const OrderedBlock& y) { return x.row < y.row; });
    for (std::size_t i = 0; i < column.size(); ++i) {
      placements_[static_cast<std::size_t>(column[i].offset)] = {P, static_cast<int>(i), column[i].transposed,
                                                                  column[i].row == P};
    }
  }
  // Scalar compressed columns of the ordered upper triangle: column 12P + c holds rows
  // 12Q + r of each row block Q (ascending), r <= c in the diagonal block.
  column_starts_.assign(1, 0);
  scalar_rows_.clear();
  for (int P = 0; P < blocks; ++P) {
    for (int c = 0; c < 12; ++c) {
      for (const OrderedBlock& block : ordered[static_cast<std::size_t>(P)]) {
        const int last = block.row == P ? c : 11;
        for (int r = 0; r <= last; ++r) scalar_rows_.push_back(12 * block.row + r);
      }
      column_starts_.push_back(static_cast<int>(scalar_rows_.size()));
    }
  }
  const auto start = std::chrono::steady_clock::now();
  solver_.analyze(12 * blocks, column_starts_, scalar_rows_);
  *analyze_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return true;
}

void NormalEquations::accumulate(const ResidualBlock& block, int pinned, std::vector<double>* hessian,
                                 bool gradient) {
  for (int i = 0; i < block.count; ++i) {
    const int a = block.nodes[i] - pinned;
    if (a < 0) continue;
    if (gradient) {
      double* g = &gradient_[static_cast<std::size_t>(12 * a)];
      for (int row = 0; row < block.rows; ++row) {
        for (int p = 0; p < 12; ++p) g[p] += block.J[i][row][p] * block.r[row];
      }
    }
    if (hessian == nullptr) continue;
    for (int k = 0; k < block.count; ++k) {
      const int b = block.nodes[k] - pinned;
      if (b < a) continue;
      const int offset = pattern_offset(a, b);
      add_outer_products(block, i, k, &(*hessian)[static_cast<std::size_t>(offset) * 144]);
    }
  }
}

void NormalEquations::assemble(const ResidualModel& model, EnergyTerms* energy) {
  std::fill(gradient_.begin(), gradient_.end(), 0.0);
  // The linear terms' residuals (E_reg, the rotation priors) are affine in the parameters x
  // with a constant Jacobian, so their share of JᵀJ is constant while the graph's structure
  // stays, and their share of Jᵀr is g₀ + JᵀJ (x − x₀) from one walk at x₀.
  const Eigen::VectorXd x = pack_parameters(*model.nodes, model.pinned, model.options->length_scale_m);
  if (!linear_valid_) {
    std::fill(linear_values_.begin(), linear_values_.end(), 0.0);
    for_each_residual_block(
        model, [&](const ResidualBlock& block) { accumulate(block, model.pinned, &linear_values_, true); },
        Terms::kLinear);
    // CHOLMOD reads its matrix and does not write it: the blocks no step rebuilds keep the
    // linear share placed here until the structure changes.
    for (std::size_t offset = 0; offset < placements_.size(); ++offset) {
      place_block(static_cast<int>(offset), &linear_values_[offset * 144], solver_.values());
    }
    linear_gradient_ = gradient_;
    linear_parameters_ = x;
    linear_valid_ = true;
  } else {
    gradient_ = linear_gradient_;
    const Eigen::VectorXd change = x - linear_parameters_;
    for (int b = 0; b < blocks_; ++b) {
      for (std::size_t i = 0; i < rows_[static_cast<std::size_t>(b)].size(); ++i) {
        const int a = rows_[static_cast<std::size_t>(b)][i];
        const double* H = &linear_values_[static_cast<std::size_t>(offsets_[static_cast<std::size_t>(b)][i]) * 144];
        for (int r = 0; r < 12; ++r) {
          for (int c = 0; c < 12; ++c) {
            const double h = H[12 * r + c];
            if (h == 0.0) continue;
            gradient_[static_cast<std::size_t>(12 * a + r)] += h * change[12 * b + c];
            if (a != b) gradient_[static_cast<std::size_t>(12 * b + c)] += h * change[12 * a + r];
          }
        }
      }
    }
  }
  // The nonlinear terms start from the linear share in the blocks they touch; the other blocks
  // are the linear share alone, left in place in the factored pattern.
  for (const int offset : nonlinear_offsets_) {
    const auto start = static_cast<std::size_t>(offset) * 144;
    std::memcpy(&block_values_[start], &linear_values_[start], 144 * sizeof(double));
  }
  for_each_residual_block(model, [&](const ResidualBlock& block) {
    accumulate(block, model.pinned, &block_values_, true);
    if (energy != nullptr) add_block_energy(block, energy);
  }, Terms::kNonlinear);
}

void NormalEquations::place_block(int offset, const double* H, double* values) const {
  const Placement& place = placements_[static_cast<std::size_t>(offset)];
  for (int c = 0; c < 12; ++c) {
    double* column = values + column_starts_[static_cast<std::size_t>(12 * place.column + c)] + 12 * place.index;
    const int last = place.diagonal ? c : 11;
    if (place.transposed) {
      for (int r = 0; r <= last; ++r) column[r] = H[12 * c + r];
    } else {
      for (int r = 0; r <= last; ++r) column[r] = H[12 * r + c];
    }
  }
}

int NormalEquations::factorize(double damping) {
  // The other blocks hold the linear share, placed by assemble. The diagonal blocks are among
  // those placed again here, so the damping is added to fresh values each time.
  double* values = solver_.values();
  for (const int offset : nonlinear_offsets_) {
    place_block(offset, &block_values_[static_cast<std::size_t>(offset) * 144], values);
  }
  // Each column's last entry is its diagonal.
  for (std::size_t column = 1; column < column_starts_.size(); ++column) {
    values[column_starts_[column] - 1] += damping;
  }
  const int singular = solver_.factorize();
  if (singular < 0) return -1;
  return 12 * order_[static_cast<std::size_t>(singular / 12)] + singular % 12;
}

std::vector<double> NormalEquations::step() const {
  std::vector<double> negative(gradient_.size());
  for (int P = 0; P < blocks_; ++P) {
    const int b = order_[static_cast<std::size_t>(P)];
    for (int i = 0; i < 12; ++i) negative[static_cast<std::size_t>(12 * P + i)] = -gradient_[static_cast<std::size_t>(12 * b + i)];
  }
  const std::vector<double> ordered = solver_.solve(negative);
  std::vector<double> step(ordered.size());
  for (int P = 0; P < blocks_; ++P) {
    const int b = order_[static_cast<std::size_t>(P)];
    for (int i = 0; i < 12; ++i) step[static_cast<std::size_t>(12 * b + i)] = ordered[static_cast<std::size_t>(12 * P + i)];
  }
  return step;
}

}  // namespace sls::fusion::deformation
