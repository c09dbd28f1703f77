// Geometric multigrid preconditioner for the implicit step's CG: one
// symmetric V-cycle on the cloth's rows x cols grid, so the CG iteration count
// stays nearly flat as the grid is refined (block Jacobi doubles it with each
// doubling of the resolution).
//
// Levels: the grid is coarsened by 2 per direction (any size: a coarse line
// sits on every other fine line and on the last one) until at most
// kMaxCoarsestNodes nodes remain. P is bilinear interpolation (x I3); pinned
// fine nodes have zero rows (their velocity change is prescribed) and a coarse
// node on a pinned fine node is fixed too (zero column), so P has full column
// rank and every coarse operator A_c = P^T A P is SPD. The Galerkin products
// have a fixed pattern, built once; each solve only refills the values. The
// coarsest level is solved by a sparse LDL^T whose pattern is analysed once.
//
// Smoothing: one forward block Gauss-Seidel sweep before the coarse
// correction and one backward sweep (its transpose) after it, so the V-cycle
// is a symmetric positive definite operator, as PCG needs. (Two or three
// sweeps each way cut CG iterations by only 25-40% on the hanging cloth.)
//
// The matrix the V-cycle works on is A with each bend spring's coupling S
// (ends two grid lines apart) rerouted through the node between them: 2S on
// each half. S (x_i - x_k)^2 <= 2S (x_i - x_j)^2 + 2S (x_j - x_k)^2, so this
// matrix is >= A (still SPD), and it exceeds A by at most the bend-to-stretch
// stiffness ratio (cloth: 1e-4 to 1), so the preconditioner loses nothing
// measurable; but every level then has a 9-point stencil instead of 13 points
// on the cloth and 25 on the coarse grids, a third of the smoothing and
// Galerkin work.
//
// Reuse across solves (prepare): any fixed SPD operator is a valid PCG
// preconditioner, only the iteration count depends on how close it is to the
// current matrix. So the coarse levels (Galerkin products, their smoothers,
// the coarsest factor) are kept for a few solves, while the finest level is
// refilled from the current matrix every solve: the stiff springs turn a
// little every step, and a V-cycle kept whole costs 1-1.5 more CG iterations
// on the hanging cloth after a single step (more than the setup it saves);
// with a fresh finest level the count grows by about 0.1 a solve. CG's
// product always uses the current matrix, so the answer is unchanged. The
// V-cycle stays SPD with levels from different matrices, as long as each
// level smooths and forms its residual with one matrix A_l: with G = D_l +
// L_l its forward sweep, level l's operator is
//   B_l = G^-T D_l G^-1 + (I - G^-T A_l) P B_(l+1) P^T (I - A_l G^-1),
// symmetric if B_(l+1) is, positive definite if B_(l+1) is and A_l's node
// blocks D_l are.
// The coarse levels are rebuilt from the current matrix when the pins, grid
// or springs change, when any free node's diagonal trace moved by more than
// kTraceChange relative (a new step size or stiffness), after max_solves
// solves, when a solve needed more than kIterationGrowth times the
// iterations of the first solve after the rebuild, or when CG gives up on
// them (invalidate).
//
// Storage: every block of these matrices is symmetric (a spring's coupling S,
// the node blocks, and weighted sums of them), and the matrices are symmetric:
// each level keeps its node blocks and its strictly lower blocks, 6 numbers a
// block. The smoother streams that once per sweep (memory, not arithmetic,
// bounds it).
#pragma once

#include <Eigen/Sparse>
#include <algorithm>
#include <memory>
#include <vector>

#include "cloth_sim/block_ldlt.hpp"
#include "cloth_sim/constraint_filter.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

class SystemMatrix;

/// A symmetric 3x3 block: xx, yy, zz, xy, xz, yz.
struct SymBlock {
  double v[6] = {0, 0, 0, 0, 0, 0};

