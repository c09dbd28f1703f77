// BlockLdlt (block_ldlt.hpp): the node-block sparse LDL^T behind the
// Cholesky preconditioner and the multigrid's coarse solve.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "cloth_sim/block_ldlt.hpp"

namespace cloth_sim {
namespace {

struct BlockSystem {
  Eigen::SparseMatrix<double> lower;  ///< lower triangle, as CholeskyFactor builds it
  Eigen::MatrixXd dense;              ///< the whole matrix
};

Mat3 randomSpd(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Mat3 g;
  for (int e = 0; e < 9; ++e) g.data()[e] = u(rng);
  return scale * (g * g.transpose() + 0.1 * Mat3::Identity());
}

/// A cloth-like SPD matrix on a rows x cols grid: node blocks (masses) plus,
/// per coupled pair (a, b), (e_a - e_b)(e_a - e_b)^T (x) S with S SPD: the
/// 8 grid neighbours and `far_pairs` random pairs (self contacts).
BlockSystem clothLike(int rows, int cols, int far_pairs, unsigned seed, double stiffness = 1e2) {
  std::mt19937 rng(seed);
  const int n = rows * cols;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int i = 0; i < n; ++i) A.block<3, 3>(3 * i, 3 * i) += randomSpd(rng, 1e-3);
  std::vector<std::pair<int, int>> pairs;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const int i = r * cols + c;
      if (c + 1 < cols) pairs.emplace_back(i, i + 1);
      if (r + 1 < rows) pairs.emplace_back(i, i + cols);
      if (r + 1 < rows && c + 1 < cols) pairs.emplace_back(i, i + cols + 1);
      if (r + 1 < rows && c > 0) pairs.emplace_back(i, i + cols - 1);
    }
  }
  std::uniform_int_distribution<int> node(0, n - 1);
  for (int k = 0; k < far_pairs; ++k) {
    const int a = node(rng), b = node(rng);
    if (a != b) pairs.emplace_back(a, b);
  }
  for (const auto& [a, b] : pairs) {
    const Mat3 S = randomSpd(rng, stiffness);
    A.block<3, 3>(3 * a, 3 * a) += S;
    A.block<3, 3>(3 * b, 3 * b) += S;
    A.block<3, 3>(3 * a, 3 * b) -= S;
    A.block<3, 3>(3 * b, 3 * a) -= S;
  }
  // Lower triangle with whole off-diagonal blocks (zeros kept) for each pair.
  std::vector<Eigen::Triplet<double>> entries;
  auto block = [&](int hi, int lo) {
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) {
        const int row = 3 * hi + r, col = 3 * lo + c;
        if (row >= col) entries.emplace_back(row, col, 0.0);
      }
    }
  };
  for (int i = 0; i < n; ++i) block(i, i);
  for (const auto& [a, b] : pairs) block(std::max(a, b), std::min(a, b));
  BlockSystem system;
  system.lower.resize(3 * n, 3 * n);
  system.lower.setFromTriplets(entries.begin(), entries.end());
  system.lower.makeCompressed();
  for (int c = 0; c < system.lower.outerSize(); ++c) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(system.lower, c); it; ++it) {
      it.valueRef() = A(it.row(), c);
    }
  }
  system.dense = A;
  return system;
}

/// Normwise backward error |A z - b| / (|A| |z| + |b|): round-off for a
/// stable factorization, whatever A's condition.
double backwardError(const Eigen::MatrixXd& A, const VecX& z, const VecX& b) {
  return (A * z - b).norm() / (A.norm() * z.norm() + b.norm());
}

double relativeError(const VecX& x, const VecX& exact) { return (x - exact).norm() / exact.norm(); }

/// The backward error of the factor's solve of A z = b for a random b.
double solveBackwardError(const BlockLdlt& ldlt, const Eigen::MatrixXd& A) {
  const VecX b = VecX::Random(A.rows());
  VecX z;
  ldlt.solve(b, z);
  return backwardError(A, z, b);
}

