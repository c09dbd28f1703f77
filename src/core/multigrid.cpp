#include "cloth_sim/multigrid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "cloth_sim/linear_solver.hpp"
#include "vectorised.hpp"

namespace cloth_sim {


namespace {

/// Fine lines that carry a coarse line: every other one and the last one
/// (for an even count it replaces the second last), so ceil(m / 2) lines for
/// m >= 3. Two or fewer lines are kept as they are.
std::vector<int> coarseLines(int m) {
  std::vector<int> lines;
  if (m <= 2) {
    for (int i = 0; i < m; ++i) lines.push_back(i);
    return lines;
  }
  for (int p = 0; p < m - 1; p += 2) lines.push_back(p);
  if (m % 2 == 0) {
    lines.back() = m - 1;
  } else {
    lines.push_back(m - 1);
  }
  return lines;
}

/// Linear interpolation of one fine line from at most two coarse lines.
struct LineWeights {
  int coarse[2] = {0, 0};
  double weight[2] = {0.0, 0.0};
  int count = 0;
};

std::vector<LineWeights> lineInterpolation(int m, const std::vector<int>& lines) {
  std::vector<LineWeights> w(m);
  size_t k = 0;
  for (int f = 0; f < m; ++f) {
    while (k + 1 < lines.size() && lines[k + 1] <= f) ++k;
    if (lines[k] == f) {
      w[f].coarse[0] = static_cast<int>(k);
      w[f].weight[0] = 1.0;
      w[f].count = 1;
    } else {
      const double t = static_cast<double>(f - lines[k]) / (lines[k + 1] - lines[k]);
      w[f].coarse[0] = static_cast<int>(k);
      w[f].coarse[1] = static_cast<int>(k + 1);
      w[f].weight[0] = 1.0 - t;
      w[f].weight[1] = t;
      w[f].count = 2;
    }
  }
  return w;
}

SymBlock identityBlock() { return {{1, 1, 1, 0, 0, 0}}; }

/// Sorts and deduplicates each row's columns into compressed rows.
void compressRows(std::vector<std::vector<int>>& rows, std::vector<int>& begin,
                  std::vector<int>& column) {
  begin.assign(rows.size() + 1, 0);
  column.clear();
  for (size_t i = 0; i < rows.size(); ++i) {
    std::sort(rows[i].begin(), rows[i].end());
    rows[i].erase(std::unique(rows[i].begin(), rows[i].end()), rows[i].end());
    column.insert(column.end(), rows[i].begin(), rows[i].end());
    begin[i + 1] = static_cast<int>(column.size());
  }
}

int findColumn(const std::vector<int>& begin, const std::vector<int>& column, int i, int j) {
  const auto first = column.begin() + begin[i], last = column.begin() + begin[i + 1];
  const auto it = std::lower_bound(first, last, j);
  return (it != last && *it == j) ? static_cast<int>(it - column.begin()) : -1;
}

/// The finest level's refill from one direction's springs (fillFinest):
/// each spring's S at both ends (2S, and 4S in the middle, where rerouted)
/// and -S (-2S on each half) on its lower blocks. Built for AVX2/FMA too: a
/// block update is then 2 vector FMAs, not 3 SSE2 multiply-adds (hang64:
/// this loop was ~10 % of a step).
CLOTH_SIM_VECTORISED
void addDirection(int slots, int offset, const double* __restrict valid,
                  const double* __restrict iso, const double* __restrict axis,
                  const double* __restrict u0, const double* __restrict u1,
                  const double* __restrict u2, const double* __restrict c,
                  const double* __restrict w0, const double* __restrict w1,
                  const double* __restrict w2, const int* __restrict via,
                  const int* __restrict block_a, const int* __restrict block_b,
                  SymBlock* __restrict node_block, SymBlock* __restrict lower) {
  for (int p = 0; p < slots; ++p) {
    if (valid[p] == 0.0) continue;
    const double a = axis[p], i = iso[p], x = u0[p], y = u1[p], z = u2[p];
    SymBlock S{{i + a * x * x, i + a * y * y, i + a * z * z, a * x * y, a * x * z, a * y * z}};
    if (c) {
      const double e = c[p], wx = w0[p], wy = w1[p], wz = w2[p];
      S.addScaled(1.0, {{e * wx * wx, e * wy * wy, e * wz * wz, e * wx * wy, e * wx * wz,
                         e * wy * wz}});
    }
    const int m = via[p];
    if (m < 0) {
      node_block[p].addScaled(1.0, S);
      node_block[p + offset].addScaled(1.0, S);
      if (block_a[p] >= 0) lower[block_a[p]].addScaled(-1.0, S);
      continue;
    }
    // Rerouted: 2S on each half, so 2S at each end, 4S in the middle, and
    // -2S on each half's coupling.
    node_block[p].addScaled(2.0, S);
    node_block[p + offset].addScaled(2.0, S);
    node_block[m].addScaled(4.0, S);
    if (block_a[p] >= 0) lower[block_a[p]].addScaled(-2.0, S);
    if (block_b[p] >= 0) lower[block_b[p]].addScaled(-2.0, S);
  }
}

/// The Galerkin refill's sums (galerkin()): each fine block times each pair
/// of its row's and column's interpolation weights onto the coarse block
/// `target` names (< nc: node block; else lower block target - nc; -1:
/// counted by its mirror pair). Built for AVX2/FMA too, as addDirection.
CLOTH_SIM_VECTORISED
void galerkinSums(int n, int nc, const int* __restrict interp_begin,
                  const double* __restrict interp_weight, const SymBlock* __restrict node_block,
                  const int* __restrict lower_begin, const int* __restrict lower_column,
                  const SymBlock* __restrict lower_block, const int* __restrict target,
                  SymBlock* __restrict coarse_node, SymBlock* __restrict coarse_lower) {
  auto add = [&](int t, double weight, const SymBlock& block) {
    if (t < 0) return;
    if (t < nc) {
      coarse_node[t].addScaled(weight, block);
    } else {
      coarse_lower[t - nc].addScaled(weight, block);
    }
  };
  for (int i = 0; i < n; ++i) {
    const int a0 = interp_begin[i], a1 = interp_begin[i + 1];
    if (a0 == a1) continue;  // a pinned node: no targets either
    const SymBlock& D = node_block[i];
    for (int a = a0; a < a1; ++a) {
      for (int b = a0; b < a1; ++b) add(*target++, interp_weight[a] * interp_weight[b], D);
    }
    for (int s = lower_begin[i]; s < lower_begin[i + 1]; ++s) {
      const int j = lower_column[s];
      const SymBlock& L = lower_block[s];
      for (int a = a0; a < a1; ++a) {
        for (int b = interp_begin[j]; b < interp_begin[j + 1]; ++b) {
          // L_ij and its mirror L_ji both land on a coarse node block when I == J.
          const int t = *target++;
          add(t, (t < nc ? 2.0 : 1.0) * interp_weight[a] * interp_weight[b], L);
        }
      }
    }
  }
}

}  // namespace

void MultigridPreconditioner::buildHierarchy(const SystemMatrix& A,
                                             const std::vector<Spring>& springs,
                                             const std::vector<char>& free, int rows,
                                             int cols) {
  levels_.clear();
  levels_.emplace_back();
  {
    Level& finest = levels_.back();
    finest.rows = rows;
    finest.cols = cols;
    finest.num_nodes = rows * cols;
    finest.free = free;
    // Lower pattern: every spring between two free nodes, a spring two grid
    // lines long by its two halves (see the header) unless this level is the
    // only one: its direct solve is then exact.
    const bool one_level = finest.num_nodes <= kMaxCoarsestNodes ||
                           coarseLines(rows).size() * coarseLines(cols).size() ==
                               static_cast<size_t>(finest.num_nodes);
    auto via = [&](const Spring& s) {
      return one_level ? -1 : middleNode(s, finest.num_nodes, cols);
    };
    auto pair_of = [&](int a, int b) { return free[a] && free[b] && a != b; };
    std::vector<std::vector<int>> lower(finest.num_nodes);
    auto add_pair = [&](int a, int b) {
      if (pair_of(a, b)) lower[std::max(a, b)].push_back(std::min(a, b));
    };
    for (const Spring& s : springs) {
      const int m = via(s);
      if (m < 0) {
        add_pair(s.i, s.j);
      } else {
        add_pair(s.i, m);
        add_pair(m, s.j);
      }
    }
    compressRows(lower, finest.lower_begin, finest.lower_column);
    auto block_of = [&](int a, int b) {
      return pair_of(a, b) ? findColumn(finest.lower_begin, finest.lower_column, std::max(a, b),
                                        std::min(a, b))
                           : -1;
    };
    const SpringLayout& layout = *A.layout();
    slot_targets_.assign(layout.directions.size(), {});
    for (size_t d = 0; d < layout.directions.size(); ++d) {
      SlotTargets& t = slot_targets_[d];
      const int slots = layout.directions[d].slots;
      t.via.assign(slots, -1);
      t.block_a.assign(slots, -1);
      t.block_b.assign(slots, -1);
    }
    for (size_t k = 0; k < springs.size(); ++k) {
      const Spring& s = springs[k];
      const SpringSlot& slot = layout.slot[k];
      SlotTargets& t = slot_targets_[slot.direction];
      const int m = via(s), p = slot.node;
      t.via[p] = m;
      if (m < 0) {
        t.block_a[p] = block_of(s.i, s.j);
      } else {
        t.block_a[p] = block_of(s.i, m);
        t.block_b[p] = block_of(m, s.j);
      }
    }
  }

  // Coarser levels until small enough or the grid stops shrinking.
  while (levels_.back().num_nodes > kMaxCoarsestNodes) {
    Level& fine = levels_.back();
    const std::vector<int> row_lines = coarseLines(fine.rows), col_lines = coarseLines(fine.cols);
    Level coarse;
    coarse.rows = static_cast<int>(row_lines.size());
    coarse.cols = static_cast<int>(col_lines.size());
    coarse.num_nodes = coarse.rows * coarse.cols;
    if (coarse.num_nodes == fine.num_nodes) break;
    const int nc = coarse.num_nodes;
    // A coarse node on a pinned fine node is fixed: its correction is zero.
    coarse.free.resize(nc);
    for (int R = 0; R < coarse.rows; ++R) {
      for (int C = 0; C < coarse.cols; ++C) {
        coarse.free[R * coarse.cols + C] = fine.free[row_lines[R] * fine.cols + col_lines[C]];
      }
    }
    const auto wr = lineInterpolation(fine.rows, row_lines);
    const auto wc = lineInterpolation(fine.cols, col_lines);
    fine.interp_begin.assign(fine.num_nodes + 1, 0);
    fine.interp_node.clear();
    fine.interp_weight.clear();
    for (int r = 0; r < fine.rows; ++r) {
      for (int c = 0; c < fine.cols; ++c) {
        const int i = r * fine.cols + c;
        if (fine.free[i]) {
          for (int a = 0; a < wr[r].count; ++a) {
            for (int b = 0; b < wc[c].count; ++b) {
              const int I = wr[r].coarse[a] * coarse.cols + wc[c].coarse[b];
              if (!coarse.free[I]) continue;
              fine.interp_node.push_back(I);
              fine.interp_weight.push_back(wr[r].weight[a] * wc[c].weight[b]);
            }
          }
        }
        fine.interp_begin[i + 1] = static_cast<int>(fine.interp_node.size());
      }
    }
    // P^T by rows, for the restriction.
    fine.restrict_begin.assign(nc + 1, 0);
    for (int I : fine.interp_node) ++fine.restrict_begin[I + 1];
    for (int I = 0; I < nc; ++I) fine.restrict_begin[I + 1] += fine.restrict_begin[I];
    fine.restrict_node.resize(fine.interp_node.size());
    fine.restrict_weight.resize(fine.interp_node.size());
    {
      std::vector<int> next(fine.restrict_begin.begin(), fine.restrict_begin.end() - 1);
      for (int i = 0; i < fine.num_nodes; ++i) {
        for (int a = fine.interp_begin[i]; a < fine.interp_begin[i + 1]; ++a) {
          const int slot = next[fine.interp_node[a]]++;
          fine.restrict_node[slot] = i;
          fine.restrict_weight[slot] = fine.interp_weight[a];
        }
      }
    }
    // Galerkin pattern, walked in the order galerkin() refills it: per fine
    // row, its node block, then its lower blocks; each with every pair of
    // interpolation entries of the block's row and column node.
    auto walk = [&](auto&& visit) {
      for (int i = 0; i < fine.num_nodes; ++i) {
        const int a0 = fine.interp_begin[i], a1 = fine.interp_begin[i + 1];
        for (int a = a0; a < a1; ++a) {
          for (int b = a0; b < a1; ++b) {
            // A node block D adds w_a w_b D to (I_a, I_b) and to its mirror: one of them.
            const int I = fine.interp_node[a], J = fine.interp_node[b];
            visit(I >= J ? I : -1, J);
          }
        }
        for (int s = fine.lower_begin[i]; s < fine.lower_begin[i + 1]; ++s) {
          const int j = fine.lower_column[s];
          for (int a = a0; a < a1; ++a) {
            for (int b = fine.interp_begin[j]; b < fine.interp_begin[j + 1]; ++b) {
              const int I = fine.interp_node[a], J = fine.interp_node[b];
              visit(std::max(I, J), std::min(I, J));
            }
          }
        }
      }
    };
    std::vector<std::vector<int>> lower(nc);
    walk([&](int I, int J) {
      if (I > J) lower[I].push_back(J);
    });
    compressRows(lower, coarse.lower_begin, coarse.lower_column);
    fine.galerkin_target.clear();
    walk([&](int I, int J) {
      if (I < 0) {
        fine.galerkin_target.push_back(-1);
      } else if (I == J) {
        fine.galerkin_target.push_back(I);
      } else {
        fine.galerkin_target.push_back(
            nc + findColumn(coarse.lower_begin, coarse.lower_column, I, J));
      }
    });
    levels_.push_back(std::move(coarse));
  }
  for (Level& level : levels_) {
    level.node_block.resize(level.num_nodes);
    level.inv_node_block.resize(level.num_nodes);
    level.lower_block.resize(level.lower_column.size());
    level.x.setZero(3 * level.num_nodes);
    level.b.setZero(3 * level.num_nodes);
    level.r.setZero(3 * level.num_nodes);
  }
  for (Level& level : levels_) partition(level);
  buildCoarseSolver();
  rows_ = rows;
  cols_ = cols;
  free_key_ = free;
}

void MultigridPreconditioner::buildCoarseSolver() {
  // The coarsest matrix's lower triangle as a scalar matrix, pattern analysed once.
  const Level& level = levels_.back();
  std::vector<Eigen::Triplet<double>> entries;
  for (int i = 0; i < level.num_nodes; ++i) {
    for (int c = 0; c < 3; ++c) {
      for (int r = c; r < 3; ++r) entries.emplace_back(3 * i + r, 3 * i + c, 1.0);
    }
    for (int s = level.lower_begin[i]; s < level.lower_begin[i + 1]; ++s) {
      const int j = level.lower_column[s];
      for (int c = 0; c < 3; ++c) {
        for (int r = 0; r < 3; ++r) entries.emplace_back(3 * i + r, 3 * j + c, 1.0);
      }
    }
  }
  const int dim = 3 * level.num_nodes;
  coarse_matrix_.resize(dim, dim);
  coarse_matrix_.setFromTriplets(entries.begin(), entries.end());
  coarse_matrix_.makeCompressed();
  auto index_of = [&](int row, int col) {
    return static_cast<int>(&coarse_matrix_.coeffRef(row, col) - coarse_matrix_.valuePtr());
  };
  // SymBlock order: xx, yy, zz, xy, xz, yz; lower triangle (r >= c) entries.
  static constexpr int kRow[6] = {0, 1, 2, 1, 2, 2}, kCol[6] = {0, 1, 2, 0, 0, 1};
  coarse_node_index_.resize(6 * level.num_nodes);
  for (int i = 0; i < level.num_nodes; ++i) {
    for (int e = 0; e < 6; ++e) coarse_node_index_[6 * i + e] = index_of(3 * i + kRow[e], 3 * i + kCol[e]);
  }
  coarse_lower_index_.resize(9 * level.lower_column.size());
  for (int i = 0; i < level.num_nodes; ++i) {
    for (int s = level.lower_begin[i]; s < level.lower_begin[i + 1]; ++s) {
      const int j = level.lower_column[s];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) coarse_lower_index_[9 * s + 3 * r + c] = index_of(3 * i + r, 3 * j + c);
      }
    }
  }
  coarse_ldlt_.analyzePattern(coarse_matrix_);
}