  static SymBlock from(const Mat3& m) {
    return {{m(0, 0), m(1, 1), m(2, 2), m(0, 1), m(0, 2), m(1, 2)}};
  }
  Mat3 toMat3() const {
    Mat3 m;
    m << v[0], v[3], v[4], v[3], v[1], v[5], v[4], v[5], v[2];
    return m;
  }
  Vec3 operator*(const Vec3& x) const {
    Vec3 y;
    multiply(x.data(), y.data());
    return y;
  }
  /// y = B x on raw 3-vectors (y may alias x).
  void multiply(const double* x, double* y) const {
    double p[3];
    product(x, p);
    y[0] = p[0];
    y[1] = p[1];
    y[2] = p[2];
  }
  /// y -= B x on raw 3-vectors (y must not alias x).
  void subtractProduct(const double* x, double* y) const {
    double p[3];
    product(x, p);
    y[0] -= p[0];
    y[1] -= p[1];
    y[2] -= p[2];
  }
  /// p = B x: the one place the product is written out.
  void product(const double* x, double* p) const {
    p[0] = v[0] * x[0] + v[3] * x[1] + v[4] * x[2];
    p[1] = v[3] * x[0] + v[1] * x[1] + v[5] * x[2];
    p[2] = v[4] * x[0] + v[5] * x[1] + v[2] * x[2];
  }
  double trace() const { return v[0] + v[1] + v[2]; }
  /// The inverse by cofactors (symmetric too); non-finite if singular.
  SymBlock inverse() const {
    const double c_xx = v[1] * v[2] - v[5] * v[5], c_yy = v[0] * v[2] - v[4] * v[4],
                 c_zz = v[0] * v[1] - v[3] * v[3], c_xy = v[4] * v[5] - v[3] * v[2],
                 c_xz = v[3] * v[5] - v[4] * v[1], c_yz = v[3] * v[4] - v[0] * v[5];
    const double s = 1.0 / (v[0] * c_xx + v[3] * c_xy + v[4] * c_xz);
    return {{s * c_xx, s * c_yy, s * c_zz, s * c_xy, s * c_xz, s * c_yz}};
  }
  void addScaled(double s, const SymBlock& b) {
    for (int k = 0; k < 6; ++k) v[k] += s * b.v[k];
  }
};

class MultigridPreconditioner {
 public:
  /// Coarsening stops at this many nodes (or when the grid can shrink no more).
  static constexpr int kMaxCoarsestNodes = 100;

  /// Builds the hierarchy's patterns if the grid, the springs or the pins
  /// changed since the last call, then refills every level from A. Returns
  /// false (the preconditioner is then unusable) if a node block or the
  /// coarsest matrix cannot be factored. Throws std::invalid_argument if
  /// rows * cols is not A's node count.
  bool setup(const SystemMatrix& A, const std::vector<Spring>& springs,
             const std::vector<char>& free, int rows, int cols);

  /// A rebuild comes due when a node's diagonal trace moved by more than this
  /// fraction since the hierarchy was built (dt, stiffness or mass changed).
  static constexpr double kTraceChange = 0.25;
  /// ... or when a solve took more than this times the first solve's iterations.
  static constexpr double kIterationGrowth = 1.5;

  /// Like setup, but keeps the coarse levels built from an earlier matrix for
  /// up to max_solves solves while they still serve (see the header comment);
  /// the finest level is always refilled from A. max_solves = 1 rebuilds
  /// every time. Returns false if a node block or the coarsest matrix cannot
  /// be factored.
  bool prepare(const SystemMatrix& A, const std::vector<Spring>& springs,
               const std::vector<char>& free, int rows, int cols, int max_solves);
  /// Tells the reuse rule how many CG iterations a solve with it took.
  void recordSolve(int iterations);
  /// The next prepare rebuilds (CG found the reused hierarchy too stale).
  void invalidate() { rebuild_due_ = true; }
  /// Whether the last prepare kept an earlier matrix's coarse levels.
  bool reused() const { return reused_; }
  /// CG iterations reused coarse levels get before they are replaced mid-solve.
  int staleIterations() const { return std::max(2 * first_iterations_, first_iterations_ + 4); }
  /// Count of coarse-level rebuilds, for tests and the benchmark.
  int rebuilds() const { return rebuilds_; }

  /// Makes the finest level act on S A S instead of A, S the filter's
  /// projectors (contacts, directional pins): its smoother solves a projected
  /// node's row on the range of S only and the residual it restricts and the
  /// correction it takes back are projected. Without this the V-cycle moved
  /// projected nodes along their constrained directions and passed those
  /// residuals to the coarse levels, and only CG's final filter took them
  /// out (the fold demo laying a layer down, ~300 CG iterations a solve).
  /// Call after prepare/setup, with the filter of the solve; no projection:
  /// the V-cycle is as before, bit for bit.
  void constrain(const ConstraintFilter& filter);

  /// z = B r, B the V-cycle (SPD on the free DOFs); pinned entries of z are
  /// zero and pinned entries of r are ignored.
  void apply(const VecX& r, VecX& z);
  /// The same on vectors split by component (r[c * n + i], CG's layout):
  /// the split and join ride on the copies in and out of the V-cycle.
  void applySplit(const double* r, double* z);

  /// Threads the V-cycle's large levels run on (solver.threads). With more
  /// than one, a level's smoother relaxes its parts (bands of whole grid
  /// rows) side by side: Gauss-Seidel within a part, the couplings across
  /// parts taken from the sweep's start (hybrid Gauss-Seidel). The backward
  /// sweep is still the forward one's transpose, so the V-cycle stays SPD.
  void setThreads(int threads);
  int numLevels() const { return static_cast<int>(levels_.size()); }
  /// Grid size of a level (0 = the cloth).
  int levelRows(int level) const { return levels_[level].rows; }
  int levelCols(int level) const { return levels_[level].cols; }