TEST(BlockLdlt, SolvesAClothLikeSystemToRoundOff) {
  const BlockSystem s = clothLike(12, 10, 40, 1, 1e-2);  // condition ~1e3
  BlockLdlt ldlt;
  ldlt.analyzePattern(s.lower);
  ASSERT_TRUE(ldlt.factorize(s.lower));
  const VecX b = VecX::Random(s.dense.rows());
  VecX z;
  ldlt.solve(b, z);
  EXPECT_LT(relativeError(z, s.dense.llt().solve(b)), 1e-12);
  EXPECT_LT(backwardError(s.dense, z, b), 1e-15);
}

// The held pairs' correction (linear_solver.cpp) solves L w = P c over a
// row's paths up the elimination tree only and splits the solve around its
// correction: both must match the whole solve.
TEST(BlockLdlt, SparseForwardSolveMatchesTheWholeOne) {
  const BlockSystem s = clothLike(12, 10, 40, 3, 1e-2);
  BlockLdlt ldlt;
  ldlt.analyzePattern(s.lower);
  ASSERT_TRUE(ldlt.factorize(s.lower));
  const int n = ldlt.numNodes();
  // A row on four nodes, one repeated (its entries add), as a pair's.
  const std::vector<int> nodes = {5, 17, 64, 100, 17};
  std::vector<Vec3> c;
  VecX dense = VecX::Zero(3 * n);
  for (int i : nodes) {
    c.push_back(Vec3::Random());
    dense.segment<3>(3 * i) += c.back();
  }
  std::vector<Vec3> whole;
  ldlt.forwardSolve(dense, whole);
  for (int pass = 0; pass < 2; ++pass) {  // the second: its scratch is clean again
    std::vector<int> positions;
    std::vector<Vec3> w;
    ldlt.forwardSolveSparse(nodes, c, &positions, &w);
    ASSERT_EQ(positions.size(), w.size());
    EXPECT_LT(positions.size(), static_cast<size_t>(n) / 2);  // the point of it
    EXPECT_TRUE(std::is_sorted(positions.begin(), positions.end()));
    std::vector<char> reached(n, 0);
    for (size_t a = 0; a < positions.size(); ++a) {
      reached[positions[a]] = 1;
      EXPECT_LT((w[a] - whole[positions[a]]).norm(), 1e-14 * (1.0 + whole[positions[a]].norm()));
    }
    for (int k = 0; k < n; ++k) {
      if (!reached[k]) EXPECT_EQ(whole[k].norm(), 0.0) << "position " << k << " outside the paths";
    }
  }
  // forwardSolve then backwardSolve is solve.
  VecX z_whole, z_split;
  ldlt.solve(dense, z_whole);
  ldlt.backwardSolve(whole, z_split);
  EXPECT_EQ((z_whole - z_split).norm(), 0.0);
}

TEST(BlockLdlt, RefactorsNewValuesOnTheSamePattern) {
  const BlockSystem first = clothLike(9, 9, 20, 2);
  const BlockSystem second = clothLike(9, 9, 20, 2, 5e6);  // same pairs, stiffer values
  BlockLdlt ldlt;
  ldlt.analyzePattern(first.lower);
  ASSERT_TRUE(ldlt.factorize(first.lower));
  ASSERT_TRUE(ldlt.factorize(second.lower));
  EXPECT_LT(solveBackwardError(ldlt, second.dense), 1e-15);  // condition ~1e12: the error itself is not small
}

