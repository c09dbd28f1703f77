// Simulation::stepWithRecovery: what happens when a step is not accepted.
// An implicit_euler step that would gain energy is solved on by Newton towards
// the backward-Euler answer, a bdf2 one retried as backward Euler, both at the
// same size; only then is the step split in halves (docs/design.md, "Accepting
// a step").
#include <algorithm>
#include <limits>
#include <string>

#include "cloth_sim/simulation.hpp"
#include "step_failure_text.hpp"

namespace cloth_sim {

namespace {
/// A refined step's Newton stops once its next full step would lower the
/// incremental potential by at most this fraction of the energy scale: what
/// is left is below what the energy check resolves (kEnergyGainTolerance).
/// On a falling 20x20 cloth of stretch 1e7 at dt 1/60: 10 Newton iterations
/// a step instead of 17, positions after 3 s within 1.3 cm of running on.
constexpr double kRefineDecrement = 1e-6;
/// Newton iterations a refined step gets while pins drift (see refine).
constexpr int kMovingPinIterations = 4;
/// Newton iterations a refined step of a linearly implicit bdf2 or newton
/// (newton_max_iterations 1) gets: implicit_euler's default.
constexpr int kLinearlyImplicitRefineIterations = 20;
/// Steps refined at once, after a linearized step was refined with more than
/// one Newton iteration, before the linearized step is tried again; each
/// failed try doubles the wait, up to kMaxRefineInterval (a stiff cloth whose
/// linearized steps always fail pays one wasted linear solve in 32 steps).
constexpr int kFirstRefineInterval = 2;
constexpr int kMaxRefineInterval = 32;
/// Nodes slower than this (m/s) are near rest: there the linearized step is
/// tried again after refined ones (stepWithRecovery).
constexpr double kRestSpeed = 0.05;
}  // namespace

void Simulation::accumulate(const StepStats& part, StepStats* total) const {
  total->addWork(part);
  total->residual = std::max(total->residual, part.residual);
  total->newton_residual = std::max(total->newton_residual, part.newton_residual);
  total->linear_converged = total->linear_converged && part.linear_converged;
  total->newton_converged = total->newton_converged && part.newton_converged;
  total->work_in += part.work_in;
  total->energy_round_off += part.energy_round_off;
  total->substeps += part.substeps;
  total->rejected += part.rejected;
  total->error_rejected += part.error_rejected;
  total->error_per_time = std::max(total->error_per_time, part.error_per_time);
  total->h_min = smallerStep(total->h_min, part.h_min);
  total->h_max = std::max(total->h_max, part.h_max);
  total->halvings = std::max(total->halvings, part.halvings);
  total->linearized += part.linearized;
  total->order_reduced += part.order_reduced;
  total->refined += part.refined;
  total->contact_work += part.contact_work;
  // The contact figures of the last sub-step are those at the end of the step.
  total->contacts = part.contacts;
  total->contact_normal_force = part.contact_normal_force;
  total->max_penetration = std::max(total->max_penetration, part.max_penetration);
  total->self_contacts = part.self_contacts;
  total->min_self_distance = std::min(total->min_self_distance, part.min_self_distance);
  total->ok = total->ok && part.ok;
  if (!part.failure.empty()) total->failure = part.failure;
}

bool Simulation::pinsJump() const {
  for (const auto& [node, pin] : pins_) {
    if (pin.position != x_.segment<3>(3 * node)) return true;
  }
  return false;
}

bool Simulation::nearRest() const {
  const double limit = kRestSpeed * kRestSpeed;
  for (int i = 0; i < model_.numNodes(); ++i) {
    if (v_.segment<3>(3 * i).squaredNorm() > limit) return false;
  }
  return true;
}

bool Simulation::pinsDrift() const {
  for (const auto& [node, pin] : pins_) {
    if (pin.velocity_until > t_) return true;
  }
  return false;
}

StepStats Simulation::refine(double h, bool can_split) {
  stepper_.setDecrementStop(kRefineDecrement * energyScale());
  // With pins drifting, Newton gets kMovingPinIterations: a gripper
  // dragging the demo fast took it 20 a step and the flooded node fell to
  // 53 of 60 Hz; a step not right by then is split, as before.
  int iterations = scene_.solver.newton_max_iterations;
  if (scene_.solver.method != Method::ImplicitEuler && iterations == 1) {
    iterations = kLinearlyImplicitRefineIterations;  // one iteration is what failed
  }
  if (pinsDrift()) iterations = std::min(iterations, kMovingPinIterations);
  stepper_.setIterationCap(iterations);
  refining_ = true;
  StepStats s = attempt(h, can_split, false, Method::Newton);
  refining_ = false;
  stepper_.setIterationCap(0);
  stepper_.setDecrementStop(0.0);
  if (s.ok) {
    s.refined = 1;
    // implicit_euler promises no Newton tolerance (see stepWithRecovery).
    s.newton_converged = true;
    s.failure.clear();
    refine_next_ = s.newton_iterations > 1;
  }
  return s;
}

StepStats Simulation::stepHoldingSizes(double h) {
  // A step starts split down to twice the last accepted sub-step: one level
  // coarser a step (stepWithRecovery).
  split_above_ = scene_.solver.method == Method::SymplecticEuler
                     ? std::numeric_limits<double>::infinity()
                     : 2.0 * accepted_h_;
  sizes_held_ = false;
  StepStats stats = stepWithRecovery(h, 0);
  if (stats.ok || !scene_.solver.recovery || !checkpoint_.saved || !sizes_held_) return stats;
  // The sizes held from earlier sub-steps did not do (a 5 m/s grab after
  // sub-steps of dt/128: the fling, s3, at dt 0.1 under newton, failed on
  // energy where trying each half whole passed): the step again from its
  // start, every size tried as before. Its rolled-back sub-steps count as
  // rejected attempts.
  restoreCheckpoint();
  hold_sizes_ = false;
  split_above_ = std::numeric_limits<double>::infinity();
  StepStats again = stepWithRecovery(h, 0);
  hold_sizes_ = true;
  again.addWork(stats);
  again.rejected += stats.rejected + stats.substeps;
  return again;
}

StepStats Simulation::splitInHalves(double h, int depth) {
  if (!checkpoint_.saved) saveCheckpoint();
  StepStats total;
  total.substeps = 0;
  total.halvings = depth + 1;
  for (int half = 0; half < 2; ++half) {
    const StepStats part = stepWithRecovery(0.5 * h, depth + 1);
    accumulate(part, &total);
    if (!part.ok) return total;
  }
  return total;
}

StepStats Simulation::stepWithRecovery(double h, int depth) {
  const bool can_split = scene_.solver.recovery && depth < scene_.solver.max_halvings;
  // No attempt longer than the sub-steps this step has needed so far, nor at
  // a step's start than twice the last step's last sub-step: an attempt
  // that fails costs as much as the sub-steps it would have saved,
  // or more (Newton at its iteration cap), and before, every sub-step of a
  // step that needed k halvings was preceded by a failed attempt at each
  // coarser level of its half, 2^k - 1 of them (the twist, s4, at dt 0.1
  // under newton: 111 rejected attempts for 117 sub-steps in 0.6 s, 2.8 s;
  // now 9 for 141, 0.31 s). Never coarser within a step: growing back after
  // a few accepted sub-steps cost rejections again (4 in a row: the twist
  // 21 rejected, 0.52 s; the fling, s3, under bdf2 46, 1.3 s against 36,
  // 0.87 s), and one level a step recovers from a brief hard spell (the
  // collapsed start, 05b: 506 sub-steps where 42 in its first 0.6 s, for the
  // same time, 0.56 s against 0.52). Not for symplectic_euler, whose
  // energy check only catches a blow-up: held at a size once accepted, hard
  // case 02 grew unstable where trying the whole step each time passes.
  if (can_split && h > split_above_) {
    sizes_held_ = true;
    return splitInHalves(h, depth);
  }
  // At the deepest halving Newton must still converge: where it cannot (a
  // singular start, e.g. zero-length springs, makes the implicit equation
  // scale-free, so halving does not help) the sub-step is taken as one
  // linearized backward-Euler step, whose linear solve is checked as usual.
  // With colliders at every depth, before a halving: there each contact pass
  // is a Newton solve of its own, and a stiff cloth whose contact set keeps
  // changing (nodes released for pulling, added again for penetrating) misses
  // the tolerance at every depth alike (a cloth on a table stiffened from 10
  // to 1e8 N/m, dt 0.1 under bdf2: residuals of 1e-4 to 1e-7 of the initial
  // after 100-275 iterations over 10-12 passes, from dt down to dt/256, and the
  // run failed there on energy; taken at once, it passes with one halving).
  // Such a step is already held to the looser energy allowance of lagged
  // friction, and the linearized step to the same energy check.
  const bool iterative = scene_.solver.method == Method::Newton ||
                         scene_.solver.method == Method::Bdf2;
  const bool fallback = scene_.solver.recovery && iterative && (!can_split || !colliders_.empty());
  const bool reject_newton = can_split || fallback;
  const bool bdf2_step = scene_.solver.method == Method::Bdf2;
  const bool implicit_euler = scene_.solver.method == Method::ImplicitEuler;
  const bool sticky = implicit_euler && refine_next_ && !pinsJump();
  if (sticky && (refine_skip_ > 0 || pinsDrift() || !nearRest())) {
    // The last step's linearized answer gained energy and Newton needed more
    // than one iteration: this one very likely does too (a stiff cloth),
    // so it goes to Newton at once (a third of a stiff demo step's solves).
    // Not for ever: after refine_skip_ such steps the linearized step is
    // tried again, after twice as many if it fails again (at most
    // kMaxRefineInterval). Where it passes, the cloth is back to linearized
    // steps: the fold demo at rest, after the laying's refined steps, spent
    // 4.3 ms a step refining (Newton needs two iterations to stop at rest)
    // where a linearized step passes in 3.3. Only near rest: in motion the
    // refined steps are the more accurate (pins dragged at 10 m/s, hard
    // case 07b: strain 2.3 % with linearized steps that passed the energy
    // check, below 2 % refined; a flung folded cloth, hard case s3 at dt
    // 0.004: its layers stayed 8.8 mm apart where refined steps and dt / 4
    // bring them within 1.2 and 1.0 mm).
    if (refine_skip_ > 0) --refine_skip_;
    StepStats direct = refine(h, can_split);
    if (direct.ok) return direct;
  }
  StepStats first = attempt(h, can_split, reject_newton);
  refine_next_ = false;
  if (first.ok) refine_interval_ = 0;  // linearized steps pass again
  if (!first.ok && energy_rejected_ && !pinsJump() && implicit_euler) {
    // implicit_euler's step is the first Newton iteration of backward Euler.
    // Where that linearization would create energy (a stiff spring turned or
    // stretched beyond its tangent: a calm cloth of stretch 1e9 at dt 1/30
    // gains 2.5e4 J in its first linearized step), the same step is solved on
    // towards the backward-Euler answer instead of being split (the stiffer
    // the cloth, the more halvings a split needed). Newton's iterates lower
    // the incremental potential; the step is accepted on the energy check,
    // as the linearized one would have been, not on Newton's tolerance: a
    // falling stiff cloth's potential is so flat along its bending modes that
    // Newton wanders there (1 % velocity changes for a 1e-7 relative
    // decrease) long after the energy is right.
    // Not when a pin jumped into the step: a pin moved 0.7 m through the demo
    // in one step took Newton 21 iterations and 38 ms (a flooded 60 Hz node
    // fell to 46 Hz), and capping Newton let strain overshoot through; two
    // half steps cost less. Pins drifting at a velocity move little in a
    // step: those steps are refined (compression at stretch 1e7 was split
    // down to 1/32 steps and still failed).
    const StepStats linear = first;
    first = refine(h, can_split);
    // Refined at once for the next refine_skip_ steps (see above); a failed
    // try of the linearized step doubles the wait.
    refine_interval_ = sticky ? std::min(2 * std::max(refine_interval_, 1), kMaxRefineInterval)
                              : kFirstRefineInterval;
    refine_skip_ = refine_interval_;
    first.wall_time_s += linear.wall_time_s;
    first.cg_iterations += linear.cg_iterations;
    first.newton_iterations += linear.newton_iterations;
    if (first.ok) return first;
    first.rejected += linear.rejected + 1;
    first.failure = "linearized step: " + linear.failure + "; solved on by newton: " + first.failure;
  }
  // A bdf2 step whose Newton missed its tolerance, in a scene with no
  // colliders and no self-collision: backward Euler solved as the newton
  // method solves it (damping axes held, exact local phase) converges where
  // bdf2's turning axes did not (hard case 07a: 10 -> 6 rejected sub-steps,
  // 05b 59 -> 29). Not with contact: an edge dragged over a table (c3) then
  // peaked at 62 % strain where 20 %; not with self-collision: the heap (s1)
  // took 46 rejected sub-steps where 26, and 10 % strain where 5 %.
  const bool unconverged_bdf2 = !first.newton_converged && first.finite &&
                                stepper_.bdf2HoldsAxes(!colliders_.empty());
  if (!first.ok && bdf2_step && (energy_rejected_ || unconverged_bdf2)) {
    // Neither BDF2 nor its trapezoidal start is dissipative step by step: a
    // step that would gain energy is retried as backward Euler (order 1) at
    // the same size, which keeps the history at h, before it costs a halving;
    // so is an unconverged one (above).
    const std::string bdf2_failure = first.failure;
    const int rejected = first.rejected + 1;
    first = attempt(h, can_split, reject_newton, Method::Newton);
    first.rejected += rejected;
    if (first.ok) {
      first.order_reduced = 1;
      if (first.failure.empty()) first.failure = "bdf2 " + bdf2_failure + ": retried as backward Euler";
      return first;
    }
    if (energy_rejected_ && scene_.solver.newton_max_iterations == 1 && !pinsJump()) {
      // Linearly implicit bdf2 promises no Newton tolerance, and its one
      // backward-Euler iteration gains energy where stiff springs turn (a
      // falling 20x20 cloth of stretch 1e5 at dt 1/60: 159 rejected
      // sub-steps in a second, 4 halvings deep): solved on, as
      // implicit_euler's step is, before it costs a halving.
      const int rejected_before = first.rejected + 1;
      StepStats refined = refine(h, can_split);
      refined.rejected += rejected_before;
      if (refined.ok) {
        refined.order_reduced = 1;
        refined.failure = "bdf2 " + bdf2_failure + ": retried as backward Euler, solved on by newton";
        return refined;
      }
      first = refined;
    }
  }
  if (!first.ok && energy_rejected_ && !can_split && stepper_.contacts().heldPulls() > 0) {
    // Contacts let go this step for pulling and held once back (no
    // cycling) stuck where they pulled: they can pull a node onto a surface
    // against its springs, a gain no halving shrinks (a stiffened cloth on a
    // table's edge, c4 at newton dt 0.1: 1.5e-3 J at dt/256). At the deepest
    // halving, before the step fails, it is retried with those sliding
    // (ContactSet::update), as the last retry above was taken (bdf2 as
    // backward Euler, implicit_euler solved on). Not at every rejection: a
    // cloth dropped onto a rod then crept on longer (kinetic energy after
    // 3 s 2.3e-3 J where 1.4e-3; 4.0e-3 in the sanitized build, above the
    // test's 3.9e-3).
    const StepStats stuck = first;
    stepper_.setSlideHeldPulls(true);
    first = implicit_euler && !pinsJump() ? refine(h, can_split)
                           : attempt(h, can_split, reject_newton,
                                     bdf2_step ? std::optional<Method>(Method::Newton)
                                               : std::nullopt);
    stepper_.setSlideHeldPulls(false);
    first.wall_time_s += stuck.wall_time_s;
    first.cg_iterations += stuck.cg_iterations;
    first.newton_iterations += stuck.newton_iterations;
    first.rejected += stuck.rejected + 1;
    if (first.ok) {
      if (bdf2_step) first.order_reduced = 1;
      return first;
    }
  }
  if (!first.ok && fallback && !first.newton_converged && first.finite) {
    const std::string newton_failure = first.failure;
    const int rejected = first.rejected + 1;
    // Its linear solve must converge while a halving is left.
    first = attempt(h, can_split, false, Method::ImplicitEuler);
    if (!first.ok && energy_rejected_ && !pinsJump()) {
      // The linearized step gains energy (a collapsed start at stretch 1e7,
      // dt 0.1: 5.7e6 J at dt/256): solved on towards backward Euler and
      // held to the energy check, as implicit_euler does (refine).
      first = refine(h, can_split);
    }
    first.rejected = rejected + (first.ok ? 0 : 1);
    if (first.ok) {
      first.linearized = 1;
      first.newton_converged = false;
      first.failure = newton_failure +
                      (can_split ? std::string(" in a step with colliders")
                                 : " even after " + std::to_string(depth) + " step halvings") +
                      ": took a linearized backward-Euler step";
      if (!first.linear_converged) {
        first.failure += " (its linear solve short of tolerance, relative residual " +
                         fmt(first.residual) + ")";
      }
      return first;
    }
  }
  if (first.ok || !can_split) {
    if (!first.ok && depth > 0) {
      first.failure += " (after " + std::to_string(depth) + " step halvings)";
    } else if (first.ok && !first.linear_converged) {
      first.failure = "linear solver did not reach tolerance (relative residual " +
                      fmt(first.residual) + ")";
    } else if (first.ok && !first.newton_converged) {
      first.failure = newtonFailure(first);
    }
    return first;
  }
  // Every attempt so far failed and changed nothing: the state is still the
  // step's start, which the halves' failure must return to.
  StepStats total = splitInHalves(h, depth);
  total.rejected += 1;
  total.wall_time_s += first.wall_time_s;
  total.cg_iterations += first.cg_iterations;
  if (!total.ok) return total;
  if (total.linearized > 0) {
    total.failure = std::to_string(total.linearized) +
                    " sub-step(s) taken as linearized backward-Euler steps: newton did not "
                    "converge even after " + std::to_string(total.halvings) + " step halvings";
  } else if (!total.linear_converged || !total.newton_converged) {
    // A sub-step at the deepest halving was accepted short of its tolerance: say that.
    total.failure = std::string(total.newton_converged ? "linear solver did not reach tolerance"
                                                       : "newton did not converge") +
                    " even after " + std::to_string(total.halvings) + " step halvings (accepted)";
  } else {
    total.failure = "recovered from: " + first.failure;
  }
  return total;
}

}  // namespace cloth_sim
