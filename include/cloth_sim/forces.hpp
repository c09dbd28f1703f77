// Whole-cloth forces, energies and the implicit system assembly. Each loop
// touches only the terms the model has (absent groups have no springs;
// gravity and drag are skipped when zero).
#pragma once

#include "cloth_sim/linear_solver.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/spring_forces.hpp"

namespace cloth_sim {

/// Parameters of spring s under the model's current group settings.
SpringParams springParams(const Model& model, const Spring& s);

/// f = m g - c_air v + spring forces (3n).
void computeForces(const Model& model, const VecX& x, const VecX& v, VecX& f);

/// Fills A = M - a df/dv - b df/dx (pinned rows are handled by the solver),
/// and in the same spring loop f(x, v) and, if w is given, df/dx * w.
/// Also accumulates A's block diagonal for the preconditioner.
void assembleSystem(const Model& model, const VecX& x, const VecX& v, double a, double b,
                    bool project_compression, SystemMatrix& A, VecX& f,
                    const VecX* w = nullptr, VecX* dfdx_w = nullptr);

/// Energy parts and max strain of a state, in one pass over the springs.
struct EnergyParts {
  double kinetic = 0.0;
  double elastic = 0.0;
  double potential = 0.0;   ///< -sum m g.x
  double max_strain = 0.0;  ///< max |d|/L - 1 (0 without springs)
  double total() const { return kinetic + elastic + potential; }
};
EnergyParts measureEnergy(const Model& model, const VecX& x, const VecX& v);

double kineticEnergy(const Model& model, const VecX& v);
double elasticEnergy(const Model& model, const VecX& x);
double gravityEnergy(const Model& model, const VecX& x);  ///< -sum m g.x
/// sqrt(sum over springs of (k L)^2): each spring force k (l - L) carries a
/// round-off of about eps k L, so a force balance cannot be met more closely
/// than about eps times this.
double springForceScale(const Model& model);
/// Largest |d|/L - 1 over all springs (0 without springs).
double maxStrain(const Model& model, const VecX& x);

}  // namespace cloth_sim
