// Solver options the README documents, run through Simulation (issue 17):
// preconditioner none (plain CG, the original project's) and
// project_compression false. Every test asserts that its steps succeeded and
// that time advanced.
#include <gtest/gtest.h>

#include "cloth_sim/linear_solver.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

::testing::AssertionResult stepN(Simulation& sim, int steps, long* cg_iterations = nullptr) {
  for (int n = 0; n < steps; ++n) {
    const double before = sim.time();
    const StepStats s = sim.step();
    if (!s.ok) return ::testing::AssertionFailure() << "step " << n << " failed: " << s.failure;
    if (!s.linear_converged) return ::testing::AssertionFailure() << "step " << n << ": CG short";
    if (!(sim.time() > before)) return ::testing::AssertionFailure() << "time did not advance";
    if (!sim.positions().allFinite()) return ::testing::AssertionFailure() << "non-finite";
    if (cg_iterations) *cg_iterations += s.cg_iterations;
  }
  return ::testing::AssertionSuccess();
}

TEST(SolverOptions, PlainCgGivesTheSameCloth) {
  for (Method method : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene plain = test::hangingCloth(8, method);
    plain.solver.preconditioner = Preconditioner::None;
    Scene jacobi = test::hangingCloth(8, method);
    Simulation a(plain), b(jacobi);
    long plain_iterations = 0, jacobi_iterations = 0;
    ASSERT_TRUE(stepN(a, 50, &plain_iterations)) << toString(method);
    ASSERT_TRUE(stepN(b, 50, &jacobi_iterations)) << toString(method);
    EXPECT_NEAR(a.time(), 0.5, 1e-12);
    // Both solve to 1e-10: the same cloth to far below its size.
    EXPECT_LT((a.positions() - b.positions()).cwiseAbs().maxCoeff(), 1e-7) << toString(method);
    EXPECT_GT(plain_iterations, 0);
    // The cloth moved: it fell from the flat start.
    EXPECT_LT(a.position(8 * 8 - 1).z(), a.model().rest_positions[3 * (8 * 8 - 1) + 2] - 0.1);
  }
}

TEST(SolverOptions, WithoutCompressionProjectionCompressedClothStillSteps) {
  // Start compressed to 80 %: transverse stiffness of compressed springs is
  // negative without the projection, and recovery must keep every step sane.
  for (bool project : {true, false}) {
    Scene s = test::hangingCloth(8);
    s.initial.stretch = 0.8;
    s.solver.project_compression = project;
    s.solver.max_iterations = 2000;
    Simulation sim(s);
    ASSERT_TRUE(stepN(sim, 50)) << "project_compression " << project;
    EXPECT_NEAR(sim.time(), 0.5, 1e-12);
    EXPECT_LT(sim.maxStrain(), 0.2) << "project_compression " << project;
    EXPECT_GT(sim.maxStrain(), -1.0);
  }
}

// `cholesky` where the masses dominate the matrix (kappa <= 10, e.g. dt
// 1e-4, or 1e-3 here: kappa 1.5): block-Jacobi CG solves there in a few tens
// of iterations and no factor is made; the cloth is the one a factor gives, to
// far below the tolerance's reach. At a step where kappa is larger the factor
// is made as asked.
TEST(SolverOptions, CholeskyMakesNoFactorWhereTheMassesDominate) {
  for (Method method : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene light = test::hangingCloth(8, method);
    light.solver.preconditioner = Preconditioner::Cholesky;
    light.solver.tolerance = 1e-10;
    for (double dt : {1e-4, 1e-3}) {
      light.solver.dt = dt;
      const double kappa = autoStiffness(buildModel(light), dt);
      ASSERT_LE(kappa, Stepper::kMassDominatedKappa);
      if (dt > 1e-4) ASSERT_GT(kappa, 1.0);  // the range session 53 added
      Scene jacobi = light;
      jacobi.solver.preconditioner = Preconditioner::BlockJacobi;
      Simulation a(light), b(jacobi);
      ASSERT_TRUE(stepN(a, 200)) << toString(method);
      ASSERT_TRUE(stepN(b, 200)) << toString(method);
      EXPECT_EQ(a.factorizations(), 0) << toString(method) << " dt " << dt;
      EXPECT_LT((a.positions() - b.positions()).cwiseAbs().maxCoeff(), 1e-9) << toString(method);
      EXPECT_LT(a.position(8 * 8 - 1).z(), a.model().rest_positions[3 * (8 * 8 - 1) + 2] - 1e-4);
    }

    Scene stiff = light;
    stiff.solver.dt = 1.0 / 60.0;
    ASSERT_GT(autoStiffness(buildModel(stiff), stiff.solver.dt), Stepper::kMassDominatedKappa);
    Simulation c(stiff);
    ASSERT_TRUE(stepN(c, 5)) << toString(method);
    EXPECT_GT(c.factorizations(), 0) << toString(method);
  }
}

// `multigrid` where its V-cycle stalls (a stiff cloth: stretch 1e8 at dt
// 0.01): a solve goes on with a Cholesky factor after
// multigridStallIterations, and the next steps start with it. So the run
// costs about what `cholesky` costs (without the rule: 90466 V-cycles in one
// implicit_euler step here; on the 128 x 128 cloth 7049 in a step with 7
// rejected sub-steps) and gives its cloth. The demo cloth's stiffness makes
// no factor.
TEST(SolverOptions, MultigridGoesOnWithAFactorWhereItsVCycleStalls) {
  for (Method method : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene stiff = test::hangingCloth(24, method);
    stiff.springs[static_cast<int>(SpringType::Stretch)].stiffness = 1e8;
    stiff.solver.preconditioner = Preconditioner::Multigrid;
    stiff.solver.tolerance = 1e-8;
    stiff.solver.newton_tolerance = 1e-6;
    Scene direct = stiff;
    direct.solver.preconditioner = Preconditioner::Cholesky;
    Simulation a(stiff), b(direct);
    long multigrid_iterations = 0, cholesky_iterations = 0;
    ASSERT_TRUE(stepN(a, 20, &multigrid_iterations)) << toString(method);
    ASSERT_TRUE(stepN(b, 20, &cholesky_iterations)) << toString(method);
    EXPECT_GT(a.factorizations(), 0) << toString(method);
    EXPECT_LE(multigrid_iterations,
              1.1 * cholesky_iterations + 2 * multigridStallIterations(a.model()))
        << toString(method);
    // Both solve to the tolerances: 5e-6 m apart after 20 steps at most here
    // (CG 1e-8 of a right-hand side the stiff springs dominate).
    EXPECT_LT((a.positions() - b.positions()).cwiseAbs().maxCoeff(), 2e-5) << toString(method);
    EXPECT_LT(a.position(24 * 24 - 1).z(), a.model().rest_positions[3 * (24 * 24 - 1) + 2] - 1e-3);

    Scene demo = test::hangingCloth(24, method);
    demo.solver.preconditioner = Preconditioner::Multigrid;
    demo.solver.tolerance = 1e-8;
    Simulation c(demo);
    ASSERT_TRUE(stepN(c, 20)) << toString(method);
    EXPECT_EQ(c.factorizations(), 0) << toString(method);
  }
}

}  // namespace
}  // namespace cloth_sim
