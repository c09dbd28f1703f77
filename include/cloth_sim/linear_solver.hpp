// The implicit step's linear solve: preconditioned CG on the system matrix
// (system_matrix.hpp), its preconditioners (block Jacobi, a sparse Cholesky
// factor, multigrid) and `auto`'s choice among them. Pinned DOFs are
// eliminated: the solve runs on the free nodes only.
#pragma once

#include <Eigen/Sparse>
#include <array>
#include <memory>
#include <vector>

#include "cloth_sim/block_ldlt.hpp"
#include "cloth_sim/constraint_filter.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/multigrid.hpp"
#include "cloth_sim/system_matrix.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

struct CgResult {
  int iterations = 0;
  double relative_residual = 0.0;  ///< ||b - A x|| / ||b|| (a bound on it after float products)
  bool converged = false;
  int float_products = 0;  ///< relaxed products taken in float (linear_solver.cpp)
};

/// The system matrix copied into a sparse matrix whose pattern is built once
/// (nodes and springs never change), refilled in place and factorized.
/// Pinned nodes become identity rows so the pattern stays the same; a
/// projected node's rows and columns are filtered (S A S, plus (I - S) times
/// its mean diagonal), so the factor is of the constrained system itself.
///
/// On a rows x cols grid, each bend spring's coupling S (ends two grid lines
/// apart) is rerouted through the node between them, 2S on each half, as the
/// multigrid does (multigrid.hpp): the matrix factored is then >= A and
/// exceeds it by at most the bend-to-stretch ratio, so CG still converges in
/// one or two iterations, but its stencil has 9 points instead of 25 and
/// its factorization (80 % of a stiff demo's step) costs a fraction.
class CholeskyFactor {
 public:
  /// Refills the values and factorizes. `grid_cols` > 0: the nodes form a
  /// grid with that many columns (bend springs rerouted); 0: A as it is.
  /// A's pair terms (self repulsion) are factored whole, their couplings
  /// too: the pattern grows by the node pairs they join (analysed again
  /// when a new one appears). Returns false if not positive definite.
  bool factorize(const SystemMatrix& A, const std::vector<Spring>& springs,
                 const ConstraintFilter& filter, int grid_cols);
  void solve(const VecX& r, VecX& z) const { ldlt_.solve(r, z); }
  const BlockLdlt& ldlt() const { return ldlt_; }
  /// A factor of a recent matrix is still a very good preconditioner: it is
  /// reused until a solve needs more than this many CG iterations.
  static constexpr int kRefactorIterations = 10;
  /// A reused factor that has not solved within this many iterations is
  /// replaced by a fresh one, and CG goes on from where it stopped.
  static constexpr int kStaleFactorIterations = 15;
  bool isValidFor(const ConstraintFilter& filter) const { return valid_ && filter == filter_; }
  void invalidate() { valid_ = false; }
  /// Changes with every factorization (unique across factors).
  long serial() const { return serial_; }

 private:
  void buildPattern(int num_nodes, const std::vector<Spring>& springs, int grid_cols);
  /// The node pairs (larger, smaller) A's pair terms couple, into pair_nodes_.
  void collectPairNodes(const SystemMatrix& A);
  /// Value indices of block (max(a, b), min(a, b)) of matrix_, entry (r, c)
  /// at nine[3c + r] (the pattern must hold it).
  void blockIndices(int a, int b, int* nine);
  Eigen::SparseMatrix<double> matrix_;
  std::vector<int> diag_index_;  ///< value index of entry (0,0) of each node block, per column
  /// Per spring: its middle node if rerouted (else -1), and the value
  /// indices (9 a spring, entry (r, c) at 3c + r) of the blocks it adds to:
  /// block (max, min) of its ends, or of its two halves.
  std::vector<int> via_, block_a_, block_b_;
  BlockLdlt ldlt_;
  int num_nodes_ = -1;
  size_t num_springs_ = 0;
  int grid_cols_ = 0;
  /// Node pairs the pattern holds beyond the springs' (sorted, unique), and
  /// those the last matrix's pair terms couple.
  std::vector<std::pair<int, int>> pattern_pairs_, pair_nodes_;
  bool valid_ = false;
  long serial_ = 0;
  ConstraintFilter filter_;  ///< the filter the factor was made for
};