void MultigridPreconditioner::fillFinest(const SystemMatrix& A) {
  // A's full node blocks are summed here from the couplings (the assembly
  // does not keep them): each spring adds S at both ends. Pinned nodes take
  // their sums too and are set to I at the end (no branch per spring).
  Level& level = levels_.front();
  const int n = level.num_nodes;
  for (int i = 0; i < n; ++i) {
    const double m = A.nodeScale(i);
    level.node_block[i] = SymBlock{{m, m, m, 0.0, 0.0, 0.0}};
  }
  for (const auto& [node, block] : A.nodeBlocks()) level.node_block[node].addScaled(1.0, block);
  for (const SystemMatrix::PairTerm& t : A.pairTerms()) {
    for (int k = 0; k < 4; ++k) level.node_block[t.node[k]].addScaled(1.0, t.diagonal(k));
  }
  std::fill(level.lower_block.begin(), level.lower_block.end(), SymBlock());
  const SpringLayout& layout = *A.layout();
  SymBlock* node_block = level.node_block.data();
  SymBlock* lower = level.lower_block.data();
  const bool held = A.hasDampingAxes();
  for (size_t d = 0; d < layout.directions.size(); ++d) {
    const SpringDirection& dir = layout.directions[d];
    const SlotTargets& t = slot_targets_[d];
    const SystemMatrix::Coefficients& co = A.coefficientsAt(static_cast<int>(d));
    addDirection(dir.slots, dir.offset, dir.valid.data(), co.iso.data(), co.axis.data(),
                 co.u[0].data(), co.u[1].data(), co.u[2].data(), held ? co.c.data() : nullptr,
                 held ? co.w[0].data() : nullptr, held ? co.w[1].data() : nullptr,
                 held ? co.w[2].data() : nullptr, t.via.data(), t.block_a.data(),
                 t.block_b.data(), node_block, lower);
  }
  for (int i = 0; i < n; ++i) {
    if (!level.free[i]) level.node_block[i] = identityBlock();
  }
}

