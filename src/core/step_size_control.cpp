#include "cloth_sim/step_size_control.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cloth_sim {

namespace {
/// Aim below the tolerance, so the next step is rarely rejected.
constexpr double kSafety = 0.9;
/// At most this growth per step: variable-step BDF2 is zero-stable below
/// 1 + sqrt(2), and a cautious growth rejects fewer steps after a calm spell.
constexpr double kMaxGrowth = 2.0;
constexpr double kMinShrink = 0.2;
/// A step that could grow by less than this keeps its size: a constant step
/// keeps BDF2 on its fixed-step formula and reuses the factor and multigrid
/// hierarchy of the last step (both change with h).
constexpr double kHysteresis = 1.2;
}  // namespace

double trapezoidDeparture(const VecX& x0, const VecX& v0, const VecX& x1, const VecX& v1,
                          double h, const ConstraintFilter& filter) {
  double sum = 0.0;
  int count = 0;
  for (int i = 0; i < filter.numNodes(); ++i) {
    if (filter.isEliminated(i)) continue;
    Vec3 d = x1.segment<3>(3 * i) - x0.segment<3>(3 * i) -
             (0.5 * h) * (v0.segment<3>(3 * i) + v1.segment<3>(3 * i));
    if (filter.isProjected(i)) d = filter.projector(i) * d;
    sum += d.squaredNorm();
    ++count;
  }
  return count > 0 ? std::sqrt(sum / count) : 0.0;
}

double bdf2ErrorFactor(double w) {
  const double c = (1.0 + w) * (1.0 + w) / (6.0 * w * (1.0 + 2.0 * w));
  return c / (c - 1.0 / 12.0);
}

StepSizeControl::StepSizeControl(double tolerance, double dt_first, double dt_min,
                                 double dt_max)
    : tolerance_(tolerance), dt_min_(dt_min), dt_max_(dt_max) {
  proposal_ = clamp(dt_first);
}

double StepSizeControl::clamp(double h) const { return std::clamp(h, dt_min_, dt_max_); }

bool StepSizeControl::judge(double h, double error, int order, bool clipped) {
  // Error per unit step: error / h is O(h^order), so the size that meets the
  // tolerance scales as (tolerance h / error)^(1 / order).
  const double allowed = tolerance_ * h;
  const double ratio = std::isfinite(error) ? error / allowed : std::numeric_limits<double>::infinity();
  const bool accepted = ratio <= 1.0 || h <= dt_min_ * (1.0 + 1e-12);
  double factor = ratio > 0.0 ? kSafety * std::pow(ratio, -1.0 / order) : kMaxGrowth;
  factor = std::clamp(factor, kMinShrink, kMaxGrowth);
  if (accepted && factor >= 1.0 && factor < kHysteresis) factor = 1.0;
  const double next = clamp(h * factor);
  if (accepted && clipped) {
    // A short step within tolerance says little about a full one: the
    // proposal stands unless even the short step came near the tolerance.
    if (factor < 1.0) proposal_ = std::min(proposal_, next);
  } else {
    proposal_ = next;
  }
  return accepted;
}

void StepSizeControl::shrinkTo(double h) { proposal_ = clamp(std::min(proposal_, h)); }

}  // namespace cloth_sim