/// Reused buffers, so a solve allocates nothing once sized.
struct CgWorkspace {
  /// CG's vectors, split by component (SystemMatrix::multiplySplit), and
  /// the unsplit ones a multigrid or Cholesky apply takes.
  VecX x, r, z, p, q, joined_r, joined_z;
  std::vector<float> p_single;  ///< p rounded to float, where products may be float
  /// Block Jacobi's inverse node blocks, split by entry (xx, yy, zz, xy,
  /// xz, yz; zero for eliminated nodes).
  std::vector<double> inv_diag;
  std::shared_ptr<CholeskyFactor> cholesky;  ///< made on first use
  std::shared_ptr<MultigridPreconditioner> multigrid;  ///< made on first use
  /// The cloth grid (node = row * cols + col); the multigrid needs it.
  int grid_rows = 0, grid_cols = 0;
  /// Solves one multigrid hierarchy may serve (MultigridPreconditioner::prepare); 1: rebuilt every solve.
  int multigrid_max_solves = 1;
  int threads = 1;  ///< solver.threads, for the multigrid (the product's are the matrix's)
  int last_iterations = 0;
  int factorizations = 0;  ///< count, for the benchmark
  /// Reused Cholesky factors that went stale in a row, and solves left that
  /// factor afresh at once instead of trying the old factor first: Newton on
  /// a stiff cloth changes the matrix so much between iterates that each
  /// trial wasted kStaleFactorIterations triangular solves (1.5 times a
  /// factorization) before the refactorization came anyway.
  int stale_factors = 0;
  int fresh_factor_solves = 0;
  /// Cholesky factors of the rerouted matrix (CholeskyFactor), and how many
  /// factors are left to make of A itself after the rerouted one did not pay.
  /// The steppers set it (every method since session 35: the hard cases
  /// under newton and bdf2 took 78 s where 122).
  bool reroute_bends = false;
  int plain_factors = 0;
  /// With held pairs (ConstraintFilter::holdPairs) the Cholesky solve is made
  /// exact on their null space too (range-space method). With B = P^T L^-T
  /// D^-1 L^-1 P the factor and C the restricted rows: W = L^-1 P C^T, whose
  /// column r is nonzero only on row r's paths up the elimination tree
  /// (entries [pair_start[r], pair_start[r+1]) at factor positions pair_pos,
  /// W's 3-vectors pair_wv and D^-1 W's pair_dwv), and C B C^T = W^T D^-1 W
  /// factored; made again when the factor or the rows change (counts below).
  std::vector<int> pair_start, pair_pos;
  std::vector<Vec3> pair_wv, pair_dwv;
  Eigen::LDLT<Eigen::MatrixXd> pair_schur;
  std::vector<Vec3> pair_half;  ///< L^-1 P r inside a corrected solve
  Eigen::VectorXd pair_s;
  bool pairs_corrected = false;
  long pair_factor = -1;  ///< CholeskyFactor::serial
  long pair_generation = -1;
};

/// kappa = h (c + h k) / m for a step of size h (k, c the stiffest spring
/// group's stiffness and damping, m the lightest node): how far the stiffest
/// coupling outweighs the lightest mass in the system matrix.
double autoStiffness(const Model& model, double h);

/// What `auto` runs for a step of size h (docs/scene.md gives the measurements):
/// - while kappa <= jacobi_limit, the cheap one (cheapPreconditioner): there
///   CG usually converges in a few hundred block-Jacobi iterations, cheaper
///   than a factorization (the 24 x 24 demo, dt 1/120, CG to 1e-4: block
///   Jacobi 1.5 ms a step at kappa 2700, 3.1 ms at 26000; cholesky 4.3 and
///   8.4), and in a few multigrid V-cycles, cheaper still from 12 x 12 up.
///   kappa alone does not say when it stops paying (a falling flat 20 x 20
///   cloth, CG to 1e-6, needed thousands of block-Jacobi iterations at kappa
///   3750): AutoPreconditioner watches the iterations and lowers the limit;
/// - cholesky up to kAutoCholeskyNodes nodes when stiffer: a factor of the
///   whole matrix solves at any stiffness in a few iterations;
/// - multigrid beyond (the factorization's fill grows faster than the grid).
/// AutoPreconditioner (below) makes the choice; any other request is kept.
/// A stronger one than the cheap guess for this model: cholesky up to
/// kAutoCholeskyNodes nodes, multigrid beyond (where it is the cheap guess too).
Preconditioner strongerPreconditioner(const Model& model);
/// The cheap one for a soft cloth: multigrid on a grid of at least
/// kAutoMultigridNodes nodes, block Jacobi on smaller ones. Measured
/// (2026-11-24, ms a step, block Jacobi / multigrid): the demo cloth at
/// 16 x 16 0.58 / 0.31 and 24 x 24 2.09 / 0.77 (implicit_euler dt 1/120, CG
/// 1e-4); the hang cloth at 12 x 12 0.15 / 0.11, 32 x 32 2.2 / 0.88 and
/// 48 x 48 7.2 / 2.1 (bdf2 dt 1/160, CG 1e-2): block Jacobi's iterations grow
/// with the grid (17 to 80), the V-cycle's barely (2.5 to 4.3).
/// With colliders (`contact`) block Jacobi on every grid: the contact
/// constraints cost the V-cycle its reach (drop32 31 CG iterations a step
/// where 2-4 free) and the hierarchy is rebuilt as contacts change.
/// Measured (2026-11-26, ms a step, block Jacobi / multigrid): drop32 2.15 /
/// 3.68, drop64 17.0 / 28.9, hang32_floor 0.29 / 0.37, the fold demo with
/// self-collision off 1.4 / 5.5.
Preconditioner cheapPreconditioner(const Model& model, bool contact = false);
/// Grids from this many nodes get multigrid as the cheap preconditioner.
constexpr int kAutoMultigridNodes = 144;
/// Above this kappa `auto` does not try the cheap guess at all (the demo at
/// stretch 1e6, kappa 5e5: thousands of iterations; at 5e4 stretch, kappa
/// 26000, still 220 and cheaper than the factor).
constexpr double kAutoJacobiLimit = 5.0e4;
/// A solve with a block-Jacobi guess that has not converged after this many
/// iterations goes on with the stronger preconditioner (about where a cholesky
/// solve costs less: 300 block-Jacobi iterations on the 20 x 20 and 24 x 24
/// cloths). A multigrid guess gets fewer: autoTrialIterations.
constexpr int kAutoJacobiIterations = 400;
constexpr int kAutoCholeskyNodes = 4096;
/// How many iterations a solve with the cheap guess `cheap` gets before it
/// goes on with the stronger preconditioner: kAutoJacobiIterations for block
/// Jacobi; for multigrid where the stronger one is cholesky, 2 sqrt(n) for n
/// nodes, about where the factor starts to cost less. A V-cycle costs as
/// much as several block-Jacobi iterations, and on a stiff cloth multigrid's
/// iterations grow with the stiffness while the factor's stay at 7-11.
/// Measured (2026-11-25, ms a step, implicit_euler CG 1e-6, multigrid /
/// cholesky): a 20 x 20 cloth with stretch springs only, stretch 1e4, dt
/// 1/240: 35 V-cycles, 1.1 / 0.53; 40 x 40, 1/240: 79, 8.6 / 5.2; 64 x 64,
/// 1/240: 121, 32 / 24; 40 x 40 stretch 1e5 dt 1/60: 494, 57 / 14; hang32
/// (shear and bend too) stretch 1e5 dt 1/60: 179, 24 / 27; dt 1/250: 28,
/// 3.9 / 7.5.
int autoTrialIterations(const Model& model, Preconditioner cheap);
/// How many V-cycle iterations a multigrid solve gets before it goes on with
/// a Cholesky factor: 2 sqrt(n) for n nodes, about where the factor starts
/// to cost less (autoTrialIterations). On a stiff cloth the V-cycle stalls
/// while the factor solves at any stiffness: the 128 x 128 cloth (hard case
/// 10) at stretch 1e7, dt 0.01, took 7049 V-cycles and 7 rejected sub-steps
/// in one step (15.5 s) where a factor solves it in 2 iterations (0.41 s).
int multigridStallIterations(const Model& model);

