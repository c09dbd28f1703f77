// bdf2 with one Newton iteration (the benchmark's cheapest accurate setting)
// on the benchmark's own cloth.
#include <gtest/gtest.h>

#include <string>

#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"

namespace cloth_sim {
namespace {

// hang64 at dt 1/120 with recovery off, so every step must succeed as it is.
// With a backward-Euler start the very first step failed here (Newton's
// residual grew: the flat cloth's first step under gravity at beta = 1); the
// trapezoidal start (beta = 1/2) takes it, and BDF2 goes on from there.
TEST(Bdf2, OneIterationRunsHang64AtLargeSteps) {
  Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hang64.yaml");
  s.solver.dt = 1.0 / 120.0;
  s.solver.tolerance = 1e-2;
  s.solver.newton_max_iterations = 1;
  s.solver.recovery = false;
  Simulation sim(s);
  for (int n = 0; n < 240; ++n) {
    const StepStats stats = sim.step();
    ASSERT_TRUE(stats.ok) << "step " << n << ": " << stats.failure;
    ASSERT_LT(sim.maxStrain(), 0.05) << "step " << n;
  }
  EXPECT_NEAR(sim.time(), 2.0, 1e-9);
}

// The contact benchmark's floor scene (bdf2, one Newton iteration, block
// Jacobi CG to 5e-3): a step's first correction starts where the last two
// were heading, and a later contact pass solves only what the changed
// contacts left, to the first pass's scale. Before: 29.0 CG iterations a
// one-pass step and 61 more for each later pass; now 23.4 and 31.
TEST(Bdf2, LinearizedStepsStartCloseAndLaterContactPassesSolveTheRemnant) {
  Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/bench/scenes/hang32_floor.yaml");
  ASSERT_EQ(s.solver.newton_max_iterations, 1);
  s.solver.recovery = false;
  Simulation sim(s);
  long one_pass_steps = 0, one_pass_cg = 0, later_passes = 0, multi_pass_cg = 0, multi_steps = 0;
  while (sim.time() < 1.0 - 1e-9) {
    const StepStats stats = sim.step();
    ASSERT_TRUE(stats.ok) << "t " << sim.time() << ": " << stats.failure;
    if (stats.contact_passes <= 1) {
      ++one_pass_steps;
      one_pass_cg += stats.cg_iterations;
    } else {
      ++multi_steps;
      later_passes += stats.contact_passes - 1;
      multi_pass_cg += stats.cg_iterations;
    }
  }
  ASSERT_GT(one_pass_steps, 300);
  ASSERT_GT(later_passes, 5);  // the swing's lowest nodes land and leave
  const double per_step = static_cast<double>(one_pass_cg) / one_pass_steps;
  const double per_later_pass =
      (multi_pass_cg - per_step * multi_steps) / static_cast<double>(later_passes);
  EXPECT_LT(per_step, 26.0);
  EXPECT_LT(per_later_pass, 1.6 * per_step);
  EXPECT_LT(sim.maxStrain(), 0.02);
}

}  // namespace
}  // namespace cloth_sim
