// Live tuning's conversion of a reconfigure request into scene overrides,
// without a master: a scene that names no solver.method keeps its automatic
// solver (cloth_sim::automaticSolver) through a request that leaves the method
// alone, and changing the method gives that method.
#include <gtest/gtest.h>

#include <string>

#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"
#include "live_tuning.hpp"

namespace cloth_sim_ros {
namespace {

TEST(LiveTuning, KeepsTheAutomaticSolverOfASceneWithoutMethod) {
  const std::string yaml = "cloth: {rows: 4, cols: 4}\n";
  cloth_sim::Simulation sim(cloth_sim::parseScene(yaml));
  cloth_sim::ClothSimConfig config = tuningConfig(sim.tuning());
  config.air_drag = 0.1;  // a request that leaves the solver alone
  cloth_sim::Tuning tuning;
  ASSERT_TRUE(tuningFromConfig(yaml, config, &tuning).ok);
  EXPECT_EQ(tuning.air_drag, 0.1);
  EXPECT_EQ(tuning.solver.method, cloth_sim::Method::Bdf2);
  EXPECT_EQ(tuning.solver.newton_max_iterations,
            cloth_sim::automaticSolver().newton_max_iterations);
  EXPECT_EQ(tuning.solver.dt, cloth_sim::automaticSolver().dt);
  // Naming another method gives it.
  config.method = "implicit_euler";
  ASSERT_TRUE(tuningFromConfig(yaml, config, &tuning).ok);
  EXPECT_EQ(tuning.solver.method, cloth_sim::Method::ImplicitEuler);
}

TEST(LiveTuning, KeepsANamedMethodsSettings) {
  const std::string yaml = "cloth: {rows: 4, cols: 4}\nsolver: {method: bdf2}\n";
  cloth_sim::Simulation sim(cloth_sim::parseScene(yaml));
  cloth_sim::ClothSimConfig config = tuningConfig(sim.tuning());
  cloth_sim::Tuning tuning;
  ASSERT_TRUE(tuningFromConfig(yaml, config, &tuning).ok);
  EXPECT_EQ(tuning.solver.method, cloth_sim::Method::Bdf2);
  EXPECT_EQ(tuning.solver.newton_max_iterations,
            cloth_sim::Scene::Solver().newton_max_iterations);
}

}  // namespace
}  // namespace cloth_sim_ros