TEST(BlockLdlt, RefactorsOnlyTheRowsAChangeReachesBitForBit) {
  // A contact pass changes a few nodes' rows: the factor redoes those rows
  // and their ancestors in the elimination tree and must equal, bit for
  // bit, a factor made from scratch (the answers may not depend on it).
  const BlockSystem s = clothLike(12, 12, 15, 6);
  Eigen::SparseMatrix<double> changed = s.lower;
  Eigen::MatrixXd changed_dense = s.dense;
  for (int node : {17, 90}) {  // one node's block scaled: its row and column change
    for (int r = 0; r < 3; ++r) {
      changed.coeffRef(3 * node + r, 3 * node) *= 1.5;
      changed_dense(3 * node + r, 3 * node) *= 1.5;
      if (r > 0) changed_dense(3 * node, 3 * node + r) *= 1.5;
    }
  }
  BlockLdlt reused, fresh;
  reused.analyzePattern(s.lower);
  fresh.analyzePattern(s.lower);
  ASSERT_TRUE(reused.factorize(s.lower));
  EXPECT_EQ(reused.rowsFactored(), reused.numNodes());
  ASSERT_TRUE(reused.factorize(changed));
  ASSERT_TRUE(fresh.factorize(changed));
  EXPECT_GT(reused.rowsFactored(), 0);
  EXPECT_LT(reused.rowsFactored(), reused.numNodes());
  const VecX b = VecX::Random(changed_dense.rows());
  VecX z_reused, z_fresh;
  reused.solve(b, z_reused);
  fresh.solve(b, z_fresh);
  EXPECT_EQ((z_reused - z_fresh).norm(), 0.0);
  EXPECT_LT(backwardError(changed_dense, z_reused, b), 1e-15);
  // The same matrix again: nothing to redo, the same answer.
  ASSERT_TRUE(reused.factorize(changed));
  EXPECT_EQ(reused.rowsFactored(), 0);
  reused.solve(b, z_reused);
  EXPECT_EQ((z_reused - z_fresh).norm(), 0.0);
  // Back to the first matrix after a failed factor: made from scratch.
  Eigen::SparseMatrix<double> broken = s.lower;
  broken.coeffRef(3 * 5, 3 * 5) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(reused.factorize(broken));
  ASSERT_TRUE(reused.factorize(s.lower));
  EXPECT_EQ(reused.rowsFactored(), reused.numNodes());
  EXPECT_LT(solveBackwardError(reused, s.dense), 1e-15);
}

TEST(BlockLdlt, FactorsAnIndefiniteMatrixExactly) {
  // Newton's exact Hessian can be indefinite: the factor goes on (no zero
  // pivot), as Eigen's scalar LDL^T did, and still solves exactly.
  BlockSystem s = clothLike(8, 8, 10, 3);
  BlockLdlt ldlt;
  ldlt.analyzePattern(s.lower);
  s.lower.coeffRef(3 * 20, 3 * 20) = -1e4;  // one node's xx entry
  s.dense(3 * 20, 3 * 20) = -1e4;
  ASSERT_TRUE(ldlt.factorize(s.lower));
  EXPECT_LT(solveBackwardError(ldlt, s.dense), 1e-15);
}

TEST(BlockLdlt, RefusesANonFiniteMatrixAndFactorsTheNextOne) {
  const BlockSystem s = clothLike(8, 8, 10, 5);
  BlockLdlt ldlt;
  ldlt.analyzePattern(s.lower);
  Eigen::SparseMatrix<double> broken = s.lower;
  broken.coeffRef(3 * 30 + 1, 3 * 30) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(ldlt.factorize(broken));
  ASSERT_TRUE(ldlt.factorize(s.lower));  // no scratch left over from the failure
  EXPECT_LT(solveBackwardError(ldlt, s.dense), 1e-15);
}

TEST(BlockLdlt, FillOfAClothGridMatchesScalarMinimumDegree) {
  // The node order (AMD on the node graph) fills no more than Eigen's
  // scalar AMD on the same matrix: a worse order costs every solve.
  const BlockSystem s = clothLike(16, 16, 0, 4);
  BlockLdlt ldlt;
  ldlt.analyzePattern(s.lower);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower> scalar;
  scalar.analyzePattern(s.lower);
  ASSERT_TRUE(ldlt.factorize(s.lower));
  scalar.factorize(s.lower);
  // Strictly lower scalar entries: 9 a block below the diagonal, 3 within a node.
  const long block_entries = 9L * ldlt.lowerBlocks() + 3L * ldlt.numNodes();
  const long scalar_entries = scalar.matrixL().nestedExpression().nonZeros();
  EXPECT_LE(block_entries, static_cast<long>(1.05 * scalar_entries))
      << "block fill " << block_entries << ", scalar fill " << scalar_entries;
}

}  // namespace
}  // namespace cloth_sim
