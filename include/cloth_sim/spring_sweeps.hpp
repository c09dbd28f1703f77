// Sweeps over one direction of the spring layout (spring_layout.hpp): the
// per-spring arithmetic of the forces, the system matrix's coefficients and
// the energy, written as loops over contiguous per-slot arrays that the
// compiler vectorises. Positions and velocities come split by component
// (splitComponents). A sweep writes each slot's term on the slot's lower
// end; PaddedTerms::addDifferences then gives every node its two-sided sum.
// Used by forces.cpp and SystemMatrix.
#pragma once

#include <vector>

#include "cloth_sim/types.hpp"

namespace cloth_sim {
namespace sweeps {

/// out[c * n + i] = x[3 i + c]: a 3n vector split by component.
void splitComponents(const VecX& x, double* out);
/// out[3 i + c] = in[c * n + i].
void joinComponents(const double* in, int n, double* out);

/// Per-slot term arrays of one direction (3, or 6 for symmetric blocks),
/// each with `offset` zeros either side; term(c)[p] is slot p's.
class PaddedTerms {
 public:
  void reset(int n, int offset, int components = 3);
  /// reset() unless already of this shape: the pads are zero still (nothing
  /// writes them), the terms are left as they were.
  void ensure(int n, int offset, int components = 3) {
    if (n != n_ || offset != offset_ || components != components_ || !data_) reset(n, offset, components);
  }
  double* term(int c) { return data_ + c * padded_ + offset_; }
  /// y_c[p] += t_c[p] - t_c[p - offset] for p < n (3 components): slot p's
  /// term on its lower end p, minus it on its upper end p + offset.
  void addDifferences(double* y_split) const;
  /// y_c[p] += t_c[p] + t_c[p - offset] for p < n, every component: a
  /// block that both ends get (the matrix diagonal).
  void addSums(double* y_split) const;
  /// y = m x + a's and b's differences (m per node, x and y split by
  /// component; b may be null): two directions and the node blocks of a
  /// product in one pass. Nodes [first, last) (last < 0: all).
  static void sumDifferences(const double* m, const double* x_split, const PaddedTerms& a,
                             const PaddedTerms* b, double* y_split, int first = 0,
                             int last = -1);
  /// y += a's and b's differences (b may be null), nodes [first, last).
  static void addPairDifferences(const PaddedTerms& a, const PaddedTerms* b, double* y_split,
                                 int first = 0, int last = -1);
  /// y = (y, or 0 with `from_zero`) + terms[0]'s differences + terms[1]'s
  /// + ..., added in that order (so the same as addDifferences of each in
  /// turn) in one pass; 3 components, count up to kMaxDirections.
  static void addDifferencesOfAll(const PaddedTerms* terms, int count, bool from_zero,
                                  double* y_split);
  /// The same for nodes [first, last) of y only.
  static void addDifferencesOfAll(const PaddedTerms* terms, int count, bool from_zero,
                                  double* y_split, int first, int last);
  static constexpr int kMaxDirections = 8;

 private:
  std::vector<double> buffer_;
  double* data_ = nullptr;
  int n_ = 0, offset_ = 0, padded_ = 0, components_ = 3;
};

/// What one direction's force sweep reads. Pointers are per slot (valid,
/// rest) or per node by component (x, v, w); w and held may be null.
struct ForceSweepIn {
  int slots = 0, offset = 0;
  const double* x[3] = {};
  const double* v[3] = {};
  const double* w[3] = {};     ///< non-null: also K (w_j - w_i)
  const double* held[3] = {};  ///< non-null: damping along these axes, per slot
  const double* valid = nullptr;
  const double* rest_length = nullptr;
  const double* rest_dir[3] = {};
  /// Non-null: the slots' lengths |x_upper - x_lower| at these x, measured
  /// already (energySweep's); implicit_euler's assembly (matrix and K w,
  /// relative-velocity damping) reads them instead of taking square roots.
  const double* length = nullptr;
  double stiffness = 0.0, damping = 0.0;
  bool along = true;            ///< along-spring damping (else relative velocity)
  bool project_compression = false;
  double a = 0.0, b = 0.0;      ///< the matrix's scales of df/dv and df/dx
};

/// What it writes per slot; null pointers are skipped.
struct ForceSweepOut {
  double* f[3] = {};    ///< force on the lower end
  double* kw[3] = {};   ///< K (w_upper - w_lower), with `w`
  double* iso = nullptr;
  double* axis = nullptr;
  double* u[3] = {};    ///< the matrix coefficients (SystemMatrix::Coefficients)
  double* c = nullptr;
  double* hw[3] = {};   ///< held damping coefficient and axis, with `held`
  /// Non-null (with iso, not with held): iso, axis and u again as floats
  /// (SystemMatrix::singleCoefficients).
  float* iso_single = nullptr;
  float* axis_single = nullptr;
  float* u_single[3] = {};
};

/// The forces (and, with `iso`, the coupling coefficients b K + a D) of one
/// direction's springs: spring_forces.hpp's formulas, slot by slot.
void forceSweep(const ForceSweepIn& in, const ForceSweepOut& out);
/// The same for slots [first, last) only (each slot's result as forceSweep's).
void forceSweep(const ForceSweepIn& in, const ForceSweepOut& out, int first, int last);

/// Sum over the direction's springs of (l - L)^2, and the largest l / L - 1
/// (or `max_strain` if larger); with `length`, each slot's l there.
void energySweep(int slots, int offset, const double* const x[3], const double* valid,
                 const double* rest_length, const double* inv_rest_length, double* sum_sq,
                 double* max_strain, double* length = nullptr);

}  // namespace sweeps
}  // namespace cloth_sim
