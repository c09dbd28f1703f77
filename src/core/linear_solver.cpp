#include "cloth_sim/linear_solver.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>

#include "cloth_sim/cg_kernels.hpp"
#include "cloth_sim/spring_sweeps.hpp"

namespace cloth_sim {

void CholeskyFactor::buildPattern(int n, const std::vector<Spring>& springs, int grid_cols) {
  via_.assign(springs.size(), -1);
  for (size_t k = 0; k < springs.size(); ++k) via_[k] = middleNode(springs[k], n, grid_cols);
  // Lower triangle only: node blocks (i, i) and coupling blocks (max, min).
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(6 * n + 9 * 2 * springs.size());
  auto block = [&](int row_node, int col_node) {
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) {
        const int row = 3 * row_node + r, col = 3 * col_node + c;
        if (row >= col) entries.emplace_back(row, col, 1.0);
      }
    }
  };
  auto pair = [&](int a, int b) { block(std::max(a, b), std::min(a, b)); };
  for (int i = 0; i < n; ++i) block(i, i);
  for (size_t k = 0; k < springs.size(); ++k) {
    const Spring& s = springs[k];
    if (via_[k] < 0) {
      pair(s.i, s.j);
    } else {
      pair(s.i, via_[k]);
      pair(via_[k], s.j);
    }
  }
  for (const auto& [hi, lo] : pattern_pairs_) block(hi, lo);
  matrix_.resize(3 * n, 3 * n);
  matrix_.setFromTriplets(entries.begin(), entries.end());
  matrix_.makeCompressed();
  // Column 3 i + c starts at its diagonal entry, node i's block below it.
  diag_index_.resize(9 * n);
  const int* outer = matrix_.outerIndexPtr();
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) {
      for (int r = c; r < 3; ++r) diag_index_[9 * i + 3 * c + r] = outer[3 * i + c] + r - c;
    }
  }
  block_a_.assign(9 * springs.size(), -1);
  block_b_.assign(9 * springs.size(), -1);
  for (size_t k = 0; k < springs.size(); ++k) {
    const Spring& s = springs[k];
    blockIndices(s.i, via_[k] < 0 ? s.j : via_[k], &block_a_[9 * k]);
    if (via_[k] >= 0) blockIndices(via_[k], s.j, &block_b_[9 * k]);
  }
  ldlt_.analyzePattern(matrix_);
  num_nodes_ = n;
  num_springs_ = springs.size();
  grid_cols_ = grid_cols;
}

void CholeskyFactor::blockIndices(int a, int b, int* nine) {
  const int hi = std::max(a, b), lo = std::min(a, b);
  // Column 3 lo + c holds node lo's block from its diagonal down (3 - c
  // entries), then every block (h, lo), h > lo, whole and in order: block
  // (hi, lo) sits as far below those in each of its three columns. One
  // search instead of nine (a heap's self pairs ask this at every factor).
  const int* outer = matrix_.outerIndexPtr();
  const int below =
      static_cast<int>(&matrix_.coeffRef(3 * hi, 3 * lo) - matrix_.valuePtr()) - outer[3 * lo];
  for (int c = 0; c < 3; ++c) {
    for (int r = 0; r < 3; ++r) nine[3 * c + r] = outer[3 * lo + c] + below - c + r;
  }
}

namespace {

/// Calls visit(a, b, w_a w_b) for each two distinct nodes a pair term
/// couples: its block between them is w_a w_b B.
template <class Visit>
void forEachCoupling(const SystemMatrix::PairTerm& t, Visit visit) {
  for (int k = 0; k < 4; ++k) {
    for (int l = k + 1; l < 4; ++l) {
      if (t.node[k] != t.node[l]) visit(t.node[k], t.node[l], t.w[k] * t.w[l]);
    }
  }
}

}  // namespace

