// The folding demo's scene (config/scenes/fold.yaml, demo.launch scene:=fold)
// run headless to the end: two corners of a towel on a table are carried
// onto the other two and let go. At every step no two triangles that share
// no node intersect (exact test); at the end the towel lies folded in two
// layers on the table, nothing below the table top.
#include <gtest/gtest.h>

#include <algorithm>

#include "cloth_sim/collision_geometry.hpp"
#include "cloth_sim/simulation.hpp"
#include "../common/cloth_checks.hpp"

namespace cloth_sim {
namespace {

/// The scene as shipped and a hair off it. A tolerance a hair off changes
/// only round-off (at 1.0002e-4 a layer falling onto the one on the table,
/// its nodes held two-sidedly by the table, threw its free nodes by the
/// whole gap: an energy jump halving did not shrink, t = 2.64 s). Another
/// step size or stretch stiffness lays the towel along another path: with
/// dt 0.008 s the top layer, pulled by the held corners, pressed onto the
/// bottom one at the table and the filter lifted it every step, unsolved
/// (every step from t = 2.1 s split 5 times deep, Simulation::resolveSelfCollision).
struct FoldVariant {
  const char* name;
  double tolerance;
  double dt;  ///< 0: the scene's
  double stretch;  ///< 0: the scene's
};

class FoldDemo : public testing::TestWithParam<FoldVariant> {};

TEST_P(FoldDemo, TowelEndsFoldedInTwoLayersWithoutIntersecting) {
  Scene scene = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/fold.yaml");
  const FoldVariant variant = GetParam();
  scene.solver.tolerance = variant.tolerance;
  if (variant.dt > 0.0) scene.solver.dt = variant.dt;
  if (variant.stretch > 0.0) scene.springs[static_cast<int>(SpringType::Stretch)].stiffness = variant.stretch;
  Simulation sim(scene);
  const double table_top = 0.75;  // the box's top (fold.yaml)
  const long steps = std::lround(4.0 / scene.solver.dt);  // the corners let go at 2.4 s
  long rejected = 0;
  for (long n = 0; n < steps; ++n) {
    const StepStats st = sim.step();
    rejected += st.rejected;
    ASSERT_TRUE(st.ok) << "step " << n << ": " << st.failure;
    ASSERT_TRUE(sim.positions().allFinite());
    ASSERT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0) << "step " << n << " t = " << sim.time();
  }
  double z_min = 1e9, z_max = -1e9, y_min = 1e9, y_max = -1e9;
  for (int i = 0; i < sim.numNodes(); ++i) {
    const Vec3 p = sim.position(i);
    z_min = std::min(z_min, p.z()), z_max = std::max(z_max, p.z());
    y_min = std::min(y_min, p.y()), y_max = std::max(y_max, p.y());
  }
  // Nothing below the table top plus the contact thickness (measured: on it, 0.752).
  EXPECT_GE(z_min, table_top + scene.contact.thickness - 1e-6);
  // Flat: two layers and the crease's loop (measured span 2.6-2.9 cm).
  EXPECT_LT(z_max - z_min, 0.03);
  // Folded in two: the 0.5 m towel covers about half its length (measured
  // 0.244 m in y with the crease).
  EXPECT_LT(y_max - y_min, 0.28);
  // The taken corners lie on the corners they were laid on, within 5 cm in
  // the plane: the top layer slides a little as it settles, by how much
  // depends on the path (as shipped 1.6 cm, 3.8 cm at CG 1e-6, 2.5 cm at
  // dt / 4, 3.5 cm at dt 0.008).
  // The 0.7 cm once measured here with multigrid was the unconverged answer
  // of a multigrid that ignored the contact projections.
  for (const auto& [taken, under] : {std::pair<int, int>{380, 0}, {399, 19}}) {
    const Vec3 d = sim.position(taken) - sim.position(under);
    EXPECT_LT(std::hypot(d.x(), d.y()), 0.05) << taken << " on " << under;
  }
  EXPECT_GT(sim.minSelfDistance(), 0.0);
  // Laid and settled without a storm of split steps (measured: none in each
  // variant; 117-787 before the filter's lifted nodes were solved again).
  EXPECT_EQ(rejected, 0);
  std::printf("[ fold     ] %s: %ld rejected, z span %.4f m, y extent %.4f m, corners %.4f / %.4f m apart, min self distance %.3g m\n",
              variant.name, rejected, z_max - z_min, y_max - y_min,
              std::hypot((sim.position(380) - sim.position(0)).x(), (sim.position(380) - sim.position(0)).y()),
              std::hypot((sim.position(399) - sim.position(19)).x(), (sim.position(399) - sim.position(19)).y()),
              sim.minSelfDistance());
}

INSTANTIATE_TEST_SUITE_P(Variants, FoldDemo,
                         testing::Values(FoldVariant{"as_shipped", 1.0e-4, 0.0, 0.0},
                                         FoldVariant{"perturbed", 1.0002e-4, 0.0, 0.0},
                                         FoldVariant{"dt_8ms", 1.0e-4, 0.008, 0.0},
                                         FoldVariant{"stretch_2800", 1.0e-4, 0.0, 2800.0}),
                         [](const testing::TestParamInfo<FoldVariant>& info) {
                           return std::string(info.param.name);
                         });

TEST(FoldDemoLaying, NoNodeIsPushedIntoTheTableAtTheScenesStepWithoutRecovery) {
  // Without recovery every linearized step is kept, as the benchmarks run.
  // At t = 2.02 s a CCD impulse through the layer being laid pushed a node
  // of the bottom one, 1.5 mm above the table's band and so free, 2.3 mm
  // down into it: the step failed. Free nodes are now guarded against
  // moves into their nearest collider beyond the band (SelfCollisionMasses).
  // Without air drag: with it the same step drives an impact zone that
  // holds the carried corners down onto the table, a prescribed motion no
  // filter can meet, which recovery halves.
  Scene scene = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/fold.yaml");
  scene.solver.recovery = false;
  scene.air_drag = 0.0;
  Simulation sim(scene);
  const double band = 0.75 + scene.contact.thickness;  // the table's top (fold.yaml)
  const long steps = std::lround(2.2 / scene.solver.dt);
  for (long n = 0; n < steps; ++n) {
    const StepStats st = sim.step();
    ASSERT_TRUE(st.ok) << "step " << n << " t = " << sim.time() << ": " << st.failure;
    ASSERT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0) << "step " << n;
    for (int i = 0; i < sim.numNodes(); ++i) {
      ASSERT_GE(sim.position(i).z(), band - 1e-6) << "node " << i << " step " << n;
    }
  }
}

}  // namespace
}  // namespace cloth_sim
