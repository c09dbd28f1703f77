// The system matrix A = M - b h df/dv - b^2 h^2 df/dx of an implicit step,
// stored per node (its mass block, a multiple of I) and per spring (one
// symmetric 3x3 coupling block S, entering as A_ii += S, A_jj += S,
// A_ij = A_ji = -S), so the sparsity pattern is the spring list: fixed,
// refilled in place each step.
//
// A spring's S is iso I + axis u u^T (its stiffness and damping act along its
// axis u and isotropically), kept as those 5 numbers. Newton's along-spring
// damping acts along an axis held over the step (newtonSolve), which can
// differ from the spring's current axis: it adds a second outer product
// c w w^T (setDampingAxis), read only while set.
//
// The couplings are kept by direction (spring_layout.hpp), one slot per node
// in separate arrays, so the product and the assembly are stencil sweeps
// over contiguous arrays the compiler vectorises: on the 16 x 16 seed cloth
// a product takes 1.5 us, where a per-spring loop over 48-byte records took
// 3.1 (docs/profile.md).
#pragma once

#include <array>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "cloth_sim/constraint_filter.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/multigrid.hpp"
#include "cloth_sim/spring_layout.hpp"
#include "cloth_sim/spring_sweeps.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

class SystemMatrix {
 public:
  /// Sizes the matrix for the layout's nodes and springs (a model's
  /// `layout`); the coupling arrays are made anew only for another layout.
  void resize(const std::shared_ptr<const SpringLayout>& layout);
  int numNodes() const { return layout_ ? layout_->num_nodes : 0; }
  int numSprings() const { return layout_ ? static_cast<int>(layout_->slot.size()) : 0; }
  /// Sets the node blocks to mass_i * I (+ extra_diagonal * I). Couplings are
  /// then set by setCoupling for every spring.
  void reset(const std::vector<double>& mass, double extra_diagonal = 0.0);
  /// Drops the node blocks and pair terms (addNodeBlock, addPairTerm) and
  /// keeps the springs' terms: the matrix as its assembly left it.
  void clearExtras() {
    node_blocks_.clear();
    pair_terms_.clear();
    changed();
  }
  /// Sets spring k's block S = iso I + axis u u^T (u unit).
  void setCoupling(int spring, double iso, double axis, const Vec3& u) {
    const SpringSlot& s = layout_->slot[spring];
    Coefficients& d = coefficients_[s.direction];
    d.iso[s.node] = iso;
    d.axis[s.node] = axis;
    for (int c = 0; c < 3; ++c) d.u[c][s.node] = u[c];
    changed();
  }
  /// Adds damping c w w^T (w unit) to spring k's block: the along-spring
  /// damping of an axis w held over the step. Kept until reset(); once one
  /// spring's is set, every spring's is part of the matrix, so set all.
  void setDampingAxis(int spring, double damping, const Vec3& w) {
    if (!has_damping_axes_) useDampingAxes();
    const SpringSlot& s = layout_->slot[spring];
    Coefficients& d = coefficients_[s.direction];
    d.c[s.node] = damping;
    for (int c = 0; c < 3; ++c) d.w[c][s.node] = w[c];
    changed();
  }
  /// One direction's coupling arrays, per slot (the assembly's sweeps write
  /// them): S = iso I + axis u u^T, plus c w w^T after useDampingAxes().
  struct Coefficients {
    std::vector<double> iso, axis, u[3];
    std::vector<double> c, w[3];  ///< sized by useDampingAxes()
  };
  Coefficients& coefficients(int direction) {
    changed();
    return coefficients_[direction];
  }
  /// Read-only: direction `direction`'s coupling arrays (c, w only while
  /// hasDampingAxes()).
  const Coefficients& coefficientsAt(int direction) const { return coefficients_[direction]; }
  bool hasDampingAxes() const { return has_damping_axes_; }
  /// Direction `direction`'s float copies of iso, axis and u0..u2 (n apart),
  /// for the assembly's sweep to write beside the double ones where the
  /// matrix before the last reset() took float products: the float product
  /// then needs no conversion pass (4 % of the seed's step). Null where
  /// there are none to write (no float products last time, held damping
  /// axes). Once every direction's is written, after coefficients():
  /// singleWritten().
  float* singleCoefficients(int direction);
  void singleWritten() const { single_valid_ = true; }
  /// The layout the matrix was sized for (resize).
  const std::shared_ptr<const SpringLayout>& layout() const { return layout_; }
  /// Makes the held damping axes part of the matrix until reset().
  void useDampingAxes();
  /// Adds a symmetric block to node i's diagonal (a contact's friction
  /// Jacobian): couplings beyond the spring list, kept until reset().
  void addNodeBlock(int node, const Mat3& block) {
    node_blocks_.emplace_back(node, SymBlock::from(block));
    changed();
  }
  const std::vector<std::pair<int, SymBlock>>& nodeBlocks() const { return node_blocks_; }
  /// A coupling (w w^T) (x) B over four nodes, B symmetric 3x3 (a self
  /// repulsion term, self_repulsion.hpp: B = c n n^T along its normal plus
  /// its friction's c_t (I - n n^T)): beyond the spring list, kept until
  /// reset(). Products apply it whole; the preconditioners see only its node
  /// blocks w_k^2 B (fullDiagonal), which keeps them SPD and their patterns
  /// fixed.
  struct PairTerm {
    std::array<int, 4> node;
    std::array<double, 4> w;
    SymBlock B;
    SymBlock diagonal(int k) const {
      SymBlock d;
      d.addScaled(w[k] * w[k], B);
      return d;
    }
  };
  void addPairTerm(const PairTerm& term) {
    pair_terms_.push_back(term);
    changed();
  }
  const std::vector<PairTerm>& pairTerms() const { return pair_terms_; }
  /// Node block without the couplings: nodeScale(i) * I.
  double nodeScale(int node) const { return node_scale_[node]; }
  Mat3 diag(int node) const { return node_scale_[node] * Mat3::Identity(); }
  Mat3 coupling(int spring) const { return couplingBlock(spring).toMat3(); }
  SymBlock couplingBlock(int spring) const;
  /// The coupling block of a direction's slot (zero where it holds no spring).
  SymBlock couplingBlockAt(int direction, int slot) const;

