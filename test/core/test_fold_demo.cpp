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

/// The solver tolerance the scene is run at: as shipped, and a hair off it,
/// which changes only round-off. (At 1.0002e-4 a layer falling onto the one
/// on the table, its nodes held two-sidedly by the table, threw its free
/// nodes by the whole gap: an energy jump halving did not shrink, t = 2.64 s.)
class FoldDemo : public testing::TestWithParam<double> {};

TEST_P(FoldDemo, TowelEndsFoldedInTwoLayersWithoutIntersecting) {
  Scene scene = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/fold.yaml");
  scene.solver.tolerance = GetParam();
  Simulation sim(scene);
  const double table_top = 0.75;  // the box's top (fold.yaml)
  const long steps = std::lround(4.0 / scene.solver.dt);  // the corners let go at 2.4 s
  for (long n = 0; n < steps; ++n) {
    const StepStats st = sim.step();
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
  // Flat: two layers and the crease's loop (measured span 2.4 cm).
  EXPECT_LT(z_max - z_min, 0.03);
  // Folded in two: the 0.5 m towel covers about half its length (measured
  // 0.244 m in y with the crease).
  EXPECT_LT(y_max - y_min, 0.28);
  // The taken corners lie on the corners they were laid on: 3.7 cm apart in
  // the plane, measured at the shipped CG tolerance and at 1e-5 and 1e-6
  // (the converged answer: the top layer slides a little as it settles).
  // The 0.7 cm once measured here was the unconverged answer of a multigrid
  // that ignored the contact projections (at 1e-6 it gives 3.65 cm too).
  for (const auto& [taken, under] : {std::pair<int, int>{380, 0}, {399, 19}}) {
    const Vec3 d = sim.position(taken) - sim.position(under);
    EXPECT_LT(std::hypot(d.x(), d.y()), 0.05) << taken << " on " << under;
  }
  EXPECT_GT(sim.minSelfDistance(), 0.0);
  std::printf("[ fold     ] z span %.4f m, y extent %.4f m, corners %.4f / %.4f m apart, min self distance %.3g m\n",
              z_max - z_min, y_max - y_min,
              std::hypot((sim.position(380) - sim.position(0)).x(), (sim.position(380) - sim.position(0)).y()),
              std::hypot((sim.position(399) - sim.position(19)).x(), (sim.position(399) - sim.position(19)).y()),
              sim.minSelfDistance());
}

INSTANTIATE_TEST_SUITE_P(Tolerances, FoldDemo, testing::Values(1.0e-4, 1.0002e-4),
                         [](const testing::TestParamInfo<double>& info) {
                           return info.index == 0 ? std::string("as_shipped") : std::string("perturbed");
                         });

}  // namespace
}  // namespace cloth_sim