void MultigridPreconditioner::galerkin(const Level& fine, Level& coarse) const {
  const int nc = coarse.num_nodes;
  std::fill(coarse.node_block.begin(), coarse.node_block.end(), SymBlock());
  std::fill(coarse.lower_block.begin(), coarse.lower_block.end(), SymBlock());
  galerkinSums(fine.num_nodes, nc, fine.interp_begin.data(), fine.interp_weight.data(),
               fine.node_block.data(), fine.lower_begin.data(), fine.lower_column.data(),
               fine.lower_block.data(), fine.galerkin_target.data(), coarse.node_block.data(),
               coarse.lower_block.data());
  for (int I = 0; I < nc; ++I) {
    if (!coarse.free[I]) coarse.node_block[I] = identityBlock();
  }
}

bool MultigridPreconditioner::prepareSmoother(Level& level) const {
  for (int i = 0; i < level.num_nodes; ++i) {
    if (!level.free[i]) {
      level.inv_node_block[i] = SymBlock();  // keeps a fixed node's x at zero
      continue;
    }
    level.inv_node_block[i] = level.node_block[i].inverse();
    const double* inv = level.inv_node_block[i].v;
    if (!std::isfinite(inv[0]) || !std::isfinite(inv[1]) || !std::isfinite(inv[2])) return false;
  }
  return true;
}

