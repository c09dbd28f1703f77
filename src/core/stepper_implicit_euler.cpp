// Stepper::implicitEuler: one linearized backward-Euler step, Baraff &
// Witkin's (M - h df/dv - h^2 df/dx) dv = h (f0 + h df/dx v0), with pins,
// contact passes and self-repulsion; and its common case (none of those
// moving or projecting anything) kept split by component from the assembly
// to the update, CG's own layout.
#include <cmath>
#include <cstring>
#include <limits>

#include "cloth_sim/forces.hpp"
#include "cloth_sim/spring_sweeps.hpp"
#include "cloth_sim/stepper.hpp"
#include "step_clock.hpp"
#include "vectorised.hpp"

namespace cloth_sim {

namespace {

/// v += dv, then x += h v, in one pass; whether both came out finite (an
/// AND of compares: no chain of dependent adds). Vectorised, but without
/// multiply-adds: rounded as the two vector expressions it replaced.
CLOTH_SIM_VECTORISED __attribute__((optimize("fp-contract=off")))
bool advanceArrays(long size, double h, const double* __restrict d, double* __restrict w,
                   double* __restrict y) {
  constexpr double kMax = std::numeric_limits<double>::max();
  long finite = 1;
  for (long i = 0; i < size; ++i) {
    const double wi = w[i] + d[i];
    const double yi = y[i] + h * wi;
    w[i] = wi;
    y[i] = yi;
    finite &= static_cast<long>(std::fabs(wi) <= kMax) & static_cast<long>(std::fabs(yi) <= kMax);
  }
  return finite != 0;
}

/// A linearized step's solve in its stats: one Newton iteration, CG's figures.
void noteSolve(const CgResult& cg, Clock::time_point start, StepStats* stats) {
  stats->solve_s = secondsSince(start);
  stats->cg_iterations = cg.iterations;
  stats->residual = cg.relative_residual;
  stats->linear_converged = cg.converged;
  stats->newton_iterations = 1;
}

bool advance(double h, const VecX& dv, VecX& v, VecX& x) {
  return advanceArrays(static_cast<long>(v.size()), h, dv.data(), v.data(), x.data());
}
}  // namespace

bool Stepper::splitStepApplies(double h, const VecX& x, const VecX& v) const {
  if (contact_on_ || !first_pass_ || (repulsion_ && !repulsion_->empty()) ||
      !filter_.projectedNodes().empty() || filter_.holdsPairs()) {
    return false;
  }
  for (size_t k = 0; k < pins_->nodes.size(); ++k) {  // every pin held where it is
    const Vec3 at = x.segment<3>(3 * pins_->nodes[k]);
    if (pins_->targets[k] != at || pinChange(k, x, v, h).squaredNorm() > 0.0) return false;
  }
  return true;
}

void Stepper::assembleLinearized(const Model& model, const VecX& x, const VecX& v, double h) {
  StartAssembly& kept = start_assembly_;
  const auto same = [](const VecX& a, const VecX& b) {
    return a.size() == b.size() &&
           std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
  };
  if (contact_on_ && kept.valid && kept.h == h && same(kept.x, x) && same(kept.v, v)) {
    A_.clearExtras();  // the last pass's friction blocks and repulsion terms
    f_ = kept.f;
    dfdx_v_ = kept.dfdx_v;
  } else {
    assembleSprings(model, x, v, h, h * h, &v, &dfdx_v_, nullptr);
    // Later contact passes start here again (contactPasses).
    if (contact_on_) kept = StartAssembly{true, h, x, v, f_, dfdx_v_};
  }
  if (repulsion_) repulsion_->addToSystem(x, v, h, h * h, true, A_, f_, &v, &dfdx_v_);
}

StepStats Stepper::implicitEulerSplit(const Model& model, double h, VecX& x, VecX& v) {
  // implicitEuler without contact, repulsion, moving or projected pins: the
  // same arithmetic on the same numbers, with f, K v0, the right side and dv
  // split by component (no join of f and K v0, no split of the right side
  // and the warm start, no join of dv: five passes over 3n).
  StepStats stats;
  const int n = model.numNodes();
  auto t0 = Clock::now();
  assembleSystem(model, x, v, h, h * h, settings_.project_compression && !exact_hessian_, A_,
                 f_split_, &v, &kv_split_, nullptr, /*split_out=*/true, settings_.threads);
  rhs_split_ = h * (f_split_ + h * kv_split_);
  filter_.applySplit(rhs_split_.data());
  stats.assembly_s = secondsSince(t0);

  t0 = Clock::now();
  if (dv_split_.size() != 3 * n) dv_split_.setZero(3 * n);
  if (!recycled_split_) recycled_.clear(), recycled_split_ = true;  // kept unsplit
  recycled_.useFor(h);
  if (recycled_iterations_ >= 2) recycled_.guess(rhs_split_, &dv_split_);
  const CgResult cg = solveLinear(model, rhs_split_, dv_split_, 0.0, /*split=*/true);
  recycled_.recordTaking(dv_split_, rhs_split_);  // set afresh before it is read again
  recycled_iterations_ = cg.iterations;
  noteSolve(cg, t0, &stats);

  // dv joined, then advanced: two plain passes beat one gathering three
  // components a node (2000 cycles a seed step where 800). dv_ is then the
  // last answer for the unsplit path's warm start too.
  dv_.resize(3 * n);
  sweeps::joinComponents(dv_split_.data(), n, dv_.data());
  finite_ = advance(h, dv_, v, x);
  linearized_ = false;  // no constraint supplied work: nothing to read off
  placePins(x);
  return stats;
}

StepStats Stepper::implicitEuler(const Model& model, double h, VecX& x, VecX& v) {
  if (splitStepApplies(h, x, v)) return implicitEulerSplit(model, h, x, v);
  StepStats stats;
  const int n = model.numNodes();
  auto t0 = Clock::now();
  assembleLinearized(model, x, v, h);
  rhs_ = h * (f_ + h * dfdx_v_);
  // Pinned velocity changes are prescribed: move their columns to the right side.
  // Nonzero only where the last step prescribed a change (pins_move).
  if (pinned_dv_dirty_ || pinned_dv_.size() != 3 * n) pinned_dv_.setZero(3 * n);
  bool pins_move = false;
  // Without friction or prescribed columns: the constraints' reaction (the
  // contacts', the held nodes', the moving pins') is measured against it.
  bool pins_drive = false;  // a pin moves in this step: its work is read off the reaction
  for (size_t k = 0; k < pins_->nodes.size() && !pins_drive && pins_->reaction_read; ++k) {
    pins_drive = pins_->targets[k] != Vec3(x.segment<3>(3 * pins_->nodes[k]));
  }
  const bool react =
      contact_on_ || !pins_->directions.empty() || filter_.holdsPairs() || pins_drive;
  if (react) rhs0_ = rhs_;
  if (contact_on_) {
    pins_move = contact_.prescribeChange(x, h, v, pinned_dv_);
    contact_.setFrictionSolve(ContactSet::FrictionSolve::Linearized);
    contact_.addFriction(rhs_, h, v);  // at v0; its turn term in A acts on dv
    contact_.addFrictionJacobian(A_, h, v);
  }
  for (size_t k = 0; k < pins_->nodes.size(); ++k) {
    if (yieldsToContact(k)) continue;
    const int p = pins_->nodes[k];
    Vec3 dv = pinChange(k, x, v, h);
    const Vec3 n = pins_->direction(k);
    if (n.squaredNorm() > 0.0) dv = n * n.dot(dv);  // the rest is solved for
    pinned_dv_.segment<3>(3 * p) = dv;
    pins_move = pins_move || dv.squaredNorm() > 0.0;
  }
  if (filter_.holdsPairs()) {  // held pairs end at their gaps: x + h (v + dv)
    g_ = x + h * v;
    filter_.pairs().meet(g_, h, pinned_dv_);
    pins_move = true;
  }
  pinned_dv_dirty_ = pins_move;  // else every entry written is zero
  if (pins_move) {
    A_.multiplyAll(pinned_dv_, g_);
    rhs_ -= g_;
  }
  filter_.apply(rhs_);
  stats.assembly_s = secondsSince(t0);

  t0 = Clock::now();
  if (dv_.size() != 3 * n) dv_.setZero(3 * n);
  if (first_pass_) {
    // Warm start from the last answers at this step size (recycled_start.hpp),
    // else from the last step's dv. Not where the last solve took less than
    // two CG iterations: its guess (its dot products) then costs more than
    // it saves (the seed at its own CG 1e-2: 0.5 iterations a step either
    // way). Not with contact: another start within the tolerance took the
    // contact hard case c4 (a cloth stiffened on a table, stretch 1e7, dt
    // 0.1) from 11 rejected sub-steps to a failure on energy after 8
    // halvings. Later contact passes start from the last pass.
    if (recycled_split_) recycled_.clear(), recycled_split_ = false;  // kept split
    recycled_.useFor(h);
    if (recycled_iterations_ >= 2 && !contact_on_) recycled_.guess(rhs_, &dv_);
  }
  const CgResult cg = solveLinear(model, rhs_, dv_);
  if (first_pass_ && !contact_on_) {  // kept only where a guess uses it
    recycled_.record(dv_, rhs_);
    recycled_iterations_ = cg.iterations;
  }
  noteSolve(cg, t0, &stats);

  if (pins_move) dv_ += pinned_dv_;  // else it is zero
  finite_ = advance(h, dv_, v, x);  // placePins puts pins on their (finite) targets
  if (react) {  // reaction = A dv - rhs0: what the constraints supplied, times h
    A_.multiplyAll(dv_, g_);
    reaction_ = g_ - rhs0_;
    for (const auto& [node, block] : A_.nodeBlocks()) {  // friction is not a reaction
      reaction_.segment<3>(3 * node) -= block * Vec3(dv_.segment<3>(3 * node));
    }
    bh_ = h;
  }
  linearized_ = react;
  if (pins_move) dv_ -= pinned_dv_;  // the free part warm-starts the next solve
  placePins(x);
  return stats;
}

}  // namespace cloth_sim
