// The energy balance over a bdf2 run's last accepted steps, where pins or
// colliders move (Simulation::attempt's energy check).
#pragma once

#include <algorithm>
#include <array>

namespace cloth_sim {

/// B = energy minus the work put in, summed from the accepted steps' gains
/// since clear(). A step may gain what B lies below its maximum over the
/// last kSteps accepted steps (credit()): that maximum then never grows, so
/// E <= E0 + W + kSteps allowances over any run (a Lyapunov-type bound, as
/// BDF2's G-norm gives for linear systems). Why not step by step: with moving
/// pins the work is a one-point quadrature whose error is of the size of
/// BDF2's own step-to-step energy change, and a step retried as backward
/// Euler bends the two-step history so that the next one "gains" again (the
/// fling at stretch 1e5, dt 1e-4: 2137 of 6600 steps retried).
class EnergyWindow {
 public:
  static constexpr int kSteps = 8;

  void clear() {
    now_ = 0.0;
    count_ = 1;
    next_ = 1;
    window_[0] = 0.0;
  }
  double credit() const {
    double top = now_;
    for (int k = 0; k < count_; ++k) top = std::max(top, window_[k]);
    return top - now_;
  }
  /// An accepted step that gained `gain` (J, may be negative).
  void accept(double gain) {
    now_ += gain;
    window_[next_] = now_;
    next_ = (next_ + 1) % kSteps;
    count_ = std::min(count_ + 1, kSteps);
  }

 private:
  std::array<double, kSteps> window_{};
  int count_ = 1, next_ = 1;
  double now_ = 0.0;
};

}  // namespace cloth_sim
