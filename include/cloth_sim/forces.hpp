// Whole-cloth forces, energies and the implicit system assembly. Each loop
// touches only the terms the model has (absent groups have no springs;
// gravity and drag are skipped when zero).
#pragma once

#include <limits>

#include "cloth_sim/linear_solver.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/spring_forces.hpp"

namespace cloth_sim {

/// Parameters of spring s under the model's current group settings.
SpringParams springParams(const Model& model, const Spring& s);

/// f = m g - c_air v + spring forces (3n). `damping_axes` (one unit vector
/// per spring, or null): along-spring damping acts along these instead of
/// the springs' current axes (newton's held axes, Stepper::newtonSolve).
/// `threads`: solver.threads (the same f on any number).
void computeForces(const Model& model, const VecX& x, const VecX& v, VecX& f,
                   const std::vector<Vec3>* damping_axes = nullptr, int threads = 1);

/// Fills A = M - a df/dv - b df/dx (pinned rows are handled by the solver),
/// and in the same spring sweep f(x, v) and, if w is given, df/dx * w.
/// `damping_axes` as in computeForces: A's damping is then a c w w^T, exact
/// (the force is linear in v and does not depend on x). With `split_out`,
/// f and df/dx * w come split by component (f[c n + i], CG's layout).
void assembleSystem(const Model& model, const VecX& x, const VecX& v, double a, double b,
                    bool project_compression, SystemMatrix& A, VecX& f,
                    const VecX* w = nullptr, VecX* dfdx_w = nullptr,
                    const std::vector<Vec3>* damping_axes = nullptr, bool split_out = false,
                    int threads = 1);

/// Each spring's current unit axis (d / |d|, or its rest direction when
/// degenerate) at positions x, into axes (one per spring).
void springAxes(const Model& model, const VecX& x, std::vector<Vec3>& axes);

/// Energy parts and max strain of a state, in one pass over the springs.
/// The node sums the round-off figures need (residualRoundOff,
/// energyRoundOff), of a velocity av.
struct RoundOffTerms {
  double momentum_sq = 0.0;  ///< sum m^2 |av|^2 = |M av|^2
  double mass_sq = 0.0;      ///< sum m^2
  double kinetic2 = 0.0;     ///< sum m |av|^2 = |av|_M^2
  double m_min = std::numeric_limits<double>::infinity();
};
RoundOffTerms roundOffTerms(const Model& model, const VecX& av);

struct EnergyParts {
  double kinetic = 0.0;
  double elastic = 0.0;
  double potential = 0.0;   ///< -sum m g.x
  double max_strain = 0.0;  ///< max |d|/L - 1 (0 without springs)
  /// self-repulsion's (self_repulsion.hpp): not measureEnergy's, the
  /// simulation adds it (Simulation::repulsionEnergy)
  double repulsion = 0.0;
  bool finite = true;  ///< x and v were finite (measureEnergy's)
  RoundOffTerms round_off;  ///< of v (measureEnergy's)
  double total() const { return kinetic + elastic + potential + repulsion; }
};
EnergyParts measureEnergy(const Model& model, const VecX& x, const VecX& v);

double kineticEnergy(const Model& model, const VecX& v);
double elasticEnergy(const Model& model, const VecX& x);
double gravityEnergy(const Model& model, const VecX& x);  ///< -sum m g.x
/// sqrt(sum over springs of (k L)^2): each spring force k (l - L) carries a
/// round-off of about eps k L, so a force balance cannot be met more closely
/// than about eps times this.
double springForceScale(const Model& model);
/// The round-off floor of a step's momentum residual ||M (v1 - av) - b h f||:
/// 100 eps times the size of its terms (M av, the weight and a unit-strain
/// spring force, times b h). Newton stops there: below it ||g|| is noise.
double residualRoundOff(const Model& model, double bh, const VecX& av);
/// The energy a residual r of residualRoundOff's size can move (J):
/// |av|_M r / sqrt(m_min) + 1/2 r^2 / m_min. A residual g moves v1 by
/// H^-1 g, the energy by (M av)^T H^-1 g to first order (dE/dv1 = M av at
/// the solution), and H >= M. It matters only for stiff springs (stretch
/// 1e8: ~1e-17 J at rest, 4e-5 J moving at 11 J, dt 0.1); elsewhere it is
/// far below the energy check's 1e-6 of the energy scale.
double energyRoundOff(const Model& model, double bh, const VecX& av);
/// The same from av's terms (measureEnergy keeps them: no second pass).
double energyRoundOff(const Model& model, double bh, const RoundOffTerms& av_terms);
/// Largest |d|/L - 1 over all springs (0 without springs).
double maxStrain(const Model& model, const VecX& x);

}  // namespace cloth_sim
