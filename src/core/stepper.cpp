#include "cloth_sim/stepper.hpp"

#include <chrono>
#include <limits>
#include <cmath>
#include <algorithm>

#include "cloth_sim/forces.hpp"
#include "step_clock.hpp"

namespace cloth_sim {

namespace {

/// The loosest relative CG tolerance of a Newton iteration (inexact Newton).
constexpr double kMaxForcing = 0.1;
/// Newton iterations of a contact pass whose set may still change (step()).
constexpr int kExploringIterations = 2;

bool hasSpringDamping(const Model& model) {
  for (const SpringGroup& g : model.groups) {
    if (g.damping != 0.0 && g.end > g.begin) return true;
  }
  return false;
}

}  // namespace

void Stepper::forces(const Model& model, const VecX& x, const VecX& v, VecX& f,
                     const std::vector<Vec3>* damping_axes) const {
  computeForces(model, x, v, f, damping_axes, settings_.threads);
  if (repulsion_) repulsion_->addForces(x, v, f);
}

void Stepper::assemble(const Model& model, const VecX& x, const VecX& v, double a, double b,
                       const VecX* w, VecX* dfdx_w, const std::vector<Vec3>* damping_axes,
                       bool linearized) {
  assembleSprings(model, x, v, a, b, w, dfdx_w, damping_axes);
  if (repulsion_) repulsion_->addToSystem(x, v, a, b, linearized, A_, f_, w, dfdx_w);
}

void Stepper::assembleSprings(const Model& model, const VecX& x, const VecX& v, double a,
                              double b, const VecX* w, VecX* dfdx_w,
                              const std::vector<Vec3>* damping_axes) {
  assembleSystem(model, x, v, a, b, settings_.project_compression && !exact_hessian_, A_, f_, w,
                 dfdx_w, damping_axes, false, settings_.threads);
  // CG's relaxed float products (linear_solver.cpp) only without contact:
  // sound there too (the answer meets the tolerance), but another answer
  // within it took the contact hard case c4 (a cloth stiffened on a table,
  // stretch 1e4, dt 0.1, bdf2) from 22 rejected sub-steps to a failure on
  // energy after 8 halvings, as holding bdf2's damping axes did (session 36).
  if (contact_on_) A_.setPsdCouplingBound(INFINITY);
}

void Stepper::setPins(const Model& model, const PinnedEnds& pins) {
  filter_.reset(model.numNodes());
  for (size_t k = 0; k < pins.nodes.size(); ++k) {
    const Vec3 n = pins.direction(k);
    if (n.squaredNorm() > 0.0) {
      filter_.project(pins.nodes[k], Mat3::Identity() - n * n.transpose());
    } else {
      filter_.eliminate(pins.nodes[k]);
    }
  }
  if (!pins.pairs.empty()) filter_.holdPairs(pins.pairs);
  pins_ = &pins;
  cg_.grid_rows = model.rows;
  cg_.grid_cols = model.cols;
  cg_.reroute_bends = true;
  cg_.multigrid_max_solves = settings_.multigrid_reuse;
  cg_.threads = settings_.threads;
  A_.setThreads(settings_.threads);
}

StepStats Stepper::step(const Model& model, double h, const PinnedEnds& pins,
                        const History& history, VecX& x, VecX& v, std::optional<Method> as,
                        const CollidersOverStep& colliders) {
  const auto start = Clock::now();
  start_assembly_.valid = false;  // the model may have changed since the last step
  setPins(model, pins);
  preconditioner_ = auto_.choose(settings_.preconditioner, model, h, !colliders.empty());
  if (multigrid_stall_backoff_ > 0 && preconditioner_ == Preconditioner::Multigrid) {
    --multigrid_stall_backoff_;
    preconditioner_ = Preconditioner::Cholesky;  // the V-cycle stalled lately (solveLinear)
  }
  // A factor where the matrix is near its block diagonal (the masses; kappa
  // <= kMassDominatedKappa) costs more than it saves: block Jacobi first
  // there (solveLinear).
  if (mass_dominated_backoff_ > 0) --mass_dominated_backoff_;
  mass_dominated_ = preconditioner_ == Preconditioner::Cholesky && mass_dominated_backoff_ == 0 &&
                    autoStiffness(model, h) <= kMassDominatedKappa;
  const Method method = as.value_or(settings_.method);
  method_ = method;
  contact_on_ = !colliders.empty();
  v_pass_.resize(0);
  StepStats stats;
  if (!contact_on_) {
    contact_.clear();
    first_pass_ = true;
    stats = runMethod(model, h, history, x, v, method);
  } else {
    x0_ = x;
    v0_ = v;
    // Passes whose contact set may still change are solved only
    // kExploringIterations Newton iterations: their answers only tell which
    // contacts to add or let go. Once a pass finds its set consistent, it is
    // solved to the tolerance (warm) and checked again. Solved to the
    // tolerance at every pass, the heap (self hard case s1) under newton
    // took 74 Newton iterations a step over 9 passes, 34 with exploring
    // passes (5.7 -> 2.7 s for 1 s); the cloth dragged over a table's edge
    // (c3) 0.68 -> 0.49 s. Not in implicit_euler's refined steps, which stop
    // on a decrement or the energy check.
    const bool explore = (method == Method::Newton || method == Method::Bdf2) &&
                         settings_.newton_max_iterations > kExploringIterations &&
                         decrement_stop_ == 0.0 && !energy_stop_;
    if (explore) contact_.keepStart();
    bool explored = false;
    stats = contactPasses(model, h, history, x, v, method, colliders, explore, &explored);
    if (explored && (!stats.ok || !stats.newton_converged)) {
      // Newton stalled from the warm start an exploring pass left (smoothed
      // friction of 1e-3 m/s on the stiffened cloth, c4: 20 iterations at
      // 3.5 % of ||g0||), or a pass failed: the step again with every pass
      // to the tolerance, as it was solved before exploring passes.
      const StepStats first_try = stats;
      contact_.backToStart();
      x = x0_;
      v = v0_;
      v_pass_.resize(0);
      setPins(model, pins);
      stats = contactPasses(model, h, history, x, v, method, colliders, false, &explored);
      stats.addWork(first_try);
    }
  }
  // implicit_euler's last pass over x and v checked them (finite_known_);
  // contact passes may move them after.
  stats.finite = finite_known_ && !contact_on_ ? finite_ : allFinite(x) && allFinite(v);
  if (!stats.finite) {
    stats.ok = false;
    stats.failure = "non-finite position or velocity";
  }
  stats.wall_time_s = secondsSince(start);
  return stats;
}

StepStats Stepper::contactPasses(const Model& model, double h, const History& history, VecX& x,
                                 VecX& v, Method method, const CollidersOverStep& colliders,
                                 bool explore, bool* explored) {
  StepStats stats;
  contact_.setGrid(model.rows, model.cols);
  contact_.begin(colliders, filter_, x, v, model.gravity, h);
  long queries = contact_.lastQueries();
  bool exploring = explore;
  *explored = false;
  for (int pass = 1;; ++pass) {
    pass_cap_ = exploring ? kExploringIterations : 0;
    if (pass > 1) {
      v_pass_.swap(v);  // v is reset below: no copy
      // The pass after the step turned smoothed starts from the predictor,
      // not from the sticking answer: at its zero slip the drag is 2 / eps,
      // and one Newton iteration there stopped a particle landing at 1 m/s
      // (0.013 m/s after the step where Coulomb leaves 0.96).
      if (contact_.lastChanges().smoothed) v_pass_.resize(0);
      x = x0_;
      v = v0_;
      setPins(model, *pins_);
    }
    contact_.constrain(filter_);
    first_pass_ = pass == 1;
    const StepStats part = runMethod(model, h, history, x, v, method);
    if (pass == 1) {
      stats = part;
    } else {
      stats.addWork(part);  // its contact passes and queries: set below
      stats.residual = std::max(stats.residual, part.residual);
      stats.newton_residual = part.newton_residual;
      stats.linear_converged = part.linear_converged;
      stats.newton_converged = part.newton_converged;
      stats.ok = part.ok;
      stats.failure = part.failure;
    }
    stats.contact_passes = pass;
    *explored = *explored || (exploring && !part.newton_converged);
    if (!stats.ok || !allFinite(x) || !allFinite(v)) break;
    const ContactCheck check =
        contact_.update(colliders, filter_, model.mass, x0_, x, v, reaction_, bh_, model.gravity,
                        settings_.tolerance);
    queries += contact_.lastQueries();
    if (check == ContactCheck::Consistent) {
      if (!exploring || part.newton_converged) break;
      exploring = false;  // the set holds: now solve it to the tolerance
      continue;
    }
    if (check == ContactCheck::Failed) {
      stats.ok = false;
      stats.failure = contact_.failure();
      break;
    }
    if (pass >= ContactSet::kMaxPasses) {
      if (exploring) {  // a last pass to the tolerance
        exploring = false;
        continue;
      }
      stats.ok = false;
      stats.failure = "contact set did not settle in " + std::to_string(pass) + " passes";
      break;
    }
  }
  pass_cap_ = 0;
  stats.contact_queries = queries;
  if (stats.ok) {
    stats.contacts = contact_.numContacts();
    stats.contact_normal_force = contact_.normalForce();
    stats.max_penetration = contact_.maxPenetration();
    stats.contact_work = contact_.work(x0_, x, reaction_, bh_);
  }
  return stats;
}

StepStats Stepper::runMethod(const Model& model, double h, const History& history, VecX& x,
                             VecX& v, Method method) {
  StepStats stats;
  finite_known_ = method == Method::ImplicitEuler;  // its advance() checks
  axes_held_ = false;  // newtonSolve holds them where it should
  linearized_ = false;  // implicitEuler sets it where its reaction is A dv - rhs
  switch (method) {
    case Method::ImplicitEuler: {
      const bool repulsed = repulsion_ && !repulsion_->empty();
      if (repulsed) x_repulsed_ = x, v_repulsed_ = v;
      stats = implicitEuler(model, h, x, v);
      // The linearized repulsion's active set: solved again while the
      // answer changes it, at most twice (the filter is the fail-safe).
      for (int again = 0; again < 2 && repulsed && stats.ok && repulsion_->updateActiveSet(x) > 0;
           ++again) {
        x = x_repulsed_, v = v_repulsed_;
        const bool first = first_pass_;
        first_pass_ = false;  // warm start from this answer
        StepStats more = implicitEuler(model, h, x, v);
        first_pass_ = first;
        more.addWork(stats);  // the earlier solves' iterations and time
        stats = more;
      }
      break;
    }
    case Method::Newton:
      stats = newtonSolve(model, h, 1.0, x, v,
                          iteration_cap_ > 0 ? iteration_cap_ : settings_.newton_max_iterations,
                          x, v);
      break;
    case Method::Bdf2:
      stats = bdf2(model, h, history, x, v);
      break;
    case Method::SymplecticEuler:
      stats = symplecticEuler(model, h, x, v);
      break;
  }
  return stats;
}

StepStats Stepper::bdf2(const Model& model, double h, const History& history, VecX& x,
                        VecX& v) {
  const int max_it = settings_.newton_max_iterations;
  if (history.x_prev && history.v_prev && history.h_prev == h) {
    ax_ = (4.0 * x - *history.x_prev) / 3.0;
    av_ = (4.0 * v - *history.v_prev) / 3.0;
    return newtonSolve(model, h, 2.0 / 3.0, ax_, av_, max_it, x, v);
  }
  if (history.x_prev && history.v_prev && settings_.error_tolerance && history.h_prev > 0.0) {
    // Variable-step BDF2 (error-controlled stepping changes h): with
    // w = h / h_prev, x1 = [(1+w)^2 x0 - w^2 x_prev] / (1+2w) + (1+w)/(1+2w) h v1.
    // Zero-stable for w < 1 + sqrt(2); StepSizeControl grows by at most 2.
    const double w = h / history.h_prev;
    const double c0 = (1.0 + w) * (1.0 + w) / (1.0 + 2.0 * w), c1 = w * w / (1.0 + 2.0 * w);
    ax_ = c0 * x - c1 * *history.x_prev;
    av_ = c0 * v - c1 * *history.v_prev;
    return newtonSolve(model, h, (1.0 + w) / (1.0 + 2.0 * w), ax_, av_, max_it, x, v);
  }
  // Trapezoidal rule: x1 = x + h/2 (v + v1), M v1 = M v + h/2 (f(x, v) + f(x1, v1)).
  forces(model, x, v, f_);
  ax_ = x + 0.5 * h * v;
  av_ = v;
  for (int i = 0; i < model.numNodes(); ++i) {
    av_.segment<3>(3 * i) += (0.5 * h / model.mass[i]) * f_.segment<3>(3 * i);
  }
  return newtonSolve(model, h, 0.5, ax_, av_, max_it, x, v);
}


double Stepper::residual(const Model& model, double bh, const VecX& ax, const VecX& av,
                         const VecX& v1, VecX& x1, VecX& g) {
  x1 = ax + bh * v1;
  forces(model, x1, v1, f_, dampingAxes());
  return residualFromForces(model, bh, av, v1, f_, g);
}

double Stepper::residualFromForces(const Model& model, double bh, const VecX& av,
                                   const VecX& v1, const VecX& f, VecX& g) const {
  g.resize(v1.size());
  for (int i = 0; i < model.numNodes(); ++i) {
    g.segment<3>(3 * i) = model.mass[i] * (v1.segment<3>(3 * i) - av.segment<3>(3 * i)) -
                          bh * f.segment<3>(3 * i);
  }
  if (contact_on_) contact_.addFriction(g, -bh, v1);
  filter_.apply(g);
  return g.norm();
}

StepStats Stepper::newtonSolve(const Model& model, double h, double beta, const VecX& ax_in,
                               const VecX& av_in, int max_iterations, VecX& x, VecX& v) {
  if (pass_cap_ > 0) max_iterations = std::min(max_iterations, pass_cap_);
  StepStats stats;
  const double bh = beta * h;
  // ax/av may alias x/v: keep copies, x and v are the outputs.
  if (&ax_in != &ax_) ax_ = ax_in;
  if (&av_in != &av_) av_ = av_in;
  bh_ = bh;
  VecX& v1 = v;
  // A later contact pass starts from the last pass's answer: the contact set
  // changed at a few nodes, the answer little (its constrained parts are set
  // below), and Newton takes one or two iterations instead of all again.
  // implicit_euler's refined steps too, whose Newton stops on a decrement or
  // the energy check: started cold at every pass, the fold demo's laying took
  // 9-16 Newton iterations a step over its 3 passes (14 ms a step, 6.5 warm).
  // (Kept cold once because contact hard case c4 stopped before its stiffened
  // cloth's strain had relaxed; on today's code c4 passes warm with the same
  // max strain, 0.0209, and 96 rejected sub-steps where 163.)
  const bool warm = v_pass_.size() == av_.size();
  v1 = warm ? v_pass_ : av_;
  for (size_t k = 0; k < pins_->nodes.size(); ++k) {  // pins end on their targets
    const int p = pins_->nodes[k];
    if (yieldsToContact(k)) continue;
    const Vec3 w = (pins_->targets[k] - ax_.segment<3>(3 * p)) / bh;
    const Vec3 n = pins_->direction(k);
    if (n.squaredNorm() > 0.0) {
      v1.segment<3>(3 * p) += n * n.dot(w - Vec3(v1.segment<3>(3 * p)));
    } else {
      v1.segment<3>(3 * p) = w;
    }
  }
  if (contact_on_) {
    contact_.prescribe(ax_, bh, v1);
    // One iteration (a linearly implicit newton or bdf2 step) takes the
    // descent's drag too: with f1' (0 beyond eps) its one solve holds a
    // slide's friction constant, and a node that stops within the step is
    // pushed back (drop64 under bdf2: 100 steps gained energy in 3 s,
    // 482 CG iterations a step; with the drag none, 115; docs/design.md).
    contact_.setFrictionSolve(decrement_stop_ > 0.0 || energy_stop_ || max_iterations == 1
                                  ? ContactSet::FrictionSolve::Descent
                                  : ContactSet::FrictionSolve::Newton);
  }
  // Held pairs end at their gaps (after the contacts: the change keeps to
  // the directions each node may move in).
  if (filter_.holdsPairs()) filter_.pairs().meet(ax_, bh, v1);
  v_start_ = v1;
  // Every iterate's forces come from one evaluation: the assembly gives f at
  // the start, the line search's accepted trial the g of the next iterate.
  auto t0 = Clock::now();
  // Along-spring damping's axes, held over a backward-Euler solve to the
  // tolerance at the step start's (x is still x0 here; ax may alias it): see
  // the header. The newton method's steps, and bdf2's steps retried as
  // backward Euler: with the turning axis, Newton missed 1e-8 in 50
  // iterations on stiff springs a pin jump turned (hard case 07a under bdf2:
  // 20 rejected sub-steps, 10 with the axes held, 6 with stepWithRecovery's
  // retry of unconverged steps too). Not implicit_euler's refined steps (a
  // decrement stop; accepted on energy), and bdf2's only in a scene without
  // colliders and self-collision (bdf2_holds): with self-collision the heap
  // (hard case s1) reached 10.8 % strain where 5 %; with colliders the
  // stiffened cloth on a table (c4 at stretch 1e4, dt 0.1, a stability map
  // run) failed its stiffening step on energy after 8 halvings, where it had
  // recovered in 5.
  const bool bdf2_holds = bdf2HoldsAxes(contact_on_);
  const bool backward_euler_to_tolerance =
      method_ == Method::Newton && beta == 1.0 && decrement_stop_ == 0.0 &&
      (settings_.method == Method::Newton || bdf2_holds);
  // bdf2's own steps (and its trapezoidal start) hold theirs at the step's
  // predictor ax + b h av instead, which is x1 to O(h^2): the damping's axis
  // is then off by O(h^2) and BDF2 stays second order (the demo cloth at
  // 12x12, dt 1/60..1/480 against 1/3840: errors within 5 % of the turning
  // axes', slopes 1.4, 1.6, 1.8 both). Held, its Newton solves the
  // minimisation of a potential, and the exact local phase below converges
  // quadratically (hard case 05a: 2335 -> 640 Newton iterations, 05b 4648 ->
  // 2051). Only where bdf2_holds: with colliders it also cut c3's 8502 ->
  // 3667, but the map run above failed; with self-collision the heap (s1)
  // rejected 517 sub-steps where 26.
  const bool bdf2_to_tolerance = method_ == Method::Bdf2 && decrement_stop_ == 0.0 &&
                                 !energy_stop_ && bdf2_holds;
  axes_held_ = model.damping_model == DampingModel::AlongSpring && hasSpringDamping(model) &&
               (backward_euler_to_tolerance || bdf2_to_tolerance);
  if (bdf2_to_tolerance) x = ax_ + bh * av_;  // the predictor (ax_ keeps the start)
  if (axes_held_) springAxes(model, x, damping_axes_);
  x = ax_ + bh * v1;
  // Projected Newton converges only linearly where springs stay compressed
  // (a scattered start: 16 iterations a step). Once an iteration has taken
  // a full step that halved ||g|| (the local phase), the iterates use the
  // exact Hessian, which converges quadratically wherever the whole matrix
  // is still positive definite (tension elsewhere outweighs the compressed
  // springs' negative transverse terms); at the first sign that it is not
  // (CG meets negative curvature or stops short, no descent) or that its
  // model does not hold (a cut step, ||g|| not halved) the rest of the
  // solve goes back to the projected one. Only for backward Euler and bdf2
  // solved to the tolerance: with their damping axes held, the exact matrix
  // is the Hessian of the potential the line search descends (with turning
  // axes, bdf2 gained energy with it and retried steps: self hard case s2,
  // 16 -> 118-162 rejected). implicit_euler's refinement stops on a
  // decrement, not a tolerance. With self-collision too (since session 45):
  // kept projected there once because the heap (hard case s1) found answers
  // strained 11-12 % at its impact where 5 %; on today's code the heap's
  // strain over 16 seeds is the same either way (mean 0.059, largest 0.100
  // against 0.094), and the newton method's self cases take a third of the
  // iterations (the twist, s4: 35.6 -> 10.7 a step, 3.0 -> 1.2 s; the
  // fling, s3: 13.2 -> 5.7, 102 -> 8 rejected attempts).
  bool exact_allowed = settings_.project_compression &&
                       (backward_euler_to_tolerance || bdf2_to_tolerance) &&
                       max_iterations > 1 && !energy_stop_;
  exact_hessian_ = false;
  auto assembleIterate = [&] {
    assemble(model, x, v1, bh, bh * bh, nullptr, nullptr, dampingAxes(), false);
    if (contact_on_) contact_.addFrictionJacobian(A_, bh, v1);
  };
  assembleIterate();
  bool forces_at_v1 = true;  // f_ is f(x, v1): the reaction below reuses it
  const double g0 = residualFromForces(model, bh, av_, v1, f_, g_);
  double g_norm = g0;
  stats.assembly_s += secondsSince(t0);
  // A later pass starts where the last one ended: its ||g|| is what the
  // changed contacts left, and its tolerances stay relative to the first
  // pass's ||g||, the step's. Relative to that remnant, a second pass of a
  // linearized step on the floor scene took 60 CG iterations where the first
  // took 28, and a Newton solve took as many iterations at every pass as at
  // the first (projected Newton converges linearly: ~9 a pass in the heap,
  // self hard case s1). (Newton's later passes once kept their own scale,
  // when the stiffened cloth on a table, c4, took 2x the time and 3x the
  // strain with the first pass's; on session 43's code c4 under newton took
  // the same time with either, 2.9 s, within its strain bound.)
  const bool again = warm && max_iterations == 1;
  if (!warm) pass_g0_ = g0;
  const double scale = warm ? std::max(g0, pass_g0_) : g0;
  // ||g|| is only known to the round-off of its terms (M v, and b h f with an
  // error of about eps k L per spring): at rest g0 itself is round-off, and a
  // target relative to it alone could never be met.
  const double target =
      std::max(settings_.newton_tolerance * scale, residualRoundOff(model, bh, av_));
  stats.linear_converged = true;
  int it = 0;
  bool decrement_reached = false;
  double eta = kMaxForcing, g_solved = g_norm;  // forcing term, ||g|| of the last solve
  while (g_norm > target && it < max_iterations && std::isfinite(g_norm)) {
    if (it > 0) {  // the first iterate was assembled above
      t0 = Clock::now();
      assembleIterate();
      forces_at_v1 = true;
      stats.assembly_s += secondsSince(t0);
    }
    t0 = Clock::now();
    rhs_ = -g_;
    // The first correction starts from the last step's first correction (it
    // changes little from step to step; implicit_euler's dv_ does the same):
    // ~35% fewer CG iterations on the hanging cloth. With block Jacobi or
    // none, from the last first corrections at this b h recycled, as
    // implicit_euler does (recycled_start.hpp; the floor scene 27.7 -> 21.8
    // CG iterations a one-pass step extrapolating the last two, 24.9 ->
    // 22.2 recycling six). Not with multigrid, whose V-cycle takes that
    // smooth error out anyway (hang32 3.2 -> 3.6 iterations a step with the
    // extrapolation). Later ones from zero.
    const bool recycle = it == 0 && !again &&
                         (preconditioner_ == Preconditioner::BlockJacobi ||
                          preconditioner_ == Preconditioner::None);
    if (recycle) newton_recycled_.useFor(bh);
    if (it == 0 && !again && delta_first_.size() == v1.size()) {
      if (!recycle || !newton_recycled_.guess(rhs_, &delta_)) delta_ = delta_first_;
    } else {
      delta_.setZero(v1.size());
    }
    // Inexact Newton (Eisenstat & Walker 1996, their choice 2): far from the
    // answer a loose linear solve serves as well as a tight one, so the CG
    // tolerance follows ||g||'s convergence, eta = 0.9 (||g_k|| / ||g_k-1||)^2,
    // between solver.tolerance and kMaxForcing. Not with one iteration (its
    // solve is the step's answer), not in implicit_euler's refinement (its
    // decrement stop needs an accurate direction), and only where CG
    // iterations are the cost (block Jacobi, none): a Cholesky factor or a
    // multigrid hierarchy costs the same at any tolerance, and the extra
    // Newton iterations a loose solve brings each pay for a new one (falling
    // 20x20, stretch 1e8, bdf2: 5.4 -> 10.6 s with it).
    double cg_tolerance = settings_.tolerance;
    if (max_iterations > 1 && !energy_stop_ && decrement_stop_ == 0.0 &&
        (preconditioner_ == Preconditioner::BlockJacobi ||
         preconditioner_ == Preconditioner::None)) {
      if (it > 0) {
        const double ratio = g_norm / g_solved;
        double next = 0.9 * ratio * ratio;
        if (0.9 * eta * eta > 0.1) next = std::max(next, 0.9 * eta * eta);
        eta = std::min(kMaxForcing, next);
      }
      cg_tolerance = std::clamp(eta, settings_.tolerance, kMaxForcing);
    }
    // The first solve of a later pass: to the step's tolerance of the first
    // pass's ||g||. Not in implicit_euler's refined steps (one iteration
    // when its scene asks one, Simulation::refine), whose decrement stop
    // needs an accurate direction.
    const bool rescaled = it == 0 && again && decrement_stop_ == 0.0 && !energy_stop_;
    if (rescaled) {
      cg_tolerance =
          std::max(cg_tolerance, std::min(kMaxForcing, settings_.tolerance * scale / g_norm));
    }
    g_solved = g_norm;
    CgResult cg = solveLinear(model, rhs_, delta_, cg_tolerance);
    if (exact_hessian_ && (!cg.converged || !(g_.dot(delta_) < 0.0))) {
      // Not positive definite here (or CG could not tell): projected again.
      stats.cg_iterations += cg.iterations;
      exact_hessian_ = exact_allowed = false;
      assembleIterate();
      delta_.setZero(v1.size());
      cg = solveLinear(model, rhs_, delta_, cg_tolerance);
    }
    if (recycle) newton_recycled_.record(delta_, rhs_);
    if (it == 0 && !again) delta_first_ = delta_;
    stats.solve_s += secondsSince(t0);
    stats.cg_iterations += cg.iterations;
    // A loose solve of inexact Newton is judged by ||g||, not by its residual.
    if (rescaled) {
      stats.residual = std::max(stats.residual, cg.relative_residual * g_norm / scale);
    } else if (cg_tolerance <= settings_.tolerance) {
      stats.residual = std::max(stats.residual, cg.relative_residual);
    }
    stats.linear_converged = stats.linear_converged && cg.converged;
    ++it;

    // Backtracking: accept the first step that lowers ||g|| or (Armijo) the
    // incremental potential, else keep the best ||g|| of 10 halvings. Far from
    // the solution ||g|| alone can stall: a flat stiff cloth under load grows
    // its spring forces with the square of the sag, so only tiny steps lower
    // ||g||, while the potential, which delta descends, lets Newton move.
    t0 = Clock::now();
    const double slope = g_.dot(delta_);  // d(potential)/d(alpha) at 0
    const bool last = -0.5 * slope <= decrement_stop_;  // nothing left worth a solve
    double phi = NAN;                     // potential at alpha = 0, when first needed
    double alpha = 1.0, best_norm = INFINITY;
    for (int ls = 0; ls < 10; ++ls, alpha *= 0.5) {
      v_trial_ = v1 + alpha * delta_;
      const double trial = residual(model, bh, ax_, av_, v_trial_, x_trial_, g_trial_);
      bool accept = trial <= (1.0 - 1e-4 * alpha) * g_norm;
      if (!accept && slope < 0.0 && std::isfinite(trial)) {
        if (std::isnan(phi)) phi = incrementalPotential(model, bh, av_, v1, x);
        accept = incrementalPotential(model, bh, av_, v_trial_, x_trial_) <= phi + 1e-4 * alpha * slope;
      }
      forces_at_v1 = accept || trial < best_norm;  // f_ is the trial's
      if (forces_at_v1) {  // keep the trial's state, not just its alpha
        best_norm = trial;
        v_best_.swap(v_trial_);
        x_best_.swap(x_trial_);
        g_best_.swap(g_trial_);
      }
      if (accept) break;
    }
    v1 = v_best_;
    x = x_best_;
    g_.swap(g_best_);
    // The quadratic model held (a full step, ||g|| halved): exact from here;
    // otherwise, in exact mode: projected for the rest of the solve.
    const bool model_held = alpha == 1.0 && best_norm <= 0.5 * g_norm;
    if (exact_hessian_ && !model_held) {
      exact_hessian_ = exact_allowed = false;
    } else if (exact_allowed && model_held) {
      exact_hessian_ = true;
    }
    g_norm = best_norm;
    stats.assembly_s += secondsSince(t0);
    if (last || (energy_stop_ && -0.5 * slope <= energy_stop_decrement_ && energy_stop_(x, v1))) {
      decrement_reached = true;
      break;
    }
  }
  exact_hessian_ = false;
  stats.newton_iterations = it;
  stats.newton_residual = scale > 0.0 ? g_norm / scale : 0.0;
  // One iteration is a linearly implicit step by choice (like implicit_euler,
  // plus the line search): no tolerance was asked of it. With more, the
  // tolerance holds and missing it at the cap is reported (and acted on).
  stats.newton_converged = g_norm <= target || max_iterations == 1 || decrement_reached;
  if (placePins(x)) forces_at_v1 = false;
  if (!(g_norm <= g0) && g0 > 0.0) {
    // Far from the solution the line search may take ||g|| up while it
    // takes the incremental potential down (a stiff cloth's first
    // iterations: ||g|| x1e3): that is progress, only short of tolerance.
    x_trial_ = ax_ + bh * v_start_;
    const bool descended = incrementalPotential(model, bh, av_, v1, x) <
                           incrementalPotential(model, bh, av_, v_start_, x_trial_);
    if (!descended || !std::isfinite(g_norm)) {
      stats.ok = false;
      stats.failure = "newton residual grew";
    }
  }
  if (contact_on_) {  // reaction = M (v1 - av) - b h f(x1, v1), friction left out
    if (!forces_at_v1) forces(model, x, v1, f_, dampingAxes());
    reaction_.resize(v1.size());
    for (int i = 0; i < model.numNodes(); ++i) {
      reaction_.segment<3>(3 * i) = model.mass[i] * (v1.segment<3>(3 * i) - av_.segment<3>(3 * i)) -
                                    bh * f_.segment<3>(3 * i);
    }
    bh_ = bh;
  }
  return stats;
}

void Stepper::constraintImpulses(const Model& model, const VecX& x1, const VecX& v1, VecX* out) {
  if (linearized_) {
    *out = reaction_;
    return;
  }
  forces(model, x1, v1, f_, dampingAxes());
  out->resize(v1.size());
  for (int i = 0; i < model.numNodes(); ++i) {
    out->segment<3>(3 * i) = model.mass[i] * (v1.segment<3>(3 * i) - av_.segment<3>(3 * i)) -
                             bh_ * f_.segment<3>(3 * i);
  }
}

double Stepper::incrementalPotential(const Model& model, double bh, const VecX& av,
                                     const VecX& v1, const VecX& x1) const {
  double phi = elasticEnergy(model, x1) + gravityEnergy(model, x1);
  double dissipation = 0.5 * model.air_drag * v1.squaredNorm();
  const bool along = model.damping_model == DampingModel::AlongSpring;
  for (size_t k = 0; k < model.springs.size(); ++k) {
    const Spring& s = model.springs[k];
    const double c = model.groups[static_cast<int>(s.type)].damping;
    if (c == 0.0) continue;
    const Vec3 dv = v1.segment<3>(3 * s.j) - v1.segment<3>(3 * s.i);
    if (!along) {
      dissipation += 0.5 * c * dv.squaredNorm();
      continue;
    }
    Vec3 u;
    if (axes_held_) {
      u = damping_axes_[k];
    } else {
      const Vec3 d = x1.segment<3>(3 * s.j) - x1.segment<3>(3 * s.i);
      u = springDirection(d, d.norm(), s.rest_length, s.rest_direction);
    }
    const double along_dv = dv.dot(u);
    dissipation += 0.5 * c * along_dv * along_dv;
  }
  for (int i = 0; i < model.numNodes(); ++i) {
    phi += 0.5 * model.mass[i] * (v1.segment<3>(3 * i) - av.segment<3>(3 * i)).squaredNorm();
  }
  if (contact_on_) phi += bh * contact_.frictionPotential(v1);  // friction's dissipation
  if (repulsion_) phi += repulsion_->energy(x1) + bh * repulsion_->frictionPotential(v1);
  return phi + bh * dissipation;
}

StepStats Stepper::symplecticEuler(const Model& model, double h, VecX& x, VecX& v) {
  StepStats stats;
  auto t0 = Clock::now();
  computeForces(model, x, v, f_, nullptr, settings_.threads);
  for (int i = 0; i < model.numNodes(); ++i) {
    if (!filter_.isEliminated(i)) v.segment<3>(3 * i) += (h / model.mass[i]) * f_.segment<3>(3 * i);
  }
  for (size_t k = 0; k < pins_->nodes.size(); ++k) {
    const int p = pins_->nodes[k];
    v.segment<3>(3 * p) = (pins_->targets[k] - x.segment<3>(3 * p)) / h;
  }
  x += h * v;
  for (size_t k = 0; k < pins_->nodes.size(); ++k) {
    x.segment<3>(3 * pins_->nodes[k]) = pins_->targets[k];
  }
  stats.assembly_s = secondsSince(t0);
  return stats;
}

bool Stepper::yieldsToContact(size_t k) const {
  return contact_on_ && contact_.holds(pins_->nodes[k]) && pins_->direction(k).squaredNorm() > 0.0;
}

bool Stepper::placePins(VecX& x) const {
  bool moved = false;
  for (size_t k = 0; k < pins_->nodes.size(); ++k) {  // exactly on target
    if (yieldsToContact(k)) continue;
    const int p = pins_->nodes[k];
    const Vec3 n = pins_->direction(k);
    const Vec3 gap = pins_->targets[k] - x.segment<3>(3 * p);
    const Vec3 shift = n.squaredNorm() > 0.0 ? Vec3(n * n.dot(gap)) : gap;
    moved = moved || shift.squaredNorm() > 0.0;
    x.segment<3>(3 * p) += shift;
  }
  return moved;
}

}  // namespace cloth_sim
