// A sparse LDL^T factorization that works on 3 x 3 node blocks: the system
// matrices of the cloth (one block per node and per coupled node pair) are
// factored and solved with fixed-size block products instead of scalar
// sparse loops, for the Cholesky preconditioner and the multigrid's coarse
// solve. Ordering: approximate minimum degree on the node graph.
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <vector>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// P A P^T = L D L^T with L unit lower block triangular and D block diagonal
/// (3 x 3 symmetric blocks, SPD for an SPD A), P a node permutation.
///
/// Input: the lower triangle (row >= col) of a symmetric 3n x 3n matrix in
/// Eigen's compressed column storage. Entries of one node pair form a block;
/// a block's missing entries count as zero.
class BlockLdlt {
 public:
  /// Orders the nodes and lays out L for `lower`'s pattern.
  void analyzePattern(const Eigen::SparseMatrix<double>& lower);
  /// Factors `lower` (the analysed pattern, new values). Returns false, and
  /// keeps no factor, where a pivot block is singular or not finite; an
  /// indefinite one is factored on (D then has it), as Eigen's scalar LDL^T did.
  /// Only the rows of the factor that depend on a row where A differs from
  /// the last factored matrix are computed again (those rows and their
  /// ancestors in the elimination tree): a contact pass that changed a few
  /// nodes' filter refactors those paths. The factor is the same, bit for
  /// bit, as one made from scratch.
  bool factorize(const Eigen::SparseMatrix<double>& lower);
  /// Rows the last factorize computed (n_ when made from scratch; for tests).
  int rowsFactored() const { return rows_factored_; }
  /// z = A^-1 r (needs a successful factorize). z may not alias r.
  void solve(const VecX& r, VecX& z) const;
  /// solve's two halves: y = L^-1 P r (one 3-vector per factor position),
  /// then z = P^T L^-T D^-1 y (y overwritten), for a correction between them.
  void forwardSolve(const VecX& r, std::vector<Vec3>& y) const;
  void backwardSolve(std::vector<Vec3>& y, VecX& z) const;
  /// w = L^-1 P c for a c nonzero only on `nodes` (c[k] at nodes[k]; a
  /// repeated node adds): a forward solve over the nodes' paths up the
  /// elimination tree, where alone w can be nonzero (L's column j is nonzero
  /// only at ancestors of j). Output: those positions, ascending, and w there.
  void forwardSolveSparse(const std::vector<int>& nodes, const std::vector<Vec3>& c,
                          std::vector<int>* positions, std::vector<Vec3>* w) const;
  int position(int node) const { return perm_[node]; }
  /// D's block at a factor position, inverted.
  const Mat3& dInverse(int position) const { return d_inverse_[position]; }
  /// Blocks of L below the diagonal (for tests and the docs' fill figures).
  int lowerBlocks() const { return static_cast<int>(l_rows_.size()); }
  int numNodes() const { return n_; }

 private:
  int n_ = 0;
  std::vector<int> perm_;   ///< node -> position in the factor
  std::vector<int> iperm_;  ///< position -> node
  /// A's blocks, row by row in factor order: row k holds its diagonal block
  /// (first) and the blocks (k, j), j < k.
  std::vector<int> a_row_start_, a_col_;
  /// Per scalar entry of the input, the value slots (block * 9 + 3c + r) it
  /// fills; the second is -1 unless it sits off the diagonal of a node block.
  std::vector<int> entry_slot_, entry_mirror_;
  std::vector<Mat3> a_blocks_;
  std::vector<Mat3> factored_blocks_;  ///< a_blocks_ of the last factor made
  bool factored_ = false;              ///< factored_blocks_ and L, D belong together
  int rows_factored_ = 0;
  std::vector<int> parent_;                   ///< elimination tree
  std::vector<int> l_start_;                  ///< column j of L: [l_start_[j], l_start_[j+1])
  std::vector<int> l_rows_;                   ///< rows of L's blocks, column by column
  std::vector<Mat3> l_blocks_;                ///< L's blocks
  std::vector<Mat3> d_inverse_;               ///< D's blocks inverted
  // Factorization scratch (kept to avoid allocating per factorization).
  std::vector<int> l_fill_, pattern_, mark_;
  std::vector<char> redo_;  ///< rows this factorize computes
  std::vector<Mat3> row_;
  mutable std::vector<Vec3> work_;
  mutable std::vector<Vec3> sparse_work_;  ///< zero outside a forwardSolveSparse
  mutable std::vector<char> sparse_seen_;
};

}  // namespace cloth_sim