void CholeskyFactor::collectPairNodes(const SystemMatrix& A) {
  pair_nodes_.clear();
  for (const SystemMatrix::PairTerm& t : A.pairTerms()) {
    forEachCoupling(t, [&](int a, int b, double) {
      pair_nodes_.emplace_back(std::max(a, b), std::min(a, b));
    });
  }
  std::sort(pair_nodes_.begin(), pair_nodes_.end());
  pair_nodes_.erase(std::unique(pair_nodes_.begin(), pair_nodes_.end()), pair_nodes_.end());
}

bool CholeskyFactor::factorize(const SystemMatrix& A, const std::vector<Spring>& springs,
                               const ConstraintFilter& filter, int grid_cols) {
  static long serials = 0;
  serial_ = ++serials;
  const std::vector<char>& free = filter.freeMask();
  const int n = A.numNodes();
  // The pair terms' couplings: a pattern that holds them all is kept (the
  // pairs a heap's layers make change every few steps; analysing each time
  // would cost more than the zeros the old ones leave), one that misses one
  // is made again, for these pairs only once it holds twice as many.
  collectPairNodes(A);
  const bool covered = std::includes(pattern_pairs_.begin(), pattern_pairs_.end(),
                                     pair_nodes_.begin(), pair_nodes_.end());
  const bool bloated = pattern_pairs_.size() > 2 * pair_nodes_.size() + 64;
  if (!covered || bloated) {
    std::vector<std::pair<int, int>> merged;
    if (!bloated) {
      std::set_union(pattern_pairs_.begin(), pattern_pairs_.end(), pair_nodes_.begin(),
                     pair_nodes_.end(), std::back_inserter(merged));
    } else {
      merged = pair_nodes_;
    }
    pattern_pairs_.swap(merged);
    num_nodes_ = -1;  // made again below
  }
  if (n != num_nodes_ || springs.size() != num_springs_ || grid_cols != grid_cols_) {
    buildPattern(n, springs, grid_cols);
  }
  // Node blocks: A's, plus what rerouting adds (S more at each end, 4S in the middle).
  std::vector<SymBlock> diag = A.fullDiagonal();
  for (size_t k = 0; k < springs.size(); ++k) {
    if (via_[k] < 0) continue;
    const SymBlock S = A.couplingBlock(static_cast<int>(k));
    diag[springs[k].i].addScaled(1.0, S);
    diag[springs[k].j].addScaled(1.0, S);
    diag[via_[k]].addScaled(4.0, S);
  }
  double* values = matrix_.valuePtr();
  std::fill(values, values + matrix_.nonZeros(), 0.0);
  for (int i = 0; i < n; ++i) {
    Mat3 D = free[i] ? diag[i].toMat3() : Mat3::Identity();
    if (filter.isProjected(i)) {
      const Mat3 S = filter.projector(i);
      D = projectedBlock(D, S);
    }
    for (int c = 0; c < 3; ++c) {
      for (int r = c; r < 3; ++r) values[diag_index_[9 * i + 3 * c + r]] = D(r, c);
    }
  }
  // Coupling -w S between nodes a and b, block (max, min) of S A S.
  auto couple = [&](const int* index, int a, int b, const Mat3& C) {
    if (!free[a] || !free[b]) return;
    const int hi = std::max(a, b), lo = std::min(a, b);
    Mat3 block = C;
    if (filter.isProjected(hi) || filter.isProjected(lo)) {
      block = filter.projector(hi) * C * filter.projector(lo);
    }
    for (int c = 0; c < 3; ++c) {
      for (int r = 0; r < 3; ++r) values[index[3 * c + r]] += block(r, c);
    }
  };
  for (size_t k = 0; k < springs.size(); ++k) {
    const Spring& s = springs[k];
    const Mat3 S = A.coupling(static_cast<int>(k));
    if (via_[k] < 0) {
      couple(&block_a_[9 * k], s.i, s.j, -S);
    } else {
      couple(&block_a_[9 * k], s.i, via_[k], -2.0 * S);
      couple(&block_b_[9 * k], via_[k], s.j, -2.0 * S);
    }
  }
  // A pair term (w w^T) (x) B couples nodes k and l by w_k w_l B (its node
  // blocks are in fullDiagonal's).
  int nine[9];
  for (const SystemMatrix::PairTerm& t : A.pairTerms()) {
    const Mat3 B = t.B.toMat3();
    forEachCoupling(t, [&](int a, int b, double ww) {
      blockIndices(a, b, nine);
      couple(nine, a, b, ww * B);
    });
  }
  valid_ = ldlt_.factorize(matrix_);
  filter_ = filter;
  return valid_;
}

