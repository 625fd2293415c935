// The sparse Cholesky wrapper of the deformation graph's solver (fusion/deformation/
// sparse_cholesky.h, CHOLMOD): a known system solved, malformed patterns refused, a singular
// matrix named by its unknown, values written in place.
#include <cstddef>
#include <vector>

#include <gtest/gtest.h>

#include "fusion/deformation/sparse_cholesky.h"
#include "sdk/core/error.h"

namespace sls::fusion::deformation {
namespace {

TEST(SparseCholesky, SolvesAndRefusesMalformedPatterns) {
  // [[4 1 0] [1 3 1] [0 1 2]] x = b.
  SparseCholesky solver;
  solver.analyze(3, {0, 1, 3, 5}, {0, 0, 1, 1, 2});
  ASSERT_EQ(solver.factorize({4, 1, 3, 1, 2}), -1);
  const std::vector<double> x = solver.solve({1, 2, 3});
  EXPECT_NEAR(4 * x[0] + x[1], 1.0, 1e-12);
  EXPECT_NEAR(x[0] + 3 * x[1] + x[2], 2.0, 1e-12);
  EXPECT_NEAR(x[1] + 2 * x[2], 3.0, 1e-12);
  // Singular: [[1 1] [1 1]].
  SparseCholesky singular;
  singular.analyze(2, {0, 1, 3}, {0, 0, 1});
  EXPECT_GE(singular.factorize({1, 1, 1}), 0);
  EXPECT_THROW(singular.solve({1, 1}), Error);
  EXPECT_THROW(solver.analyze(2, {0, 1, 2}, {0, 0}), Error);  // column 1 lacks its diagonal
  EXPECT_THROW(solver.analyze(2, {0, 2, 3}, {1, 0, 1}), Error);
}

// The values written in place (what the normal equations do) factor as the copied ones, bit
// for bit, and are kept between factorisations of the pattern.
TEST(SparseCholesky, ValuesWrittenInPlaceFactorAsTheCopiedOnes) {
  SparseCholesky unanalysed;
  EXPECT_EQ(unanalysed.values(), nullptr);
  EXPECT_THROW(unanalysed.factorize(), Error);
  const std::vector<double> values = {4, 1, 3, 1, 2};
  SparseCholesky copied, in_place;
  copied.analyze(3, {0, 1, 3, 5}, {0, 0, 1, 1, 2});
  in_place.analyze(3, {0, 1, 3, 5}, {0, 0, 1, 1, 2});
  ASSERT_EQ(copied.factorize(values), -1);
  double* entries = in_place.values();
  ASSERT_NE(entries, nullptr);
  for (std::size_t k = 0; k < values.size(); ++k) entries[k] = values[k];
  ASSERT_EQ(in_place.factorize(), -1);
  EXPECT_EQ(in_place.solve({1, 2, 3}), copied.solve({1, 2, 3}));
  ASSERT_EQ(in_place.factorize(), -1);  // the values stay: the same factor again
  EXPECT_EQ(in_place.solve({1, 2, 3}), copied.solve({1, 2, 3}));
  entries[4] = 0.25;  // [[4 1 0] [1 3 1] [0 1 0.25]]: not positive definite
  EXPECT_EQ(in_place.factorize(), 2);
  EXPECT_THROW(in_place.solve({1, 2, 3}), Error);
}

}  // namespace
}  // namespace sls::fusion::deformation
