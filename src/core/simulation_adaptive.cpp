// Error-controlled stepping (solver.error_tolerance) and the checkpoint that
// lets a step be taken back: Simulation::stepToward, advanceTo.
#include <algorithm>
#include <cmath>
#include <limits>

#include "cloth_sim/simulation.hpp"

namespace cloth_sim {

void Simulation::saveCheckpoint() {
  // Member buffers: no allocation once sized.
  checkpoint_.x = x_;
  checkpoint_.v = v_;
  checkpoint_.x_prev = x_prev_;
  checkpoint_.v_prev = v_prev_;
  checkpoint_.has_prev = has_prev_;
  checkpoint_.t = t_;
  checkpoint_.h_prev = h_prev_;
  checkpoint_.work = work_in_total_;
  checkpoint_.pins.assign(pins_.begin(), pins_.end());
  checkpoint_.colliders = collider_states_;
  checkpoint_.max_penetration = max_penetration_;
  checkpoint_.min_self_distance = min_self_distance_;
  checkpoint_.saved = true;
}

void Simulation::restoreCheckpoint() {
  x_ = checkpoint_.x;
  v_ = checkpoint_.v;
  x_prev_ = checkpoint_.x_prev;
  v_prev_ = checkpoint_.v_prev;
  has_prev_ = checkpoint_.has_prev;
  t_ = checkpoint_.t;
  h_prev_ = checkpoint_.h_prev;
  work_in_total_ = checkpoint_.work;
  pins_ = std::map<int, PinTarget>(checkpoint_.pins.begin(), checkpoint_.pins.end());
  collider_states_ = checkpoint_.colliders;
  max_penetration_ = checkpoint_.max_penetration;
  min_self_distance_ = checkpoint_.min_self_distance;
  measureState();
}

void Simulation::resetStepControl() {
  const Scene::Solver& s = scene_.solver;
  step_control_ = s.error_tolerance
                      ? StepSizeControl(*s.error_tolerance, s.dt, s.dt_min, s.dt_max)
                      : StepSizeControl();
}

StepStats Simulation::stepToward(double t_limit) {
  if (!adaptive()) {
    const double left = t_limit - t_;
    return step(left < scene_.solver.dt * (1.0 + 1e-9) ? left : scene_.solver.dt);
  }
  applyDueEvents();  // so the next event is the one to stop at
  StepStats total;
  total.substeps = 0;
  // Redo smaller until the estimate passes; dt_min always passes, so this
  // ends (each rejection shrinks by at least StepSizeControl's safety).
  for (;;) {
    double h = step_control_.proposal();
    double stop = t_limit;
    if (next_event_ < scene_.events.size()) stop = std::min(stop, scene_.events[next_event_].time);
    const double left = stop - t_;
    bool clipped = false;
    // The last step to a stop takes what is left; one that would leave a
    // sliver behind it splits the rest in two.
    if (left <= h * (1.0 + 1e-9)) {
      clipped = left < h;
      h = left;
    } else if (left < 2.0 * h) {
      h = 0.5 * left;
      clipped = true;
    }
    const bool had_history = has_prev_;
    const double h_prev = h_prev_;
    StepStats part = step(h);  // saves the checkpoint the rejection goes back to
    if (!part.ok) {
      accumulate(part, &total);
      return finish(total);
    }
    if (part.substeps > 1) {
      // Recovery split it (energy or solver, not accuracy): accepted, and
      // the next steps start at the size that worked.
      step_control_.shrinkTo(part.h_min);
      accumulate(part, &total);
      return finish(total);
    }
    // Which formula took the step decides the estimate's factor and order.
    const bool bdf2_formula = scene_.solver.method == Method::Bdf2 && had_history &&
                              part.order_reduced == 0 && h_prev > 0.0;
    const bool trapezoidal_start = scene_.solver.method == Method::Bdf2 && !bdf2_formula &&
                                   part.order_reduced == 0;
    // Pins and the contact normals the step ended with: no error there.
    departure_filter_.reset(model_.numNodes());
    for (const auto& entry : pins_) departure_filter_.eliminate(entry.first);
    stepper_.contacts().constrainNormals(departure_filter_);
    const double departure =
        trapezoidDeparture(checkpoint_.x, checkpoint_.v, x_, v_, h, departure_filter_);
    bool accepted = true;
    if (!trapezoidal_start) {  // the trapezoidal rule departs from itself by round-off only
      const double factor = bdf2_formula ? bdf2ErrorFactor(h / h_prev) : 1.0;
      const double error = factor * departure / size_;
      accepted = step_control_.judge(h, error, bdf2_formula ? 2 : 1, clipped);
      if (accepted) part.error_per_time = error / h;
    }
    if (accepted) {
      accumulate(part, &total);
      return finish(total);
    }
    // Taken back: the state, the clock and the step count as before it.
    restoreCheckpoint();
    --step_count_;
    ++total.error_rejected;
    total.addWork(part);  // the work was spent all the same
  }
}

StepStats Simulation::advanceTo(double t_end) {
  StepStats total;
  total.substeps = 0;
  if (!std::isfinite(t_end) || !(t_end > t_)) {
    total.ok = false;
    total.failure = "advanceTo: t_end must be finite and after the current time " + std::to_string(t_) +
                    ", got " + std::to_string(t_end);
    return total;
  }
  // Stops within round-off of t_end count as there.
  const double slack = 1e-9 * std::max(scene_.solver.dt, t_end - t_);
  if (adaptive()) {
    while (t_end - t_ > slack) {
      const StepStats part = stepToward(t_end);
      accumulate(part, &total);
      if (!part.ok) break;
    }
  } else {
    const long steps = std::max(1L, static_cast<long>(std::ceil((t_end - t_) / scene_.solver.dt - 1e-9)));
    const double h = (t_end - t_) / static_cast<double>(steps);
    for (long k = 0; k < steps; ++k) {
      const StepStats part = step(h);
      accumulate(part, &total);
      if (!part.ok) break;
    }
  }
  return finish(total);
}

StepStats Simulation::finish(StepStats total) {
  total.energy = measures_.total();
  total.max_strain = measures_.max_strain;
  total.finite = allFinite(x_) && allFinite(v_);
  last_stats_ = total;
  return total;
}

}  // namespace cloth_sim