namespace {

/// z = S B r on split vectors, returning r . z: the preconditioner B is
/// built on the free mask (projected nodes count as free there), so its
/// output is filtered; r is filtered, so r . S z = r . z.
double applyPreconditioner(Preconditioner kind, CgWorkspace& ws, const ConstraintFilter& filter,
                           const VecX& r, VecX& z) {
  const int n = static_cast<int>(r.size() / 3);
  if (kind == Preconditioner::BlockJacobi) {
    const double* inv[6];
    for (int e = 0; e < 6; ++e) inv[e] = ws.inv_diag.data() + static_cast<size_t>(e) * n;
    const double rz = cg_kernels::blockJacobi(n, inv, r.data(), z.data());
    filter.applySplit(z.data());
    return rz;
  }
  if (kind == Preconditioner::Multigrid) {
    ws.multigrid->applySplit(r.data(), z.data());  // pinned entries come back zero
    filter.applySplit(z.data());
    return cg_kernels::dot(3 * n, r.data(), z.data());
  }
  // Cholesky works on unsplit vectors (its cost dwarfs the copies).
  ws.joined_r.resize(3 * n);
  sweeps::joinComponents(r.data(), n, ws.joined_r.data());
  if (ws.pairs_corrected) {
    // z = B (r - C^T s), s = (C B C^T)^-1 C B r: with y = L^-1 P r, C B r =
    // W^T D^-1 y, and the backward half solves for y - W s.
    const BlockLdlt& factor = ws.cholesky->ldlt();
    factor.forwardSolve(ws.joined_r, ws.pair_half);
    const Eigen::Index m = ws.pair_s.size();
    for (Eigen::Index k = 0; k < m; ++k) {
      double t = 0.0;
      for (int e = ws.pair_start[k]; e < ws.pair_start[k + 1]; ++e) {
        t += ws.pair_dwv[e].dot(ws.pair_half[ws.pair_pos[e]]);
      }
      ws.pair_s[k] = t;
    }
    ws.pair_s = ws.pair_schur.solve(ws.pair_s);
    for (Eigen::Index k = 0; k < m; ++k) {
      const double sr = ws.pair_s[k];
      for (int e = ws.pair_start[k]; e < ws.pair_start[k + 1]; ++e) {
        ws.pair_half[ws.pair_pos[e]].noalias() -= sr * ws.pair_wv[e];
      }
    }
    factor.backwardSolve(ws.pair_half, ws.joined_z);
  } else {
    ws.cholesky->solve(ws.joined_r, ws.joined_z);
  }
  sweeps::splitComponents(ws.joined_z, z.data());
  filter.applySplit(z.data());
  return cg_kernels::dot(3 * n, r.data(), z.data());
}

/// The Cholesky preconditioner B made exact on the held pairs' null space
/// (CgWorkspace::pair_wv): without, B ignores the rows, and CG on the
/// projected system took up to 8 400 iterations a step (a fling at stretch
/// 1e8 under bdf2; 1 300 with: 3.2 ms a step where 4.0). Made per factor and
/// set of rows by a forward solve over each row's paths up the elimination
/// tree (a third of the tree on the heap), not one whole solve a row: those
/// took 48 % of the heap's time when every pushed pair was held.

void correctForPairs(const ConstraintFilter& filter, int dim, CgWorkspace& ws) {
  ws.pairs_corrected = false;
  if (!filter.holdsPairs()) return;
  if (ws.pair_factor == ws.cholesky->serial() && ws.pair_generation == filter.pairsGeneration()) {
    ws.pairs_corrected = ws.pair_s.size() > 0;
    return;
  }
  ws.pair_factor = ws.cholesky->serial();
  ws.pair_generation = filter.pairsGeneration();
  ws.pair_s.resize(0);
  ws.pair_start.assign(1, 0);
  ws.pair_pos.clear();
  ws.pair_wv.clear();
  ws.pair_dwv.clear();
  const BlockLdlt& factor = ws.cholesky->ldlt();
  std::vector<int> positions;
  std::vector<Vec3> w;
  for (const PairProjection::Row& row : filter.pairs().rows()) {
    if (row.nodes.empty()) continue;
    factor.forwardSolveSparse(row.nodes, row.c, &positions, &w);
    ws.pair_pos.insert(ws.pair_pos.end(), positions.begin(), positions.end());
    ws.pair_wv.insert(ws.pair_wv.end(), w.begin(), w.end());
    for (size_t a = 0; a < positions.size(); ++a) ws.pair_dwv.push_back(factor.dInverse(positions[a]) * w[a]);
    ws.pair_start.push_back(static_cast<int>(ws.pair_pos.size()));
  }
  const Eigen::Index m = static_cast<Eigen::Index>(ws.pair_start.size()) - 1;
  if (m == 0) return;
  // C B C^T = W^T D^-1 W, summed position by position over the rows there.
  std::vector<std::vector<int>> at(static_cast<size_t>(dim / 3));
  for (Eigen::Index r = 0; r < m; ++r) {
    for (int e = ws.pair_start[r]; e < ws.pair_start[r + 1]; ++e) at[ws.pair_pos[e]].push_back(e);
  }
  std::vector<int> row_of(ws.pair_pos.size());
  for (Eigen::Index r = 0; r < m; ++r) {
    for (int e = ws.pair_start[r]; e < ws.pair_start[r + 1]; ++e) row_of[e] = static_cast<int>(r);
  }
  Eigen::MatrixXd schur = Eigen::MatrixXd::Zero(m, m);
  for (const std::vector<int>& entries : at) {
    for (size_t a = 0; a < entries.size(); ++a) {
      const Vec3& dw = ws.pair_dwv[entries[a]];
      for (size_t b = 0; b <= a; ++b) schur(row_of[entries[a]], row_of[entries[b]]) += ws.pair_wv[entries[b]].dot(dw);
    }
  }
  // Entries within a position come in row order: the lower triangle is filled.
  for (Eigen::Index c = 1; c < m; ++c) {
    for (Eigen::Index r = 0; r < c; ++r) schur(r, c) = schur(c, r);
  }
  // Regularised against round-off (the rows are independent).
  const double largest = schur.diagonal().maxCoeff();
  schur.diagonal().array() += 1e-9 * largest;
  ws.pair_schur.compute(schur);
  // Positive where B is: an indefinite factor (BlockLdlt factors on through
  // indefinite pivots) gives no correction (z was garbage, CG diverged).
  ws.pairs_corrected = ws.pair_schur.info() == Eigen::Success &&
                       (ws.pair_schur.vectorD().array() > 0.0).all();
  if (ws.pairs_corrected) ws.pair_s.resize(m);
}

}  // namespace

