#include "cloth_sim/block_ldlt.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/OrderingMethods>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>

#include "vectorised.hpp"

namespace cloth_sim {

void BlockLdlt::analyzePattern(const Eigen::SparseMatrix<double>& lower) {
  const int n = static_cast<int>(lower.rows() / 3);
  n_ = n;
  // The node blocks `lower` holds, each once, by block column b: (a, b), a >= b.
  // (Per node block, not per scalar entry: a heap's self pairs make the
  // pattern again every few steps, and 9x the entries cost 9x the sorting.)
  std::vector<int> col_start(n + 1, 0), col_node;
  col_node.reserve(static_cast<size_t>(lower.nonZeros()) / 4 + n);
  {
    std::vector<int> seen(n, -1);
    for (int b = 0; b < n; ++b) {
      for (int c = 3 * b; c < 3 * b + 3; ++c) {
        for (Eigen::SparseMatrix<double>::InnerIterator it(lower, c); it; ++it) {
          const int a = static_cast<int>(it.row()) / 3;
          if (seen[a] == b) continue;
          seen[a] = b;
          col_node.push_back(a);
        }
      }
      col_start[b + 1] = static_cast<int>(col_node.size());
    }
  }
  // Fill-reducing order of the node graph (both triangles; Eigen's AMD
  // wants the diagonal too: without it the fill here is 30 % larger).
  std::vector<Eigen::Triplet<double>> graph;
  graph.reserve(2 * col_node.size() + n);
  for (int b = 0; b < n; ++b) {
    for (int e = col_start[b]; e < col_start[b + 1]; ++e) {
      const int a = col_node[e];
      if (a != b) {
        graph.emplace_back(a, b, 1.0);
        graph.emplace_back(b, a, 1.0);
      }
    }
  }
  for (int i = 0; i < n; ++i) graph.emplace_back(i, i, 1.0);
  Eigen::SparseMatrix<double> nodes(n, n);
  nodes.setFromTriplets(graph.begin(), graph.end());
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order;
  Eigen::AMDOrdering<int>()(nodes, order);  // order(position) = node
  iperm_.assign(order.indices().data(), order.indices().data() + n);
  perm_.assign(n, 0);
  for (int k = 0; k < n; ++k) perm_[iperm_[k]] = k;

  // A's blocks in factor order, row k: (k, k) first, then (k, j < k) ascending.
  a_row_start_.assign(n + 1, 0);
  for (int b = 0; b < n; ++b) {
    for (int e = col_start[b]; e < col_start[b + 1]; ++e) {
      const int a = col_node[e];
      if (a != b) ++a_row_start_[std::max(perm_[a], perm_[b]) + 1];
    }
  }
  for (int k = 0; k < n; ++k) a_row_start_[k + 1] += a_row_start_[k] + 1;  // + the diagonal
  a_col_.assign(a_row_start_[n], 0);
  {
    std::vector<int> next(a_row_start_.begin(), a_row_start_.end() - 1);
    for (int k = 0; k < n; ++k) a_col_[next[k]++] = k;
    for (int b = 0; b < n; ++b) {
      for (int e = col_start[b]; e < col_start[b + 1]; ++e) {
        const int a = col_node[e];
        if (a == b) continue;
        const int k = std::max(perm_[a], perm_[b]);
        a_col_[next[k]++] = std::min(perm_[a], perm_[b]);
      }
    }
    for (int k = 0; k < n; ++k) std::sort(a_col_.begin() + a_row_start_[k] + 1, a_col_.begin() + a_row_start_[k + 1]);
  }
  auto blockId = [&](int k, int j) {
    const auto first = a_col_.begin() + a_row_start_[k] + 1, last = a_col_.begin() + a_row_start_[k + 1];
    return static_cast<int>(std::lower_bound(first, last, j) - a_col_.begin());
  };
  // Where each scalar entry goes: block (k, j) holds rows of node iperm(k),
  // columns of node iperm(j); a pair stored the other way round is transposed.
  // (The block of each (a, b) found once per block column, then reused.)
  entry_slot_.assign(lower.nonZeros(), -1);
  entry_mirror_.assign(lower.nonZeros(), -1);
  std::vector<int> block_of(n, -1);
  int e = 0;
  for (int b = 0; b < n; ++b) {
    for (int q = col_start[b]; q < col_start[b + 1]; ++q) {
      const int a = col_node[q];
      const int pa = perm_[a], pb = perm_[b];
      block_of[a] = a == b ? a_row_start_[pa] : pa > pb ? blockId(pa, pb) : blockId(pb, pa);
    }
    for (int c = 3 * b; c < 3 * b + 3; ++c) {
      for (Eigen::SparseMatrix<double>::InnerIterator it(lower, c); it; ++it, ++e) {
        const int row = static_cast<int>(it.row());
        const int a = row / 3, ra = row % 3, cb = c % 3;
        const int block = block_of[a];
        if (a == b) {
          entry_slot_[e] = 9 * block + 3 * cb + ra;
          if (ra != cb) entry_mirror_[e] = 9 * block + 3 * ra + cb;
        } else if (perm_[a] > perm_[b]) {
          entry_slot_[e] = 9 * block + 3 * cb + ra;
        } else {
          entry_slot_[e] = 9 * block + 3 * ra + cb;
        }
      }
    }
  }
  a_blocks_.assign(a_col_.size(), Mat3::Zero());
  factored_ = false;

  // Elimination tree and L's column counts (row k of L: the nodes met walking
  // up the tree from each j of A's row k, as in Eigen's simplicial analysis).
  parent_.assign(n, -1);
  mark_.assign(n, -1);
  std::vector<int> count(n, 0);
  for (int k = 0; k < n; ++k) {
    mark_[k] = k;
    for (int b = a_row_start_[k] + 1; b < a_row_start_[k + 1]; ++b) {
      for (int i = a_col_[b]; mark_[i] != k; i = parent_[i]) {
        if (parent_[i] == -1) parent_[i] = k;
        ++count[i];
        mark_[i] = k;
      }
    }
  }
  l_start_.assign(n + 1, 0);
  for (int j = 0; j < n; ++j) l_start_[j + 1] = l_start_[j] + count[j];
  l_rows_.assign(l_start_[n], 0);
  l_blocks_.assign(l_start_[n], Mat3::Zero());
  d_inverse_.assign(n, Mat3::Identity());
  l_fill_.assign(n, 0);
  pattern_.assign(n, 0);
  row_.assign(n, Mat3::Zero());
  work_.assign(n, Vec3::Zero());
}

namespace {

/// row[rows[p]] -= w L_p^T for p in [begin, end): one column of L updating
/// the row being factored (3x3 blocks in column order, X(r, c) at 3c + r).
/// Most of a factorization; built for AVX2/FMA and the baseline (as the
/// triangular solves below: Eigen's fixed-size product stays scalar here).
CLOTH_SIM_VECTORISED
void columnUpdate(int begin, int end, const int* __restrict rows, const double* __restrict l,
                  const double* __restrict w, double* __restrict row) {
  const double w0 = w[0], w1 = w[1], w2 = w[2], w3 = w[3], w4 = w[4], w5 = w[5], w6 = w[6],
               w7 = w[7], w8 = w[8];
  for (int p = begin; p < end; ++p) {
    const double* m = l + 9 * static_cast<size_t>(p);
    double* t = row + 9 * static_cast<size_t>(rows[p]);
    for (int c = 0; c < 3; ++c) {
      const double m0 = m[c], m1 = m[3 + c], m2 = m[6 + c];
      t[3 * c] -= w0 * m0 + w3 * m1 + w6 * m2;
      t[3 * c + 1] -= w1 * m0 + w4 * m1 + w7 * m2;
      t[3 * c + 2] -= w2 * m0 + w5 * m1 + w8 * m2;
    }
  }
}

}  // namespace

bool BlockLdlt::factorize(const Eigen::SparseMatrix<double>& lower) {
  const int n = n_;
  a_blocks_.assign(a_col_.size(), Mat3::Zero());  // (held the factor before last's: swapped)
  const double* values = lower.valuePtr();
  double* slots = a_blocks_.front().data();
  for (size_t e = 0; e < entry_slot_.size(); ++e) {
    slots[entry_slot_[e]] += values[e];
    if (entry_mirror_[e] >= 0) slots[entry_mirror_[e]] += values[e];
  }
  // Row k of L and D depends on A's row k and on the rows of L in its row
  // pattern, all descendants of k in the elimination tree. So a row that
  // changed in A changes its own row of the factor and its ancestors' only;
  // every other row is the last factor's. (From scratch after an analysis
  // or a failure.)
  const bool partial = factored_;
  factored_ = false;  // until this factor is whole
  redo_.assign(n, partial ? 0 : 1);
  if (partial) {
    for (int k = 0; k < n; ++k) {
      const int b0 = a_row_start_[k], b1 = a_row_start_[k + 1];
      if (std::memcmp(&a_blocks_[b0], &factored_blocks_[b0], sizeof(Mat3) * (b1 - b0)) == 0) {
        continue;
      }
      for (int i = k; i >= 0 && !redo_[i]; i = parent_[i]) redo_[i] = 1;
    }
  }
  rows_factored_ = static_cast<int>(std::count(redo_.begin(), redo_.end(), 1));
  std::copy(l_start_.begin(), l_start_.end() - 1, l_fill_.begin());
  std::fill(mark_.begin(), mark_.end(), -1);
  // Up-looking: row k of L from A's row k and the rows above it. With
  // W = L D, W(k, i) = A(k, i) - sum over j < i of W(k, j) L(i, j)^T.
  // A kept row's entries stay where they are in L's columns (rows
  // ascending): a redone row first moves each column's fill past them.
  for (int k = 0; k < n; ++k) {
    if (!redo_[k]) continue;
    int top = n;
    mark_[k] = k;
    for (int b = a_row_start_[k] + 1; b < a_row_start_[k + 1]; ++b) {
      int i = a_col_[b];
      row_[i] += a_blocks_[b];
      int len = 0;
      for (; mark_[i] != k; i = parent_[i]) {
        pattern_[len++] = i;
        mark_[i] = k;
      }
      while (len > 0) pattern_[--top] = pattern_[--len];
    }
    Mat3 d = a_blocks_[a_row_start_[k]];
    for (; top < n; ++top) {
      const int i = pattern_[top];  // ancestors after descendants
      if (partial) {
        while (l_rows_[l_fill_[i]] < k) ++l_fill_[i];  // row k's entry is in the column
      }
      const Mat3 w = row_[i];
      row_[i].setZero();
      columnUpdate(l_start_[i], l_fill_[i], l_rows_.data(),
                   reinterpret_cast<const double*>(l_blocks_.data()), w.data(),
                   reinterpret_cast<double*>(row_.data()));
      const Mat3 l = w * d_inverse_[i];
      d.noalias() -= l * w.transpose();
      l_rows_[l_fill_[i]] = k;
      l_blocks_[l_fill_[i]++] = l;
    }
    if (!d.allFinite()) return false;  // row_ is all zero again
    const Eigen::LLT<Mat3> pivot(d);
    if (pivot.info() == Eigen::Success) {
      d_inverse_[k] = pivot.solve(Mat3::Identity());
    } else {
      // Indefinite: factored on, as Eigen's scalar LDL^T did (it failed
      // only on a zero pivot). Refusing it made the contact cases worse
      // (c4 under newton at stretch 1e7, dt 0.1: recovered, then failed
      // with 61 refused factors; also session 37's probe): where Newton's
      // exact Hessian is indefinite the caller's recovery decides, and an
      // indefinite preconditioner still takes CG to its tolerance or stops it.
      const Mat3 sym = 0.5 * (d + d.transpose());
      const double det = sym.determinant();
      if (!(std::abs(det) > 0.0) || !std::isfinite(det)) return false;
      d_inverse_[k] = sym.inverse();
    }
  }
  factored_blocks_.swap(a_blocks_);
  factored_ = true;
  return true;
}

void BlockLdlt::solve(const VecX& r, VecX& z) const {
  forwardSolve(r, work_);
  backwardSolve(work_, z);
}

namespace {

// The triangular solves on raw arrays: y is 3 doubles a position, a block of
// L 9 doubles in column order (Mat3's storage). Built for AVX2/FMA and the
// baseline (vectorised.hpp): in the baseline build each block product was 9
// multiplies and 6 adds a scalar chain; they are most of a Cholesky-
// preconditioned CG iteration (the hard cases: half of a newton step).

/// y = L^-1 y in place (column order: column j's blocks update the rows below).
CLOTH_SIM_VECTORISED
void forwardKernel(int n, const int* __restrict start, const int* __restrict rows,
                   const double* __restrict l, double* __restrict y) {
  for (int j = 0; j < n; ++j) {
    const double y0 = y[3 * j], y1 = y[3 * j + 1], y2 = y[3 * j + 2];
    for (int p = start[j]; p < start[j + 1]; ++p) {
      const double* m = l + 9 * static_cast<size_t>(p);
      double* t = y + 3 * rows[p];
      t[0] -= m[0] * y0 + m[3] * y1 + m[6] * y2;
      t[1] -= m[1] * y0 + m[4] * y1 + m[7] * y2;
      t[2] -= m[2] * y0 + m[5] * y1 + m[8] * y2;
    }
  }
}

/// y = D^-1 y, then y = L^-T y in place (column j gathers the rows below it).
/// Two sets of sums, so the chains of adds are half as long.
CLOTH_SIM_VECTORISED
void backwardKernel(int n, const int* __restrict start, const int* __restrict rows,
                    const double* __restrict l, const double* __restrict d_inverse,
                    double* __restrict y) {
  for (int j = 0; j < n; ++j) {
    const double* m = d_inverse + 9 * static_cast<size_t>(j);
    const double y0 = y[3 * j], y1 = y[3 * j + 1], y2 = y[3 * j + 2];
    y[3 * j] = m[0] * y0 + m[3] * y1 + m[6] * y2;
    y[3 * j + 1] = m[1] * y0 + m[4] * y1 + m[7] * y2;
    y[3 * j + 2] = m[2] * y0 + m[5] * y1 + m[8] * y2;
  }
  for (int j = n - 1; j >= 0; --j) {
    double a0 = y[3 * j], a1 = y[3 * j + 1], a2 = y[3 * j + 2];
    double b0 = 0.0, b1 = 0.0, b2 = 0.0;
    int p = start[j];
    const int end = start[j + 1];
    auto gather = [&](int q, double& s0, double& s1, double& s2) {
      const double* m = l + 9 * static_cast<size_t>(q);
      const double* t = y + 3 * rows[q];
      s0 -= m[0] * t[0] + m[1] * t[1] + m[2] * t[2];
      s1 -= m[3] * t[0] + m[4] * t[1] + m[5] * t[2];
      s2 -= m[6] * t[0] + m[7] * t[1] + m[8] * t[2];
    };
    for (; p + 1 < end; p += 2) {
      gather(p, a0, a1, a2);
      gather(p + 1, b0, b1, b2);
    }
    if (p < end) gather(p, a0, a1, a2);
    y[3 * j] = a0 + b0;
    y[3 * j + 1] = a1 + b1;
    y[3 * j + 2] = a2 + b2;
  }
}

}  // namespace

void BlockLdlt::forwardSolve(const VecX& r, std::vector<Vec3>& y) const {
  const int n = n_;
  y.resize(n);
  for (int k = 0; k < n; ++k) y[k] = r.segment<3>(3 * iperm_[k]);
  // L y = P r. Vec3 and Mat3 are plain arrays of 3 and 9 doubles.
  static_assert(sizeof(Vec3) == 3 * sizeof(double) && sizeof(Mat3) == 9 * sizeof(double));
  forwardKernel(n, l_start_.data(), l_rows_.data(),
                reinterpret_cast<const double*>(l_blocks_.data()),
                reinterpret_cast<double*>(y.data()));
}

void BlockLdlt::backwardSolve(std::vector<Vec3>& y, VecX& z) const {
  const int n = n_;
  // L^T x = D^-1 y
  backwardKernel(n, l_start_.data(), l_rows_.data(),
                 reinterpret_cast<const double*>(l_blocks_.data()),
                 reinterpret_cast<const double*>(d_inverse_.data()),
                 reinterpret_cast<double*>(y.data()));
  z.resize(3 * n);
  for (int k = 0; k < n; ++k) z.segment<3>(3 * iperm_[k]) = y[k];
}

void BlockLdlt::forwardSolveSparse(const std::vector<int>& nodes, const std::vector<Vec3>& c,
                                   std::vector<int>* positions, std::vector<Vec3>* w) const {
  if (sparse_work_.size() != static_cast<size_t>(n_)) {
    sparse_work_.assign(n_, Vec3::Zero());
    sparse_seen_.assign(n_, 0);
  }
  positions->clear();
  for (size_t k = 0; k < nodes.size(); ++k) {
    sparse_work_[perm_[nodes[k]]] += c[k];
    for (int j = perm_[nodes[k]]; j != -1 && !sparse_seen_[j]; j = parent_[j]) {
      sparse_seen_[j] = 1;
      positions->push_back(j);
    }
  }
  std::sort(positions->begin(), positions->end());
  w->resize(positions->size());
  for (size_t a = 0; a < positions->size(); ++a) {
    const int j = (*positions)[a];
    const Vec3 wj = sparse_work_[j];
    for (int p = l_start_[j]; p < l_start_[j + 1]; ++p) sparse_work_[l_rows_[p]].noalias() -= l_blocks_[p] * wj;
    (*w)[a] = wj;
    sparse_work_[j].setZero();
    sparse_seen_[j] = 0;
  }
}

}  // namespace cloth_sim
