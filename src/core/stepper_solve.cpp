// Stepper::solveLinear: CG on the step's matrix with the preconditioner the
// step picked, and the three places where a cheap one is tried first with a
// capped budget and CG goes on from its answer with a stronger one: block
// Jacobi before a `cholesky` factor where the masses dominate, the factor
// after a stalled `multigrid` V-cycle, and `auto`'s trial of its cheap guess.
#include <algorithm>

#include "cloth_sim/linear_solver.hpp"
#include "cloth_sim/stepper.hpp"

namespace cloth_sim {

template <class Then>
CgResult Stepper::solveThenGoOn(const Model& model, const VecX& b, VecX& x, double tolerance,
                                bool split, Preconditioner first, int cap, Then then,
                                bool* went_on) {
  CgResult cg = conjugateGradient(A_, model.springs, filter_, b, x, first, tolerance, cap, cg_,
                                  split);
  *went_on = !cg.converged;
  if (!*went_on) return cg;
  const int spent = cg.iterations;
  cg = conjugateGradient(A_, model.springs, filter_, b, x, then(), tolerance,
                         settings_.max_iterations, cg_, split);
  cg.iterations += spent;
  return cg;
}

CgResult Stepper::solveLinear(const Model& model, const VecX& b, VecX& x, double tolerance,
                              bool split) {
  if (!(tolerance > 0.0)) tolerance = settings_.tolerance;
  bool went_on = false;
  if (mass_dominated_ && preconditioner_ == Preconditioner::Cholesky) {
    // Stiffer than kappa says (self-repulsion, contact): the factor, on from
    // where block Jacobi got to, and for the next steps too.
    const CgResult cg = solveThenGoOn(
        model, b, x, tolerance, split, Preconditioner::BlockJacobi,
        std::min(settings_.max_iterations, kMassDominatedIterations),
        [&] { return preconditioner_; }, &went_on);
    if (went_on) {
      mass_dominated_ = false;
      mass_dominated_backoff_ = kMassDominatedBackoff;
    }
    return cg;
  }
  const bool trial = settings_.preconditioner == Preconditioner::Auto &&
                     preconditioner_ != strongerPreconditioner(model);
  if (!trial && preconditioner_ == Preconditioner::Multigrid &&
      model.numNodes() <= kMultigridFactorNodes &&
      multigridStallIterations(model) < settings_.max_iterations) {
    // Stalled (a stiff cloth): the factor, on from where the V-cycle got to,
    // and for this step's other solves and the next steps too.
    const CgResult cg = solveThenGoOn(model, b, x, tolerance, split, preconditioner_,
                                      multigridStallIterations(model),
                                      [] { return Preconditioner::Cholesky; }, &went_on);
    if (went_on) {
      preconditioner_ = Preconditioner::Cholesky;
      multigrid_stall_backoff_ = kMultigridStallBackoff;
    }
    return cg;
  }
  if (!trial) {
    return conjugateGradient(A_, model.springs, filter_, b, x, preconditioner_, tolerance,
                             settings_.max_iterations, cg_, split);
  }
  // `auto` guessed the cheap preconditioner and it does not pay: on from
  // where it got to.
  return solveThenGoOn(
      model, b, x, tolerance, split, preconditioner_,
      std::min(settings_.max_iterations, autoTrialIterations(model, preconditioner_)),
      [&] { return preconditioner_ = auto_.escalate(model); }, &went_on);
}

}  // namespace cloth_sim