bool MultigridPreconditioner::factorCoarsest() {
  const Level& level = levels_.back();
  double* values = coarse_matrix_.valuePtr();
  for (int i = 0; i < level.num_nodes; ++i) {
    for (int e = 0; e < 6; ++e) values[coarse_node_index_[6 * i + e]] = level.node_block[i].v[e];
  }
  for (size_t s = 0; s < level.lower_block.size(); ++s) {
    const Mat3 L = level.lower_block[s].toMat3();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) values[coarse_lower_index_[9 * s + 3 * r + c]] = L(r, c);
    }
  }
  return coarse_ldlt_.factorize(coarse_matrix_);
}

bool MultigridPreconditioner::matchesStructure(const SystemMatrix& A,
                                               const std::vector<Spring>& springs,
                                               const std::vector<char>& free, int rows,
                                               int cols) const {
  bool same = rows == rows_ && cols == cols_ && free == free_key_ &&
              2 * springs.size() == spring_ends_.size();
  // The spring list and the layout made from it that the patterns were last
  // matched to: the same structure, without comparing every spring (hang64:
  // 3 % of a step). Else the springs' ends decide (a copy of the model).
  if (same && A.layout() == layout_key_ && springs.data() == springs_key_) return true;
  for (size_t k = 0; same && k < springs.size(); ++k) {
    same = springs[k].i == spring_ends_[2 * k] && springs[k].j == spring_ends_[2 * k + 1];
  }
  return same;
}