/// `auto` across steps: the cheap guess (block Jacobi or multigrid,
/// cheapPreconditioner) where it pays. A solve with it that runs past
/// autoTrialIterations goes on with the stronger preconditioner (no step is
/// rejected for the guess). After kAutoEscalations attempts in a row did so,
/// the stronger one is used from the start for every step at least half that
/// stiff (kappa), and the guess is tried again after kAutoReprobeAttempts attempts, or on a cloth
/// made much softer. One long solve alone does not move the limit: the
/// flooded demo node (pins grasped and released 200 times a second) has
/// such solves now and then, and a limit lowered by them put it on the
/// factor and its marker rate fell to 53 of 60 Hz.
class AutoPreconditioner {
 public:
  /// This attempt's preconditioner (`requested` as it is unless Auto);
  /// `contact`: the scene has colliders (cheapPreconditioner).
  Preconditioner choose(Preconditioner requested, const Model& model, double h,
                        bool contact = false);
  /// A block-Jacobi solve of this attempt did not converge in time: returns
  /// the stronger preconditioner.
  Preconditioner escalate(const Model& model);
  /// Forgets what was learnt (a new scene).
  void reset() {
    jacobi_limit_ = kAutoJacobiLimit;
    streak_ = 0;
  }
  double jacobiLimit() const { return jacobi_limit_; }
  static constexpr int kAutoEscalations = 3;
  static constexpr int kAutoReprobeAttempts = 200;

 private:
  double jacobi_limit_ = kAutoJacobiLimit;
  double kappa_ = 0.0;      ///< of the attempt being solved
  bool guessed_ = false;    ///< the attempt being solved started with the cheap guess
  bool escalated_ = false;  ///< ... and escalated
  int streak_ = 0;          ///< attempts in a row that escalated
  int since_lowered_ = 0;   ///< attempts since the limit was lowered
};

/// Preconditioned conjugate gradient on S A S y = S b, S the constraint
/// filter (Baraff & Witkin's modified PCG). `x` is the warm start and the
/// answer, filtered on entry (eliminated entries zero). Stops when
/// ||r|| <= tolerance * ||S b|| or after max_iterations. The preconditioner
/// is built on the filter's free mask and its output filtered: S B S.
/// With `split`, b and x come (and x goes) split by component, CG's own
/// layout (SystemMatrix::multiplySplit): no split or join passes.
CgResult conjugateGradient(const SystemMatrix& A, const std::vector<Spring>& springs,
                           const ConstraintFilter& filter, const VecX& b, VecX& x,
                           Preconditioner preconditioner, double tolerance,
                           int max_iterations, CgWorkspace& ws, bool split = false);

}  // namespace cloth_sim
