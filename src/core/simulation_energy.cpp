// The energy check's measures (Simulation::attempt): the energy scale its
// allowances are relative to, and the work moving pins did over a step.
#include "cloth_sim/simulation.hpp"

#include <algorithm>

namespace cloth_sim {

double Simulation::energyScale() const {
  double weight = 0.0;
  if (model_.has_gravity) {
    weight = Eigen::Map<const VecX>(model_.mass.data(), model_.numNodes()).sum() *
             model_.gravity.norm() * std::max(size_, 1e-3);
  }
  return measures_.kinetic + measures_.elastic + weight + 1e-12;
}

double Simulation::pinWork(const VecX& x1, const VecX& v1, double h, Method taken) {
  // The pins' force times their travel (static pins do no work), read from
  // the solve that gave (x1, v1):
  // - after a Newton solve (newton, bdf2, a refined step) the end state
  //   balances, and the solve's own reaction M (v1 - av) - b h f(x1, v1)
  //   is right for bdf2 too, whose momentum balance is not M (v1 - v0) / h
  //   (read that way, with its sign counted, the fling hard case under bdf2
  //   rejected 358 steps; 43 with the solve's reading, 55 before either);
  // - after implicit_euler's linearized step, its linear system's reaction
  //   A dv - rhs: read off f(x1, v1), a state the linearized answer does
  //   not balance, it was off by more than the work itself (pins dragged at
  //   10 m/s: a step that overstretched the cloth 42 % was accepted; the
  //   fold demo without self-collision refined 237 of 480 steps that gained
  //   nothing);
  // - but the end state, M (v1 - v0) / h - f(x1, v1), after a linearized
  //   step in which a pin jumped (a teleport, the same travel at every step
  //   size: the linear system's springs store what their tangents say, not
  //   what the jumped state holds, and no halving closes that gap, so the
  //   pin-jump hard case failed at stretch 1e5-1e8; the end state credits
  //   the jumped node's own momentum change, the bulk of a teleport's
  //   work), and with self-collision (the nodes its response holds do work
  //   in the solve that nothing credits, docs/stability.md, "session 26",
  //   which the end-state reading happened to cover: with the system's
  //   reading the twist failed at stretch 1e5-1e8, dt 0.1).
  const bool solved = taken == Method::Newton || taken == Method::Bdf2;
  const bool linear_system = stepper_.linearizedReaction() && pin_ends_.reaction_read;
  double impulse_scale = 1.0;  // force_ holds the pins' forces times this (b h: impulses)
  if (solved || linear_system) {
    stepper_.constraintImpulses(model_, x1, v1, &force_);
    impulse_scale = stepper_.reactionScale();
  } else {
    stepper_.forces(model_, x1, v1, force_, stepper_.dampingAxes());
    for (int node : pin_ends_.nodes) {
      force_.segment<3>(3 * node) =
          model_.mass[node] * (v1.segment<3>(3 * node) - v_save_.segment<3>(3 * node)) / h -
          force_.segment<3>(3 * node);
    }
  }
  double work = 0.0;
  for (int node : pin_ends_.nodes) {
    work += force_.segment<3>(3 * node).dot(x1.segment<3>(3 * node) - x_save_.segment<3>(3 * node));
  }
  return work / impulse_scale;
}

}  // namespace cloth_sim