  /// y = A x, unfiltered (contact reactions), in double precision.
  void multiplyAll(const VecX& x, VecX& y) const;
  /// y = A x on vectors split by component (x[c * n + i]; CG's layout);
  /// y must not alias x. After allowSinglePrecision, in single precision
  /// from the second product on where that fits the tolerance.
  void multiplySplit(const double* x, double* y) const;
  /// CG tells the matrix its relative tolerance before a solve: the
  /// products after the first may round the springs' terms to single
  /// precision (the node blocks stay double) if singlePrecisionFits. Not the
  /// first: a solve of one product would pay for the float copies and gain
  /// nothing (the seed scene at rest).
  void allowSinglePrecision(double tolerance) const {
    single_tolerance_ = tolerance;
    single_products_ = 0;
  }
  /// Whether rounding the terms to float is far below `tolerance`: when
  /// 2^-24 times the largest ratio of a node's couplings to its node block,
  /// times 40, is at most the tolerance (a term's few roundings, kept 10x
  /// below what CG is asked for). Stiff cloth (couplings >> mass) stays
  /// double: a float spring axis would leak its stiffness into the soft
  /// directions.
  bool singlePrecisionFits(double tolerance) const;
  /// The largest ratio of a node's summed coupling norms to its node block.
  double couplingToMassRatio() const;
  /// For CG's relaxed products (linear_solver.cpp): a bound on a float
  /// product's error relative to |A x|, the rounding singlePrecisionFits
  /// checks times the node blocks' spread (largest over smallest). A >= the
  /// node blocks holds where every coupling is PSD and there are no extra
  /// node blocks or pair terms; elsewhere INFINITY (no bound, no float).
  double relaxedSingleRounding() const;
  /// The assembler's bound on a node's summed couplings (|iso| + |axis| +
  /// |c| over its slots), given with its word that every coupling is PSD
  /// (assembleSystem with the compression projection: twice b k + a c of
  /// each direction's group). Any later change of the couplings drops it;
  /// without it there are no relaxed products.
  /// Threads the product runs on (solver.threads); the same y on any count.
  void setThreads(int threads) { threads_ = threads; }
  void setPsdCouplingBound(double bound) const {
    psd_coupling_bound_ = bound;
    ratio_valid_ = false;
  }
  /// y = A x with the springs' terms in float (node blocks, pair terms and
  /// vectors in double), whatever the tolerance: CG bounds its error itself.
  void multiplySplitFloat(const double* x, double* y) const;
  /// The same, x's float copy given (CG keeps one beside its direction:
  /// no conversion pass a product).
  void multiplySplitFloat(const double* x, const float* x_single, double* y) const;
  /// Full diagonal block of node i including its springs' couplings (summed
  /// on first use after the couplings changed: only block Jacobi and Cholesky
  /// need them).
  Mat3 fullDiag(int node) const { return fullDiagonal()[node].toMat3(); }
  const std::vector<SymBlock>& fullDiagonal() const;

