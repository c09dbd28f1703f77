// What one step (or one call to Simulation::step) reports.
#pragma once

#include <limits>
#include <string>

namespace cloth_sim {

/// The smaller step size of two, where 0 means "none taken yet" (StepStats::h_min).
inline double smallerStep(double a, double b) {
  if (a <= 0.0) return b;
  return b <= 0.0 ? a : (a < b ? a : b);
}

struct StepStats {
  int cg_iterations = 0;      ///< summed over Newton iterations and sub-steps
  /// largest final relative CG residual ||r||/||b|| of the solves held to
  /// solver.tolerance (inexact Newton's looser ones are judged by ||g||)
  double residual = 0.0;
  int newton_iterations = 0;  ///< nonlinear iterations (1 for implicit_euler)
  double newton_residual = 0.0;  ///< final ||g|| / ||g0|| (newton, bdf2)
  bool linear_converged = true;  ///< every CG solve met its tolerance
  bool newton_converged = true;  ///< newton/bdf2: ||g|| met newton_tolerance (or round-off)
  double wall_time_s = 0.0;
  double assembly_s = 0.0;    ///< forces + Jacobians + matrix fill
  double solve_s = 0.0;       ///< linear solves
  double energy = 0.0;        ///< 1/2 m v^2 + elastic - m g.x after the step
  double max_strain = 0.0;    ///< max over springs of |d|/L - 1
  double work_in = 0.0;       ///< work done on the cloth by moving pins and stiffness changes
  /// Energy the step's round-off can move (J, energyRoundOff; summed over
  /// sub-steps): the energy check forgives gains below it, and so should
  /// any check of energy per step.
  double energy_round_off = 0.0;
  bool finite = true;         ///< every position and velocity finite
  int substeps = 1;           ///< steps actually taken (> 1 after recovery)
  int halvings = 0;           ///< deepest step halving used by recovery
  int rejected = 0;           ///< attempts rolled back
  /// Sizes of the steps taken (s): h_min the smallest sub-step of recovery
  /// or of error control, h_max the largest step
  double h_min = 0.0, h_max = 0.0;
  /// Error-controlled stepping: steps redone smaller because their error
  /// estimate exceeded solver.error_tolerance (not counted in `rejected`)
  int error_rejected = 0;
  /// Error-controlled stepping: the largest local error estimate accepted,
  /// relative to the cloth's diagonal and divided by the step size (1/s)
  double error_per_time = 0.0;
  /// newton/bdf2 sub-steps whose Newton iteration did not converge even at the
  /// deepest halving, taken instead as one linearized backward-Euler step
  /// (implicit_euler's step, its linear solve to tolerance)
  int linearized = 0;
  /// bdf2 steps that would have gained energy, retried as backward Euler
  /// (order 1) at the same size before any halving
  int order_reduced = 0;
  /// implicit_euler steps whose linearized answer would have gained energy,
  /// solved on by Newton (up to newton_max_iterations, accepted on the energy
  /// check) at the same size, before any halving; not counted in `rejected`
  int refined = 0;
  // contact (zero without colliders)
  int contacts = 0;              ///< nodes in contact at the end of the step
  double contact_normal_force = 0.0;  ///< sum of normal force magnitudes, N
  double max_penetration = 0.0;  ///< deepest inside surface + thickness at the step's end, m
  double contact_work = 0.0;     ///< work of the contact forces on the cloth, J
  int contact_passes = 0;        ///< solves until the contact set was consistent
  /// node-collider pairs queried exactly by the contact detection, every pass
  /// (the broad phase's survivors, ContactSet::lastQueries)
  long contact_queries = 0;
  // self-collision (zero / infinity when disabled)
  int self_contacts = 0;  ///< non-adjacent pairs closer than the thickness at the step's end
  /// smallest distance between non-adjacent parts at the step's end, m
  /// (exact below the thickness; infinity when no pair is near)
  double min_self_distance = std::numeric_limits<double>::infinity();
  double self_collision_s = 0.0;  ///< time in the self-collision filter (in wall_time_s)
  /// solves of the step beyond the first, with the nodes the filter moved
  /// prescribed (Simulation::resolveSelfCollision)
  int self_solves = 0;
  bool ok = true;             ///< false: the step failed and the state was rolled back
  std::string failure;        ///< why, when !ok (or what recovery fixed)

  /// Adds the effort `part` spent (iterations, times, contact passes,
  /// self-collision solves) to this step's: for a step whose answer was
  /// replaced (taken back, or solved again) but whose work counts.
  void addWork(const StepStats& part) {
    cg_iterations += part.cg_iterations;
    newton_iterations += part.newton_iterations;
    wall_time_s += part.wall_time_s;
    assembly_s += part.assembly_s;
    solve_s += part.solve_s;
    contact_passes += part.contact_passes;
    contact_queries += part.contact_queries;
    self_collision_s += part.self_collision_s;
    self_solves += part.self_solves;
  }
};

}  // namespace cloth_sim