double autoStiffness(const Model& model, double h) {
  double stiffest = 0.0;
  for (const SpringGroup& group : model.groups) {
    if (group.present) stiffest = std::max(stiffest, group.damping + h * group.stiffness);
  }
  double lightest = std::numeric_limits<double>::infinity();
  for (double m : model.mass) lightest = std::min(lightest, m);
  return h * stiffest / lightest;
}

Preconditioner strongerPreconditioner(const Model& model) {
  return model.numNodes() <= kAutoCholeskyNodes ? Preconditioner::Cholesky
                                                : Preconditioner::Multigrid;
}

Preconditioner cheapPreconditioner(const Model& model, bool contact) {
  const bool grid = model.rows > 1 && model.cols > 1 && model.rows * model.cols == model.numNodes();
  return grid && !contact && model.numNodes() >= kAutoMultigridNodes ? Preconditioner::Multigrid
                                                                     : Preconditioner::BlockJacobi;
}

int autoTrialIterations(const Model& model, Preconditioner cheap) {
  if (cheap != Preconditioner::Multigrid ||
      strongerPreconditioner(model) != Preconditioner::Cholesky) {
    return kAutoJacobiIterations;
  }
  return multigridStallIterations(model);
}

int multigridStallIterations(const Model& model) {
  return static_cast<int>(std::lround(2.0 * std::sqrt(static_cast<double>(model.numNodes()))));
}

