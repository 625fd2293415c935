// The deformation graph's Gauss–Newton normal equations (JᵀJ + μI) δ = −Jᵀr in 12 x 12 blocks,
// one block row and column per unpinned node, factored by SparseCholesky in a fill-reducing
// order of the blocks (AMD on the block pattern). The pattern kept is
// the union of every pattern seen since the unknowns last changed: a step whose blocks lie
// inside it reuses CHOLMOD's analysis (blocks it does not use are zeros), one that needs a new
// block (a new node, a constraint coupling nodes not coupled before) grows it and analyses
// again.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "fusion/deformation/residuals.h"
#include "fusion/deformation/sparse_cholesky.h"

namespace sls::fusion::deformation {

class NormalEquations {
 public:
  // Makes the pattern hold every block the model needs; true when it was analysed again
  // (adding the analysis' milliseconds to *analyze_ms).
  bool prepare(const ResidualModel& model, double* analyze_ms);
  // JᵀJ and Jᵀr from every residual block. With `energy`, the blocks' energies it walks are
  // added to it as evaluate_energy adds them: E_rot's and the constraints' (Terms::kNonlinear);
  // the linear terms' share is kept from a walk at the last change of the graph's structure.
  void assemble(const ResidualModel& model, EnergyTerms* energy = nullptr);
  // Factors JᵀJ + damping·I: -1, or the unknown whose pivot vanished (singular).
  int factorize(double damping);
  // −(JᵀJ + μI)⁻¹ Jᵀr.
  std::vector<double> step() const;

  std::size_t nonzeros() const { return scalar_rows_.size(); }
  std::size_t analyses() const { return solver_.analyses(); }
  std::size_t factorizations() const { return solver_.factorizations(); }

 private:
  int block_offset(int row_block, int column_block) const;   // -1: not in the pattern
  int pattern_offset(int row_block, int column_block) const; // the same; not in it: an internal error
  // Adds a block's JᵀJ to `hessian` (when given) and its Jᵀr to the gradient (when asked).
  void accumulate(const ResidualBlock& block, int pinned, std::vector<double>* hessian, bool gradient);

  int blocks_ = 0;                            // unknowns / 12
  std::size_t prepared_version_ = 0;          // the model's structure_version last prepared for
  std::vector<std::vector<int>> rows_;        // per block column, its row blocks (<= it), ascending
  std::vector<std::vector<int>> offsets_;     // each block's index into block_values_ (/ 144)
  // 144 per block, row-major: the linear share plus the nonlinear terms', written only in the
  // blocks the nonlinear terms touch (nonlinear_offsets_); factorize reads no other.
  std::vector<double> block_values_;
  std::vector<double> linear_values_;         // the linear terms' share (constant while the structure is)
  std::vector<int> nonlinear_offsets_;        // the blocks E_rot and the constraints touch, ascending
  std::vector<double> linear_gradient_;       // their Jᵀr at linear_parameters_
  Eigen::VectorXd linear_parameters_;
  bool linear_valid_ = false;
  std::vector<double> gradient_;              // Jᵀr
  std::vector<int> order_;  // the factored order: order_[P] is the block placed P-th
  // Where each stored block lies in the factored pattern: in ordered block column `column`,
  // the `index`-th row block; its column c's entries start at column_starts_[12 column + c]
  // + 12 index (only the diagonal block, the last, is shorter: r <= c).
  struct Placement {
    int column = 0;
    int index = 0;
    bool transposed = false;
    bool diagonal = false;
  };
  std::vector<Placement> placements_;
  // Writes a stored block's values (H, row-major) to their places in the factored pattern.
  void place_block(int offset, const double* H, double* values) const;
  std::vector<int> column_starts_, scalar_rows_;
  SparseCholesky solver_;
};

}  // namespace sls::fusion::deformation