 private:
  struct Level {
    int rows = 0, cols = 0;
    int num_nodes = 0;
    std::vector<char> free;
    // The matrix: node blocks, then the strictly lower blocks of row i at
    // [lower_begin[i], lower_begin[i + 1]) with columns lower_column.
    std::vector<SymBlock> node_block;
    std::vector<int> lower_begin, lower_column;
    std::vector<SymBlock> lower_block;
    std::vector<SymBlock> inv_node_block;  ///< zero for fixed nodes, so they stay zero
    // Interpolation from the next coarser level, one row per node of this
    // level: coarse nodes interp_node[k] with weights interp_weight[k] for k
    // in [interp_begin[i], interp_begin[i + 1]).
    std::vector<int> interp_begin, interp_node;
    std::vector<double> interp_weight;
    // The same by the coarse nodes (P^T's rows), for the restriction.
    std::vector<int> restrict_begin, restrict_node;
    std::vector<double> restrict_weight;
    // Galerkin refill of the next coarser matrix, in the order galerkin()
    // walks this level's blocks and interpolation pairs: the coarse block each
    // product adds to (index < coarse num_nodes: a node block; else lower
    // block index + num_nodes; -1: counted by its mirror pair).
    std::vector<int> galerkin_target;
    VecX x, b, r;  ///< V-cycle buffers
    // Threads: the smoother's parts (node ranges of whole grid rows, each
    // relaxed by its own thread; empty: one), per row the first lower block
    // within its part, and the rows coupled to an earlier part.
    std::vector<int> part_start, inner_begin, cross_rows;
  };

  void checkGrid(const SystemMatrix& A, int rows, int cols) const;
  bool matchesStructure(const SystemMatrix& A, const std::vector<Spring>& springs,
                        const std::vector<char>& free, int rows, int cols) const;
  void buildStructure(const SystemMatrix& A, const std::vector<Spring>& springs,
                      const std::vector<char>& free, int rows, int cols);
  /// Smoothers, Galerkin products and coarsest factor from the filled finest level.
  bool rebuildCoarse();
  void buildHierarchy(const SystemMatrix& A, const std::vector<Spring>& springs,
                      const std::vector<char>& free, int rows, int cols);
  void buildCoarseSolver();
  void fillFinest(const SystemMatrix& A);
  void galerkin(const Level& fine, Level& coarse) const;
  bool prepareSmoother(Level& level) const;
  bool factorCoarsest();
  void vcycle(int level);
  /// Gauss-Seidel over the level's rows (forward from x = 0, or backward),
  /// each part on its own thread where the level has parts.
  void relax(Level& level, bool forward, const SymBlock* inv);
  /// The level's parts for threads_ (none below parallel::kMinNodes).
  void partition(Level& level) const;

  std::vector<Level> levels_;
  // constrain(): the finest level's smoother blocks with the projected
  // nodes' replaced by S (S D S + (I - S) tr(D) / 3)^-1 S, and those nodes'
  // projectors; empty when the filter has no projection.
  std::vector<SymBlock> constrained_inv_;
  std::vector<int> projected_;
  std::vector<SymBlock> projector_;
  // Finest-level refill, by the matrix's directions (a sweep over each
  // direction's slots, not a gather per spring): per slot, the node between
  // the spring's ends if it is rerouted (-1: not, or no spring), and the
  // lower blocks it subtracts from (the spring's own, or its two halves';
  // -1: none, a pinned end). Indexed [direction][slot].
  struct SlotTargets {
    std::vector<int> via, block_a, block_b;
  };
  std::vector<SlotTargets> slot_targets_;
  // Coarsest direct solve: lower triangle of its matrix as a scalar sparse matrix.
  Eigen::SparseMatrix<double> coarse_matrix_;
  std::vector<int> coarse_node_index_;   ///< value index of entry r >= c of node blocks, 6 a node
  std::vector<int> coarse_lower_index_;  ///< value index of all 9 entries of each lower block
  BlockLdlt coarse_ldlt_;
  // What the patterns were built for.
  int rows_ = -1, cols_ = -1;
  std::vector<int> spring_ends_;
  // The matrix layout and spring list the patterns were last matched to.
  std::shared_ptr<const SpringLayout> layout_key_;
  const Spring* springs_key_ = nullptr;
  std::vector<char> free_key_;
  bool ready_ = false;
  int threads_ = 1;
  // Reuse state: the finest node blocks' traces the coarse levels were built from, solves
  // since then, the first solve's iterations.
  std::vector<double> built_trace_;
  int solves_since_build_ = 0;
  int first_iterations_ = 0;
  bool rebuild_due_ = true;
  bool reused_ = false;
  int rebuilds_ = 0;
};

}  // namespace cloth_sim
