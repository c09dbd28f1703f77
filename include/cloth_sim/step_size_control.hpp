// Error-controlled time stepping (solver.error_tolerance): the local error
// estimate of a step, and the step size that keeps it within the tolerance.
//
// The estimate compares the step with the trapezoidal rule over the same
// interval, x1 - x0 - h (v0 + v1) / 2, which costs one pass over the nodes
// and no solve. The trapezoidal rule is third order locally, so this
// departure is the step's own position error up to a known factor:
//   backward Euler (implicit_euler, newton): E = departure          (order 1)
//   BDF2 with step ratio w = h / h_prev:     E = C / (C - 1/12) departure,
//     C = (1 + w)^2 / (6 w (1 + 2 w))      (8/5 at w = 1)      (order 2)
// (Taylor expansion of each formula's residual on the exact solution;
// docs/design.md, "Error-controlled stepping").
#pragma once

#include "cloth_sim/constraint_filter.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// RMS over the nodes the filter does not eliminate of |S_i (x1 - x0 -
/// h (v0 + v1) / 2)_i| (m), S_i the node's filter at the end of the step.
/// Pinned nodes follow their targets and a contact node ends on its surface
/// along its normals (filtered out by the caller: ContactSet::
/// constrainNormals): no error of the step there. The trapezoidal rule has
/// one across a landing's velocity jump (h |v_impact| / 2), so counting it
/// shrank every landing step to dt_min.
double trapezoidDeparture(const VecX& x0, const VecX& v0, const VecX& x1, const VecX& v1,
                          double h, const ConstraintFilter& filter);

/// The factor that turns the departure into a BDF2 step's local error, for
/// the step ratio w = h / h_prev (> 0).
double bdf2ErrorFactor(double w);

/// Picks step sizes for a local error per unit step of `tolerance` (relative
/// to a length scale, per simulated second), within [dt_min, dt_max].
class StepSizeControl {
 public:
  StepSizeControl() = default;
  StepSizeControl(double tolerance, double dt_first, double dt_min, double dt_max);

  /// The size the next step should have (s).
  double proposal() const { return proposal_; }
  double dtMin() const { return dt_min_; }

  /// Judges a step of size h whose relative local error estimate is `error`,
  /// taken by a method of `order`; `clipped`: h was cut short of proposal()
  /// (an event or the end of an interval). Returns whether the step is
  /// accepted (error within tolerance * h, or h already at dt_min) and sets
  /// the next proposal either way.
  bool judge(double h, double error, int order, bool clipped);
  /// A step that recovery had to split (an energy or solver failure, not an
  /// error estimate): the next steps start from the size that worked.
  void shrinkTo(double h);

 private:
  double clamp(double h) const;

  double tolerance_ = 0.0;
  double proposal_ = 0.0;
  double dt_min_ = 0.0;
  double dt_max_ = 0.0;
};

}  // namespace cloth_sim