bool MultigridPreconditioner::setup(const SystemMatrix& A, const std::vector<Spring>& springs,
                                    const std::vector<char>& free, int rows, int cols) {
  invalidate();
  return prepare(A, springs, free, rows, cols, 1);
}

void MultigridPreconditioner::checkGrid(const SystemMatrix& A, int rows, int cols) const {
  if (rows < 1 || cols < 1 || rows * cols != A.numNodes()) {
    throw std::invalid_argument("multigrid preconditioner: grid " + std::to_string(rows) + " x " +
                                std::to_string(cols) + " does not match the " +
                                std::to_string(A.numNodes()) + " nodes of the system");
  }
}

void MultigridPreconditioner::buildStructure(const SystemMatrix& A,
                                             const std::vector<Spring>& springs,
                                             const std::vector<char>& free, int rows, int cols) {
  ready_ = false;
  buildHierarchy(A, springs, free, rows, cols);
  spring_ends_.resize(2 * springs.size());
  for (size_t k = 0; k < springs.size(); ++k) {
    spring_ends_[2 * k] = springs[k].i;
    spring_ends_[2 * k + 1] = springs[k].j;
  }
}

bool MultigridPreconditioner::rebuildCoarse() {
  ready_ = false;
  reused_ = false;
  rebuild_due_ = true;  // until this fill succeeds
  ++rebuilds_;
  for (size_t l = 0; l + 1 < levels_.size(); ++l) {
    if (!prepareSmoother(levels_[l])) return false;
    galerkin(levels_[l], levels_[l + 1]);
  }
  if (!factorCoarsest()) return false;
  const Level& finest = levels_.front();
  built_trace_.resize(finest.num_nodes);
  for (int i = 0; i < finest.num_nodes; ++i) built_trace_[i] = finest.node_block[i].trace();
  solves_since_build_ = 0;
  first_iterations_ = 0;
  rebuild_due_ = false;
  ready_ = true;
  return true;
}