Preconditioner AutoPreconditioner::choose(Preconditioner requested, const Model& model,
                                          double h, bool contact) {
  if (requested != Preconditioner::Auto) return requested;
  if (guessed_) streak_ = escalated_ ? streak_ + 1 : 0;  // the last attempt's verdict
  if (streak_ >= kAutoEscalations) {
    jacobi_limit_ = std::min(jacobi_limit_, 0.5 * kappa_);
    streak_ = 0;
    since_lowered_ = 0;
  } else if (jacobi_limit_ < kAutoJacobiLimit && ++since_lowered_ > kAutoReprobeAttempts) {
    jacobi_limit_ = kAutoJacobiLimit;  // try the cheap guess again
  }
  kappa_ = autoStiffness(model, h);
  escalated_ = false;
  const Preconditioner stronger = strongerPreconditioner(model);
  const Preconditioner chosen =
      kappa_ <= jacobi_limit_ ? cheapPreconditioner(model, contact) : stronger;
  guessed_ = chosen != stronger;  // a guess the iterations judge
  return chosen;
}

Preconditioner AutoPreconditioner::escalate(const Model& model) {
  escalated_ = true;
  return strongerPreconditioner(model);
}

CgResult conjugateGradient(const SystemMatrix& A, const std::vector<Spring>& springs,
                           const ConstraintFilter& filter, const VecX& b, VecX& x,
                           Preconditioner preconditioner, double tolerance,
                           int max_iterations, CgWorkspace& ws, bool split) {
  const int n = A.numNodes();
  const int dim = 3 * n;
  const std::vector<char>& free = filter.freeMask();
  if (split) {
    filter.applySplit(x.data());
  } else {
    filter.apply(x);
  }
  A.allowSinglePrecision(tolerance);

  // The iteration runs on vectors split by component (the product's layout).
  // A split x is worked on in place (swapped in, swapped back at the end).
  if (split) ws.x.swap(x);
  ws.x.resize(dim);
  ws.r.resize(dim);
  ws.z.resize(dim);
  ws.p.resize(dim);
  ws.q.resize(dim);
  double* xs = ws.x.data();
  double* rs = ws.r.data();
  auto splitB = [&] {
    if (split) {
      ws.r = b;
    } else {
      sweeps::splitComponents(b, rs);
    }
    filter.applySplit(rs);  // S b: also the residual of a cold start
  };
  auto giveX = [&] {  // the answer into x, in its layout
    if (split) {
      x.swap(ws.x);
    } else {
      sweeps::joinComponents(xs, n, x.data());
    }
  };
  splitB();

  CgResult result;
  bool fresh_factor = false;
  bool rerouted = false;  ///< a fresh factor of the rerouted matrix (CholeskyFactor)
  const double b_norm = std::sqrt(cg_kernels::dot(dim, rs, rs));
  if (!(b_norm > 0.0)) {
    if (split) x.swap(ws.x);
    x.setZero();
    result.converged = std::isfinite(b_norm);
    result.relative_residual = result.converged ? 0.0 : b_norm;
    return result;
  }
  if (preconditioner == Preconditioner::BlockJacobi) {
    ws.inv_diag.resize(6 * static_cast<size_t>(n));
    const std::vector<SymBlock>& diag = A.fullDiagonal();
    auto store = [&](int i, const SymBlock& inv) {
      for (int e = 0; e < 6; ++e) ws.inv_diag[static_cast<size_t>(e) * n + i] = inv.v[e];
    };
    for (int i = 0; i < n; ++i) store(i, free[i] ? diag[i].inverse() : SymBlock());
    // A projected node's block acts on the range of S only: invert
    // S D S + (I - S) tr(D)/3 (SPD), whose inverse on that range is exact.
    for (int i : filter.projectedNodes()) {
      store(i, SymBlock::from(projectedBlock(diag[i].toMat3(), filter.projector(i)).inverse()));
    }
  } else if (preconditioner == Preconditioner::Cholesky) {
    if (!ws.cholesky) ws.cholesky = std::make_shared<CholeskyFactor>();
    fresh_factor = !ws.cholesky->isValidFor(filter) ||
                   ws.last_iterations > CholeskyFactor::kRefactorIterations ||
                   ws.fresh_factor_solves > 0;
    if (ws.fresh_factor_solves > 0) --ws.fresh_factor_solves;
    if (fresh_factor) {
      ++ws.factorizations;
      rerouted = ws.reroute_bends && ws.plain_factors == 0 && ws.grid_cols > 0;
      if (ws.plain_factors > 0) --ws.plain_factors;
      if (rerouted && !ws.cholesky->factorize(A, springs, filter, ws.grid_cols)) {
        rerouted = false;  // an indefinite coupling made it so: A itself, for a while
        ws.plain_factors = 64;
      }
      if (!rerouted && !ws.cholesky->factorize(A, springs, filter, 0)) {
        if (split) x.swap(ws.x);
        result.relative_residual = 1.0;
        return result;  // not positive definite: the caller's recovery decides
      }
    }
    correctForPairs(filter, dim, ws);
  } else if (preconditioner == Preconditioner::Multigrid) {
    if (!ws.multigrid) ws.multigrid = std::make_shared<MultigridPreconditioner>();
    ws.multigrid->setThreads(ws.threads);
    if (!ws.multigrid->prepare(A, springs, free, ws.grid_rows, ws.grid_cols,
                               ws.multigrid_max_solves)) {
      if (split) x.swap(ws.x);
      result.relative_residual = 1.0;
      return result;  // a singular block or coarse matrix: the caller's recovery decides
    }
    ws.multigrid->constrain(filter);
  }

  const bool cold = split ? ws.x.isZero(0.0) : x.isZero(0.0);  // no product needed
  if (cold) {
    ws.x.setZero();
  } else {
    if (!split) sweeps::splitComponents(x, xs);
    A.multiplySplit(xs, ws.q.data());
    filter.applySplit(ws.q.data());
  }
  // r = b - A x0 and its norm in one pass (cold: r is b, its norm b's).
  double r_norm = cold ? b_norm : std::sqrt(cg_kernels::subtractAndSquare(dim, ws.q.data(), rs));
  // A warm start worse than zero is dropped.
  if (!cold && !(r_norm <= b_norm)) {
    ws.x.setZero();
    splitB();
    r_norm = b_norm;
  }
  const double target = tolerance * b_norm;
  // Without a preconditioner z is r itself.
  const bool plain = preconditioner == Preconditioner::None;
  VecX& z = plain ? ws.r : ws.z;
  double rz = plain ? r_norm * r_norm : applyPreconditioner(preconditioner, ws, filter, ws.r, z);
  // A preconditioner kept from an earlier matrix (a reused Cholesky factor,
  // multigrid coarse levels) either still solves in a few iterations or is
  // stale (e.g. Newton iterates on stiff rotating springs): then it gets only
  // a few before a fresh one, instead of the whole budget.
  const bool reused_factor = preconditioner == Preconditioner::Cholesky && !fresh_factor;
  const bool reused_multigrid =
      preconditioner == Preconditioner::Multigrid && ws.multigrid->reused();
  const int budget =
      reused_factor      ? std::min(max_iterations, CholeskyFactor::kStaleFactorIterations)
      : reused_multigrid ? std::min(max_iterations, ws.multigrid->staleIterations())
                         : max_iterations;
  // Relaxed float products where the whole solve's tolerance does not allow
  // them (A.singlePrecisionFits): a product's rounding reaches the answer
  // only through the residual still to be removed, so it may grow as that
  // falls (inexact Krylov methods: van den Eshof & Sleijpen 2004). A float
  // product of p, whose error is below eps |A p|, shifts the recurrence's r
  // from b - A x by at most eps |alpha A p| = eps |r_k - r_k+1|: gap sums
  // those bounds, the solve stops on r + gap <= target, and a product is
  // float only while that keeps gap within half the target.
  const double eps = A.singlePrecisionFits(tolerance) ? INFINITY : A.relaxedSingleRounding();
  double gap = 0.0;
  int k = 0;
  double* ps = ws.p.data();
  double* qs = ws.q.data();
  // Where float products may come, p's float copy is kept as p is updated
  // (no conversion pass a product).
  const bool relaxable = std::isfinite(eps);
  if (relaxable) {
    ws.p_single.resize(dim);
    cg_kernels::copyWithSingle(dim, z.data(), ps, ws.p_single.data());  // p = z
  } else {
    ws.p = z;
  }
  while (r_norm + gap > target && k < budget) {
    const bool relaxed = gap + 2.0 * eps * r_norm <= 0.5 * target;
    if (relaxed) {
      A.multiplySplitFloat(ps, ws.p_single.data(), qs);
      ++result.float_products;
    } else {
      A.multiplySplit(ps, qs);
    }
    filter.applySplit(qs);
    const double pq = cg_kernels::dot(dim, ps, qs);
    if (!(pq > 0.0)) break;  // not positive definite (or NaN): stop, report
    const double alpha = rz / pq;
    const double rr = cg_kernels::updateSolution(dim, alpha, ps, qs, xs, rs);
    const double r_before = r_norm;
    r_norm = std::sqrt(rr);
    if (relaxed) gap += eps * (r_before + r_norm);
    ++k;
    if (r_norm + gap <= target) break;
    const double rz_new = plain ? rr : applyPreconditioner(preconditioner, ws, filter, ws.r, z);
    if (relaxable) {
      cg_kernels::updateDirectionWithSingle(dim, rz_new / rz, z.data(), ps, ws.p_single.data());
    } else {
      cg_kernels::updateDirection(dim, rz_new / rz, z.data(), ps);
    }
    rz = rz_new;
  }
  giveX();
  if ((reused_factor || reused_multigrid) && r_norm + gap > target && k < max_iterations) {
    // Too stale for this matrix: rebuild from it and go on from x.
    if (reused_factor) {
      ws.cholesky->invalidate();
      // Stale again: the next 2, 4, 8, 16 solves factor afresh at once.
      ws.stale_factors = std::min(ws.stale_factors + 1, 4);
      ws.fresh_factor_solves = 1 << ws.stale_factors;
    }
    if (reused_multigrid) ws.multigrid->invalidate();
    CgResult more = conjugateGradient(A, springs, filter, b, x, preconditioner, tolerance,
                                      max_iterations - k, ws, split);
    more.iterations += k;
    more.float_products += result.float_products;
    return more;
  }
  if (preconditioner == Preconditioner::Multigrid) ws.multigrid->recordSolve(k);
  r_norm += gap;  // what the true residual is known to be below
  if (reused_factor && r_norm <= target) ws.stale_factors = 0;  // reuse pays again
  // The rerouted matrix is close to A on a cloth, not on a collapsed or
  // crumpled one (bend springs across folds): a fresh factor of it that does
  // not solve in kRefactorIterations is set aside for the next 64 factors
  // (a collapsed start: 1200 CG iterations a step instead of 240).
  if (rerouted && k > CholeskyFactor::kRefactorIterations) ws.plain_factors = 64;
  result.iterations = k;
  ws.last_iterations = k;
  result.relative_residual = r_norm / b_norm;
  result.converged = r_norm <= target;
  return result;
}

}  // namespace cloth_sim
