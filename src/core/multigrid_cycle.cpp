// The multigrid preconditioner's V-cycle (multigrid.hpp): Gauss-Seidel
// smoothing, restriction and prolongation, and their split among threads
// (solver.threads). The hierarchy it runs on is built in multigrid.cpp.
#include <algorithm>
#include <stdexcept>

#include "cloth_sim/multigrid.hpp"
#include "parallel.hpp"
#include "vectorised.hpp"

namespace cloth_sim {

namespace {

// The V-cycle's loops, built for AVX2/FMA too (vectorised.hpp): the block
// products are scalar chains, and FMA shortens both their latency and their
// instruction count (hang64: the V-cycle is ~40 % of the step).

/// One Gauss-Seidel relaxation of rows i in [first, last) stepping by `step`
/// (+1 forward, -1 backward; relaxRows picks the direction): row i solved from s = b_i + r_i minus its
/// lower blocks' x_j (j < i), then x_i's coupling scattered into r_j, so r
/// gathers -sum_{j > i} A_ij x_j for the rows still to come. x_i = inv_i s.
///
/// The forward sweep (from x = 0) needs r neither read nor zeroed first:
/// nothing has been scattered into r_i when row i comes (its upper
/// neighbours come later), so row i starts from b_i and sets r_i to zero
/// for their scatters; the backward sweep takes r zeroed.
template <bool kForward>
inline __attribute__((always_inline)) void relaxRowsIn(
    int first, int last, int step, const int* __restrict start, const int* __restrict stop,
    const int* __restrict column, const SymBlock* __restrict lower,
    const SymBlock* __restrict inv, const double* __restrict b, double* __restrict x,
    double* __restrict r) {
  for (int i = first; i != last; i += step) {
    double s[3] = {b[3 * i], b[3 * i + 1], b[3 * i + 2]};
    if constexpr (kForward) {
      r[3 * i] = r[3 * i + 1] = r[3 * i + 2] = 0.0;
    } else {
      s[0] += r[3 * i], s[1] += r[3 * i + 1], s[2] += r[3 * i + 2];
    }
    for (int k = start[i]; k < stop[i]; ++k) lower[k].subtractProduct(x + 3 * column[k], s);
    inv[i].multiply(s, x + 3 * i);
    for (int k = start[i]; k < stop[i]; ++k) lower[k].subtractProduct(x + 3 * i, r + 3 * column[k]);
  }
}

/// Rows [first, last) relaxed forward or backward; row i's lower blocks are
/// k in [start[i], stop[i]) (all of them: start = begin, stop = begin + 1).
CLOTH_SIM_VECTORISED
void relaxRows(bool forward, int first, int last, const int* __restrict start,
               const int* __restrict stop, const int* __restrict column,
               const SymBlock* __restrict lower, const SymBlock* __restrict inv,
               const double* __restrict b, double* __restrict x, double* __restrict r) {
  if (forward) {
    relaxRowsIn<true>(first, last, 1, start, stop, column, lower, inv, b, x, r);
  } else {
    relaxRowsIn<false>(last - 1, first - 1, -1, start, stop, column, lower, inv, b, x, r);
  }
}

/// coarse = P^T fine (restriction) for coarse rows [first, last), by P^T's rows (restrict_begin/node/
/// weight): each coarse entry summed once from its fine nodes, no zeroing
/// pass and no read-modify-write per interpolation entry.
CLOTH_SIM_VECTORISED
void restrictToCoarse(int first, int last, const int* __restrict begin,
                      const int* __restrict node, const double* __restrict weight,
                      const double* __restrict fine, double* __restrict coarse) {
  for (int I = first; I < last; ++I) {
    double c0 = 0.0, c1 = 0.0, c2 = 0.0;
    for (int a = begin[I]; a < begin[I + 1]; ++a) {
      const double* f = fine + 3 * node[a];
      const double w = weight[a];
      c0 += w * f[0];
      c1 += w * f[1];
      c2 += w * f[2];
    }
    coarse[3 * I] = c0, coarse[3 * I + 1] = c1, coarse[3 * I + 2] = c2;
  }
}

/// fine += P coarse (prolongation of the coarse correction), fine rows
/// [first, last).
CLOTH_SIM_VECTORISED
void prolongToFine(int first, int last, const int* __restrict interp_begin,
                   const int* __restrict node, const double* __restrict weight,
                   const double* __restrict coarse, double* __restrict fine) {
  for (int i = first; i < last; ++i) {
    double* f = fine + 3 * i;
    for (int a = interp_begin[i]; a < interp_begin[i + 1]; ++a) {
      const double* c = coarse + 3 * node[a];
      const double w = weight[a];
      f[0] += w * c[0];
      f[1] += w * c[1];
      f[2] += w * c[2];
    }
  }
}

}  // namespace

void MultigridPreconditioner::vcycle(int l) {
  Level& level = levels_[l];
  const int n = level.num_nodes;
  if (l + 1 == numLevels()) {
    coarse_ldlt_.solve(level.b, level.x);
    for (int i = 0; i < n; ++i) {
      if (!level.free[i]) level.x.segment<3>(3 * i).setZero();
    }
    return;
  }
  VecX& x = level.x;
  VecX& r = level.r;
  const bool projected = l == 0 && !projected_.empty();
  const SymBlock* inv = projected ? constrained_inv_.data() : level.inv_node_block.data();
  // S v on the projected nodes (the finest level, constrained).
  auto project = [&](VecX& v) {
    double t[3];
    for (size_t k = 0; k < projected_.size(); ++k) {
      double* vi = v.data() + 3 * projected_[k];
      projector_[k].multiply(vi, t);
      vi[0] = t[0], vi[1] = t[1], vi[2] = t[2];
    }
  };

  // Forward Gauss-Seidel from x = 0. Row i's equation then holds exactly with
  // the new x_j (j < i) and x_j = 0 (j > i), so the residual is
  // r_i = -sum_{j > i} A_ij x_j: gathered from later rows as they are solved.
  relax(level, true, inv);

  // Coarse correction: x += P A_c^-1 P^T r (A_c^-1 by the next V-cycle).
  if (projected) project(r);
  Level& coarse = levels_[l + 1];
  [[maybe_unused]] const int parts =
      std::max<int>(1, static_cast<int>(level.part_start.size()) - 1);
  // P^T and P are gathers by rows: any split of the rows gives the same sums.
#pragma omp parallel num_threads(parts) if (parts > 1)
  {
    int first = 0, last = coarse.num_nodes;
    parallel::range(parallel::thread(), parallel::team(), coarse.num_nodes, &first, &last);
    restrictToCoarse(first, last, level.restrict_begin.data(), level.restrict_node.data(),
                     level.restrict_weight.data(), r.data(), coarse.b.data());
  }
  vcycle(l + 1);
#pragma omp parallel num_threads(parts) if (parts > 1)
  {
    int first = 0, last = n;
    parallel::range(parallel::thread(), parallel::team(), n, &first, &last);
    prolongToFine(first, last, level.interp_begin.data(), level.interp_node.data(),
                  level.interp_weight.data(), coarse.x.data(), x.data());
  }
  if (projected) project(x);  // x was in the range of S before the correction

  // Backward Gauss-Seidel (the forward sweep's transpose): rows j > i are
  // already new; their part -sum_{j > i} A_ij x_j is scattered into r as
  // each row is solved, the old x_j (j < i) are gathered.
  r.setZero();
  relax(level, false, inv);
}

void MultigridPreconditioner::relax(Level& level, bool forward, const SymBlock* inv) {
  const int* begin = level.lower_begin.data();
  const int* column = level.lower_column.data();
  const SymBlock* lower = level.lower_block.data();
  double* x = level.x.data();
  double* r = level.r.data();
  const double* b = level.b.data();
  const int parts = static_cast<int>(level.part_start.size()) - 1;
  if (parts <= 1) {
    relaxRows(forward, 0, level.num_nodes, begin, begin + 1, column, lower, inv, b, x, r);
    return;
  }
  // Couplings between parts: r_i -= A_ij x_j and r_j -= A_ij x_i (A_ij is
  // symmetric). Forward (from x = 0): after the parts, which left them out,
  // so r is the residual. Backward: before, with the x the sweep starts from.
  auto across = [&] {
    for (int i : level.cross_rows) {
      for (int k = begin[i]; k < level.inner_begin[i]; ++k) {
        const int j = column[k];
        lower[k].subtractProduct(x + 3 * j, r + 3 * i);
        lower[k].subtractProduct(x + 3 * i, r + 3 * j);
      }
    }
  };
  if (!forward) across();
  const int* inner = level.inner_begin.data();
  const int* part = level.part_start.data();
  // (A team smaller than asked takes the parts in turns: every part is relaxed.)
#pragma omp parallel num_threads(parts)
  for (int t = parallel::thread(); t < parts; t += parallel::team()) {
    relaxRows(forward, part[t], part[t + 1], inner, begin + 1, column, lower, inv, b, x, r);
  }
  if (forward) across();
}

void MultigridPreconditioner::setThreads(int threads) {
  threads = std::max(threads, 1);
  if (threads == threads_) return;
  threads_ = threads;
  for (Level& level : levels_) partition(level);
}

void MultigridPreconditioner::partition(Level& level) const {
  level.part_start.clear();
  level.cross_rows.clear();
  level.inner_begin.clear();
  const int threads = std::min(parallel::partsFor(threads_, level.num_nodes), level.rows);
  if (threads <= 1) return;
  level.inner_begin.assign(level.lower_begin.begin(), level.lower_begin.end() - 1);
  // Whole grid rows a part, so the couplings across are the two lines at each cut.
  for (int t = 0; t <= threads; ++t) {
    level.part_start.push_back(level.cols * ((level.rows * t) / threads));
  }
  for (int t = 1; t < threads; ++t) {
    for (int i = level.part_start[t]; i < level.part_start[t + 1]; ++i) {
      int k = level.lower_begin[i];
      while (k < level.lower_begin[i + 1] && level.lower_column[k] < level.part_start[t]) ++k;
      level.inner_begin[i] = k;
      if (k > level.lower_begin[i]) level.cross_rows.push_back(i);
    }
  }
}

void MultigridPreconditioner::constrain(const ConstraintFilter& filter) {
  projected_.clear();
  projector_.clear();
  if (!ready_ || !filter.hasProjections()) return;
  const Level& finest = levels_.front();
  constrained_inv_ = finest.inv_node_block;
  for (int i : filter.projectedNodes()) {
    if (!finest.free[i]) continue;
    const Mat3 S = filter.projector(i);
    // As block Jacobi's projected block, kept on the range of S.
    constrained_inv_[i] =
        SymBlock::from(S * projectedBlock(finest.node_block[i].toMat3(), S).inverse() * S);
    projected_.push_back(i);
    projector_.push_back(SymBlock::from(S));
  }
}

void MultigridPreconditioner::applySplit(const double* r, double* z) {
  if (!ready_) throw std::logic_error("multigrid preconditioner applied before a successful setup");
  Level& finest = levels_.front();
  const int n = finest.num_nodes;
  double* b = finest.b.data();
  for (int i = 0; i < n; ++i) {
    const bool f = finest.free[i];
    for (int c = 0; c < 3; ++c) b[3 * i + c] = f ? r[c * n + i] : 0.0;
  }
  vcycle(0);
  const double* x = finest.x.data();
  for (int c = 0; c < 3; ++c) {
    for (int i = 0; i < n; ++i) z[c * n + i] = x[3 * i + c];
  }
}

void MultigridPreconditioner::apply(const VecX& r, VecX& z) {
  if (!ready_) throw std::logic_error("multigrid preconditioner applied before a successful setup");
  Level& finest = levels_.front();
  finest.b = r;
  for (int i = 0; i < finest.num_nodes; ++i) {
    if (!finest.free[i]) finest.b.segment<3>(3 * i).setZero();
  }
  vcycle(0);
  z = finest.x;
}

}  // namespace cloth_sim
