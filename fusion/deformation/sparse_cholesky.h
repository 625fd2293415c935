// The one sparse solver of the deformation graph: a symmetric positive definite system
// factored by CHOLMOD (SuiteSparse), the only file that sees CHOLMOD's types (DESIGN.md
// section 2). The pattern is analysed once (fill-reducing ordering and symbolic factor) and
// every numeric factorisation with the same pattern reuses that analysis; a new pattern is
// analysed again. Simplicial LDLᵀ of the matrix in the order it is given (the caller orders
// it, e.g. by fill_reducing_order() on a coarser pattern, so CHOLMOD factors it without a
// permuted copy): deterministic (no BLAS in the factor), and the systems of a deformation
// graph (12 unknowns a node, a few neighbours each) are too sparse for supernodes to pay.
//
//   SparseCholesky solver;
//   solver.analyze(n, column_starts, rows);   // upper triangle, compressed columns
//   solver.factorize(values);                 // same pattern, as often as the values change
//   std::vector<double> x = solver.solve(b);
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

namespace sls::fusion::deformation {

class SparseCholesky {
 public:
  SparseCholesky();
  ~SparseCholesky();
  SparseCholesky(SparseCholesky&&) noexcept;
  SparseCholesky& operator=(SparseCholesky&&) noexcept;

  // A fill-reducing order (AMD) of a symmetric pattern given as analyze() takes it:
  // order[i] is the index placed i-th.
  static std::vector<int> fill_reducing_order(int n, const std::vector<int>& column_starts,
                                              const std::vector<int>& rows);

  // The pattern of the upper triangle of an n x n symmetric matrix in compressed columns:
  // column c's rows are rows[column_starts[c] .. column_starts[c + 1]), ascending, each <= c,
  // the diagonal included. Replaces any earlier analysis. sls::Error(kInvalidArgument) for a
  // malformed pattern, kOutOfMemory when CHOLMOD cannot allocate.
  void analyze(int n, const std::vector<int>& column_starts, const std::vector<int>& rows);
  bool analyzed() const;
  int size() const;

  // The numeric factorisation of the analysed pattern with these values (one per entry, in
  // the pattern's order). Returns -1, or, when the matrix is not positive definite (a
  // singular system: unknowns nothing constrains), the unknown (column) whose pivot vanished:
  // one at most 1e-12 of its diagonal entry, zero, negative or not finite. The factor is then
  // unusable until a factorisation succeeds.
  int factorize(const std::vector<double>& values);
  // The same, with the values written in place first: values() is the analysed pattern's
  // array (one per entry, in its order), kept between factorisations, so a caller that fills
  // it skips a copy. Null before analyze().
  double* values();
  int factorize();
  // x = A⁻¹ b with the last factorisation.
  std::vector<double> solve(const std::vector<double>& b) const;

  // How many times a pattern was analysed and a matrix factored (the analysis is reused
  // between factorisations of one pattern).
  std::size_t analyses() const;
  std::size_t factorizations() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::fusion::deformation