 private:
  void changed() {
    full_diag_valid_ = false, single_valid_ = false, ratio_valid_ = false;
    psd_coupling_bound_ = INFINITY;
  }
  void multiplySplitDouble(const double* x, double* y) const;
  void multiplySplitSingle(const double* x, double* y,
                           const float* x_single) const;  // system_matrix_single.cpp
  /// The float product's pieces: direction k's terms for slots [first,
  /// last), and the sums of directions k, k + 1 for nodes [first, last) (the
  /// last pair's with y = m x).
  void singleTerms(size_t k, const float* x_single, int first, int last) const;
  void singlePairSums(size_t k, int first, int last, const double* x, double* y) const;
  /// y += the extra node blocks' and the pair terms' products (either product).
  void addNodeBlocksAndPairTerms(const double* x, double* y) const;
  void makeSingleCopies() const;
  void sizeSingleCopies() const;  ///< single_dirs_ for this layout (terms' pads zero)
  std::shared_ptr<const SpringLayout> layout_;
  std::vector<double> node_scale_;  ///< node block = node_scale_ * I
  std::vector<Coefficients> coefficients_;  ///< per direction of the layout
  bool has_damping_axes_ = false;
  std::vector<std::pair<int, SymBlock>> node_blocks_;  ///< extra node blocks (addNodeBlock)
  std::vector<PairTerm> pair_terms_;                   ///< addPairTerm's
  /// ys += the pair terms' product (split vectors), in double precision.
  void multiplyPairTerms(const double* xs, double* ys) const;
  mutable std::vector<SymBlock> full_diag_;
  mutable bool full_diag_valid_ = false;
  /// Work arrays of the product and the diagonal: by component, each
  /// direction's per-slot terms (the product), one direction's blocks (the diagonal).
  mutable std::vector<double> x_split_, y_split_, diag_split_;
  mutable std::vector<sweeps::PaddedTerms> direction_terms_;
  mutable sweeps::PaddedTerms terms_;
  /// The single-precision product's copies: per direction its coefficients
  /// (iso, axis, u0..u2, then c, w0..w2 when held) and padded terms, the
  /// float x and the summed terms.
  struct SingleDirection {
    std::vector<float> coefficients;
    std::vector<float> terms;  ///< 3 components of n + offset, offset zeros first
  };
  mutable std::vector<SingleDirection> single_dirs_;
  mutable std::vector<float> x_single_, sum_single_;
  mutable double single_tolerance_ = 0.0;  ///< allowSinglePrecision's; 0: double
  mutable int single_products_ = 0;        ///< products since
  mutable bool single_valid_ = false;      ///< the float copies are of this matrix
  mutable bool single_used_ = false;       ///< a float product since reset()
  bool single_wanted_ = false;             ///< single_used_ before the last reset()
  mutable std::vector<double> coupled_;  ///< per node, couplingToMassRatio's sums
  mutable double ratio_ = 0.0;
  mutable bool ratio_valid_ = false;
  mutable double psd_coupling_bound_ = INFINITY;  ///< setPsdCouplingBound's
  std::pair<double, double> node_scale_range_{0.0, 0.0};  ///< smallest, largest (reset)
  int threads_ = 1;
};

inline SymBlock SystemMatrix::couplingBlock(int spring) const {
  const SpringSlot& s = layout_->slot[spring];
  return couplingBlockAt(s.direction, s.node);
}

inline SymBlock SystemMatrix::couplingBlockAt(int direction, int p) const {
  const Coefficients& d = coefficients_[direction];
  const double a = d.axis[p], iso = d.iso[p], u0 = d.u[0][p], u1 = d.u[1][p], u2 = d.u[2][p];
  SymBlock S{{iso + a * u0 * u0, iso + a * u1 * u1, iso + a * u2 * u2, a * u0 * u1, a * u0 * u2,
              a * u1 * u2}};
  if (has_damping_axes_) {
    const double e = d.c[p], w0 = d.w[0][p], w1 = d.w[1][p], w2 = d.w[2][p];
    S.addScaled(1.0, {{e * w0 * w0, e * w1 * w1, e * w2 * w2, e * w0 * w1, e * w0 * w2,
                       e * w1 * w2}});
  }
  return S;
}

}  // namespace cloth_sim
