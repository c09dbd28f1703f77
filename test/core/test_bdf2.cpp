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

}  // namespace
}  // namespace cloth_sim