bool MultigridPreconditioner::prepare(const SystemMatrix& A, const std::vector<Spring>& springs,
                                      const std::vector<char>& free, int rows, int cols,
                                      int max_solves) {
  checkGrid(A, rows, cols);
  projected_.clear();  // until constrain() says otherwise
  projector_.clear();
  bool reuse = ready_ && !rebuild_due_ && solves_since_build_ < max_solves;
  if (!matchesStructure(A, springs, free, rows, cols)) {
    buildStructure(A, springs, free, rows, cols);
    reuse = false;
  }
  layout_key_ = A.layout();
  springs_key_ = springs.data();
  // The finest level always follows the current matrix (its stiff springs
  // turn every step, and a stale smoother costs an extra CG iteration after a
  // single step); the coarse levels are kept unless a node block changed
  // much (new step size or stiffness).
  fillFinest(A);
  const Level& finest = levels_.front();
  for (int i = 0; reuse && i < finest.num_nodes; ++i) {
    reuse = !finest.free[i] || std::abs(finest.node_block[i].trace() - built_trace_[i]) <=
                                   kTraceChange * std::abs(built_trace_[i]);
  }
  if (!reuse) return rebuildCoarse();
  reused_ = true;
  if (!prepareSmoother(levels_.front())) {
    ready_ = false;
    return false;
  }
  return true;
}

void MultigridPreconditioner::recordSolve(int iterations) {
  ++solves_since_build_;
  if (first_iterations_ == 0) {
    first_iterations_ = iterations;  // the first solve that iterated at all
  } else if (iterations > kIterationGrowth * first_iterations_) {
    rebuild_due_ = true;
  }
}

}  // namespace cloth_sim
