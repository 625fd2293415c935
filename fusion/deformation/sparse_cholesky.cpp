#include "fusion/deformation/sparse_cholesky.h"

#include <cmath>
#include <utility>

#include <cholmod.h>

#include "sdk/core/error.h"

namespace sls::fusion::deformation {

struct SparseCholesky::Impl {
  cholmod_common common{};
  cholmod_sparse* matrix = nullptr;  // the analysed pattern, values filled per factorisation
  cholmod_factor* factor = nullptr;
  int n = 0;
  bool factored = false;
  std::size_t analyses = 0;
  std::size_t factorizations = 0;

  Impl() {
    cholmod_start(&common);
    common.supernodal = CHOLMOD_SIMPLICIAL;  // see the header: small, very sparse, deterministic
    common.final_ll = 0;                     // LDLᵀ: the pivots are D's diagonal, checked below
    common.print = 0;
    // The order given (see the header), not postordered: factored without a permuted copy.
    common.nmethods = 1;
    common.method[0].ordering = CHOLMOD_NATURAL;
    common.postorder = 0;
    common.error_handler = nullptr;          // errors come back through common.status
  }
  ~Impl() {
    release();
    cholmod_finish(&common);
  }
  void release() {
    if (factor != nullptr) cholmod_free_factor(&factor, &common);
    if (matrix != nullptr) cholmod_free_sparse(&matrix, &common);
    factored = false;
  }
  void check_status(const char* what) {
    if (common.status == CHOLMOD_OUT_OF_MEMORY) {
      throw_error(ErrorCode::kOutOfMemory, "sparse Cholesky: CHOLMOD ran out of memory in {}", what);
    }
    if (common.status < CHOLMOD_OK) {
      throw_error(ErrorCode::kInternal, "sparse Cholesky: CHOLMOD failed in {} (status {})", what, common.status);
    }
  }
};

SparseCholesky::SparseCholesky() : impl_(std::make_unique<Impl>()) {}
SparseCholesky::~SparseCholesky() = default;
SparseCholesky::SparseCholesky(SparseCholesky&&) noexcept = default;
SparseCholesky& SparseCholesky::operator=(SparseCholesky&&) noexcept = default;

namespace {

void check_pattern(int n, const std::vector<int>& column_starts, const std::vector<int>& rows) {
  if (n <= 0) throw_error(ErrorCode::kInvalidArgument, "sparse Cholesky: a system of {} unknowns", n);
  if (column_starts.size() != static_cast<std::size_t>(n) + 1 || column_starts.front() != 0 ||
      column_starts.back() != static_cast<int>(rows.size())) {
    throw_error(ErrorCode::kInvalidArgument, "sparse Cholesky: {} column starts and {} rows for {} unknowns",
                column_starts.size(), rows.size(), n);
  }
  for (int c = 0; c < n; ++c) {
    const int begin = column_starts[static_cast<std::size_t>(c)], end = column_starts[static_cast<std::size_t>(c) + 1];
    if (end <= begin || rows[static_cast<std::size_t>(end) - 1] != c) {
      throw_error(ErrorCode::kInvalidArgument, "sparse Cholesky: column {} lacks its diagonal entry", c);
    }
    for (int k = begin; k < end; ++k) {
      const int r = rows[static_cast<std::size_t>(k)];
      if (r < 0 || r > c || (k > begin && rows[static_cast<std::size_t>(k) - 1] >= r)) {
        throw_error(ErrorCode::kInvalidArgument, "sparse Cholesky: column {}: rows not ascending in [0, {}]", c, c);
      }
    }
  }
}

// A CHOLMOD matrix holding the pattern (values zero).
cholmod_sparse* make_matrix(int n, const std::vector<int>& column_starts, const std::vector<int>& rows,
                            cholmod_common* common) {
  cholmod_sparse* matrix = cholmod_allocate_sparse(static_cast<std::size_t>(n), static_cast<std::size_t>(n), rows.size(),
                                                   /*sorted=*/1, /*packed=*/1, /*stype=*/1, CHOLMOD_REAL, common);
  if (matrix == nullptr) return nullptr;
  int* p = static_cast<int*>(matrix->p);
  int* i = static_cast<int*>(matrix->i);
  double* x = static_cast<double*>(matrix->x);
  for (std::size_t c = 0; c < column_starts.size(); ++c) p[c] = column_starts[c];
  for (std::size_t k = 0; k < rows.size(); ++k) {
    i[k] = rows[k];
    x[k] = 0.0;
  }
  return matrix;
}

}  // namespace

std::vector<int> SparseCholesky::fill_reducing_order(int n, const std::vector<int>& column_starts,
                                                     const std::vector<int>& rows) {
  check_pattern(n, column_starts, rows);
  Impl scratch;
  cholmod_sparse* matrix = make_matrix(n, column_starts, rows, &scratch.common);
  if (matrix == nullptr) scratch.check_status("allocate");
  std::vector<int> order(static_cast<std::size_t>(n));
  const int ok = cholmod_amd(matrix, nullptr, 0, order.data(), &scratch.common);
  cholmod_free_sparse(&matrix, &scratch.common);
  if (!ok) scratch.check_status("amd");
  return order;
}

void SparseCholesky::analyze(int n, const std::vector<int>& column_starts, const std::vector<int>& rows) {
  Impl& s = *impl_;
  check_pattern(n, column_starts, rows);
  s.release();
  s.n = n;
  s.matrix = make_matrix(n, column_starts, rows, &s.common);
  if (s.matrix == nullptr) s.check_status("allocate");
  s.factor = cholmod_analyze(s.matrix, &s.common);
  if (s.factor == nullptr) s.check_status("analyze");
  ++s.analyses;
}

bool SparseCholesky::analyzed() const { return impl_->factor != nullptr; }
int SparseCholesky::size() const { return impl_->n; }

double* SparseCholesky::values() { return impl_->matrix != nullptr ? static_cast<double*>(impl_->matrix->x) : nullptr; }

int SparseCholesky::factorize(const std::vector<double>& values) {
  Impl& s = *impl_;
  if (s.factor == nullptr) throw_error(ErrorCode::kInternal, "sparse Cholesky: factorize before analyze");
  if (values.size() != s.matrix->nzmax) {
    throw_error(ErrorCode::kInternal, "sparse Cholesky: {} values for a pattern of {}", values.size(), s.matrix->nzmax);
  }
  double* x = static_cast<double*>(s.matrix->x);
  for (std::size_t k = 0; k < values.size(); ++k) x[k] = values[k];
  return factorize();
}

int SparseCholesky::factorize() {
  Impl& s = *impl_;
  if (s.factor == nullptr) throw_error(ErrorCode::kInternal, "sparse Cholesky: factorize before analyze");
  s.factored = false;
  const double* x = static_cast<const double*>(s.matrix->x);
  cholmod_factorize(s.matrix, s.factor, &s.common);
  ++s.factorizations;
  const int* perm = static_cast<const int*>(s.factor->Perm);  // the identity (natural order)
  const auto unknown_of = [perm](int column) { return perm != nullptr ? perm[column] : column; };
  if (s.common.status == CHOLMOD_NOT_POSDEF) {
    const auto minor = static_cast<int>(s.factor->minor);
    return minor < s.n ? unknown_of(minor) : 0;
  }
  s.check_status("factorize");
  // A pivot that vanished against its diagonal entry: the matrix is singular (to rounding),
  // and the solution along that unknown would be noise. D is the first entry of each column
  // of the simplicial LDLᵀ factor; column j of the factor is unknown perm[j].
  const int* column_start = static_cast<const int*>(s.matrix->p);
  const int* lp = static_cast<const int*>(s.factor->p);
  const double* lx = static_cast<const double*>(s.factor->x);
  for (int j = 0; j < s.n; ++j) {
    const int unknown = unknown_of(j);
    const double diagonal = x[column_start[unknown + 1] - 1];  // the column's last entry is its diagonal
    const double pivot = lx[lp[j]];
    if (!std::isfinite(pivot) || !(pivot > 1e-12 * std::abs(diagonal))) return unknown;
  }
  s.factored = true;
  return -1;
}

std::vector<double> SparseCholesky::solve(const std::vector<double>& b) const {
  Impl& s = *impl_;
  if (!s.factored) throw_error(ErrorCode::kInternal, "sparse Cholesky: solve without a successful factorisation");
  if (b.size() != static_cast<std::size_t>(s.n)) {
    throw_error(ErrorCode::kInternal, "sparse Cholesky: a right-hand side of {} for {} unknowns", b.size(), s.n);
  }
  cholmod_dense* rhs = cholmod_allocate_dense(b.size(), 1, b.size(), CHOLMOD_REAL, &s.common);
  if (rhs == nullptr) s.check_status("allocate");
  double* r = static_cast<double*>(rhs->x);
  for (std::size_t k = 0; k < b.size(); ++k) r[k] = b[k];
  cholmod_dense* solution = cholmod_solve(CHOLMOD_A, s.factor, rhs, &s.common);
  cholmod_free_dense(&rhs, &s.common);
  if (solution == nullptr) s.check_status("solve");
  const double* x = static_cast<const double*>(solution->x);
  std::vector<double> out(x, x + b.size());
  cholmod_free_dense(&solution, &s.common);
  return out;
}

std::size_t SparseCholesky::analyses() const { return impl_->analyses; }
std::size_t SparseCholesky::factorizations() const { return impl_->factorizations; }

}  // namespace sls::fusion::deformation
