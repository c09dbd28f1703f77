// Newton's local phase (Stepper::newtonSolve, session 35): once an iteration
// has taken a full step that halved ||g||, the newton method goes on with
// the exact Hessian instead of the one with compression projected out. On a
// cloth that keeps springs compressed, projected Newton converges only
// linearly (hard case 05a: 15.7 iterations a step); the exact one
// converges quadratically where the whole matrix stays positive definite.
#include <gtest/gtest.h>

#include <string>

#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"

namespace cloth_sim {
namespace {

const std::string kScattered =
    std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/05a_scattered_start.yaml";

struct SolveCounts {
  long newton_iterations = 0, rejected = 0;
  bool converged = true;
};

SolveCounts runSteps(const std::vector<std::string>& sets, int steps) {
  Simulation sim(loadScene(kScattered, sets));
  SolveCounts r;
  for (int n = 0; n < steps; ++n) {
    const StepStats s = sim.step();
    EXPECT_TRUE(s.ok) << "step " << n << ": " << s.failure;
    if (!s.ok) break;
    r.newton_iterations += s.newton_iterations;
    r.rejected += s.rejected;
    r.converged = r.converged && s.newton_converged;
  }
  return r;
}

// A 12 x 12 cloth started scattered (1 cm) hangs with crumpled cells that
// stay compressed. One simulated second under newton, to newton_tolerance
// 1e-8 at every step: about 4 iterations a step with either preconditioner
// (projected throughout: 15.7 with Cholesky).
TEST(NewtonLocalPhase, ConvergesQuadraticallyOnACrumpledCloth) {
  for (const char* preconditioner : {"cholesky", "block_jacobi"}) {
    const SolveCounts r = runSteps(
        {"solver.method=newton", std::string("solver.preconditioner=") + preconditioner}, 100);
    EXPECT_TRUE(r.converged) << preconditioner;
    EXPECT_LE(r.newton_iterations, 6 * 100) << preconditioner;
    EXPECT_LE(r.rejected, 2) << preconditioner;
  }
}

// The same solve with the local phase's exact matrix left out (bdf2's
// Newton keeps the projected one): the linear convergence the phase cures.
// Guards the measurement above against a cloth that simply got easier.
TEST(NewtonLocalPhase, ProjectedNewtonIsLinearThere) {
  const SolveCounts r = runSteps({"solver.method=bdf2"}, 100);
  EXPECT_TRUE(r.converged);
  EXPECT_GE(r.newton_iterations, 8 * 100);
}

}  // namespace
}  // namespace cloth_sim
