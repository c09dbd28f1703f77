// CG's relaxed float products (linear_solver.cpp): where the whole solve's
// tolerance is too tight for a float product, products after the residual
// has fallen far enough are taken in float, and the solve still stops only
// when the true residual b - A x, computed apart in double, is within the
// tolerance. Where the assembler gives no word that the couplings are PSD
// (no compression projection) or the matrix has extra node blocks (contact
// friction), every product stays double.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>

#include "cloth_sim/forces.hpp"
#include "cloth_sim/linear_solver.hpp"
#include "cloth_sim/simulation.hpp"

namespace cloth_sim {
namespace {

struct System {
  Model model;
  SystemMatrix A;
  ConstraintFilter filter;
  VecX b;
};

/// The seed scene's step matrix after `steps` steps of its cloth (soft:
/// couplings about a third of a node's mass), at stretch `stiffness`.
System seedSystem(bool project, double stiffness = 100.0, int steps = 30) {
  Scene scene = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/seed.yaml",
                          {"springs.stretch.stiffness=" + std::to_string(stiffness)});
  Simulation sim(scene);
  for (int k = 0; k < steps; ++k) EXPECT_TRUE(sim.step().ok);
  System s;
  s.model = sim.model();
  VecX f;
  const double h = scene.solver.dt;
  assembleSystem(s.model, sim.positions(), sim.velocities(), h, h * h, project, s.A, f);
  s.filter.reset(s.model.numNodes());
  for (int p : scene.pins) s.filter.eliminate(p);
  s.b = h * f;
  s.filter.apply(s.b);
  return s;
}

/// |b - A x| / |b| on the free DOFs, in double, apart from CG.
double trueResidual(const System& s, const VecX& x) {
  VecX Ax;
  s.A.multiplyAll(x, Ax);
  VecX r = s.b - Ax;
  s.filter.apply(r);
  return r.norm() / s.b.norm();
}

/// The answer to round-off.
VecX exactAnswer(const System& s) {
  CgWorkspace ws;
  VecX x = VecX::Zero(s.b.size());
  const CgResult cg = conjugateGradient(s.A, s.model.springs, s.filter, s.b, x,
                                        Preconditioner::None, 1e-14, 2000, ws);
  EXPECT_TRUE(cg.converged);
  EXPECT_LE(trueResidual(s, x), 1e-12);  // double's own round-off on the stiff cloth
  return x;
}

/// A start near the answer, as a warm start gives one.
VecX nearby(const VecX& x, double relative, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  VecX d(x.size());
  for (int k = 0; k < d.size(); ++k) d[k] = noise(rng);
  return x + (relative * x.norm() / d.norm()) * d;
}

TEST(RelaxedProducts, FloatProductsOnceTheResidualIsSmallAndTheTrueResidualStillMeetsTheTolerance) {
  const System s = seedSystem(true);
  ASSERT_FALSE(s.A.singlePrecisionFits(1e-8));  // the whole solve's rule says double
  ASSERT_TRUE(std::isfinite(s.A.relaxedSingleRounding()));
  const VecX exact = exactAnswer(s);
  for (Preconditioner p : {Preconditioner::None, Preconditioner::BlockJacobi}) {
    for (double start : {0.0, 1e-2, 1e-4}) {
      SCOPED_TRACE("preconditioner " + std::to_string(static_cast<int>(p)) + ", start " +
                   std::to_string(start));
      CgWorkspace ws;
      VecX x = start > 0.0 ? nearby(exact, start, 3) : VecX::Zero(s.b.size());
      const CgResult cg = conjugateGradient(s.A, s.model.springs, s.filter, s.b, x, p, 1e-8,
                                            500, ws);
      ASSERT_TRUE(cg.converged);
      EXPECT_GT(cg.float_products, 0);
      EXPECT_LE(cg.float_products, cg.iterations);
      // The reported residual bounds the true one, which meets the tolerance.
      EXPECT_LE(trueResidual(s, x), cg.relative_residual * (1.0 + 1e-6));
      EXPECT_LE(trueResidual(s, x), 1e-8);
    }
  }
}

TEST(RelaxedProducts, StiffClothAtATightToleranceMeetsItToo) {
  // Couplings ~3e4 times a node's mass: float products only where the
  // residual is far below the target, if anywhere; the answer meets it.
  const System s = seedSystem(true, 1e7, 5);
  const VecX exact = exactAnswer(s);
  CgWorkspace ws;
  VecX x = nearby(exact, 1e-3, 5);
  const CgResult cg = conjugateGradient(s.A, s.model.springs, s.filter, s.b, x,
                                        Preconditioner::BlockJacobi, 1e-8, 5000, ws);
  ASSERT_TRUE(cg.converged);
  EXPECT_LE(trueResidual(s, x), 1e-8);
}

TEST(RelaxedProducts, DoubleWithoutTheAssemblersWordOrWithExtraNodeBlocks) {
  {
    // No compression projection: no word that the couplings are PSD.
    const System s = seedSystem(false);
    EXPECT_FALSE(std::isfinite(s.A.relaxedSingleRounding()));
    CgWorkspace ws;
    VecX x = nearby(exactAnswer(s), 1e-4, 7);
    const CgResult cg = conjugateGradient(s.A, s.model.springs, s.filter, s.b, x,
                                          Preconditioner::None, 1e-8, 500, ws);
    EXPECT_TRUE(cg.converged);
    EXPECT_EQ(cg.float_products, 0);
  }
  {
    // A contact's friction block on a node: A >= the node blocks is not known.
    System s = seedSystem(true);
    s.A.addNodeBlock(40, 0.5 * Mat3::Identity());
    EXPECT_FALSE(std::isfinite(s.A.relaxedSingleRounding()));
    CgWorkspace ws;
    VecX x = VecX::Zero(s.b.size());
    const CgResult cg = conjugateGradient(s.A, s.model.springs, s.filter, s.b, x,
                                          Preconditioner::None, 1e-8, 500, ws);
    EXPECT_TRUE(cg.converged);
    EXPECT_EQ(cg.float_products, 0);
  }
  {
    // A coupling changed after the assembly: the word is dropped.
    System s = seedSystem(true);
    ASSERT_TRUE(std::isfinite(s.A.relaxedSingleRounding()));
    s.A.setCoupling(3, -0.1, 0.0, Vec3::UnitX());
    EXPECT_FALSE(std::isfinite(s.A.relaxedSingleRounding()));
  }
}

}  // namespace
}  // namespace cloth_sim

namespace cloth_sim {
namespace {

/// v split by component (v[c n + i]).
VecX splitOf(const VecX& v) {
  const int n = static_cast<int>(v.size() / 3);
  VecX s(v.size());
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) s[c * n + i] = v[3 * i + c];
  }
  return s;
}

// implicit_euler's common step hands CG its vectors split by component
// (stepper_implicit_euler.cpp). Split or not, CG must do the same arithmetic:
// the same answer to the bit, from a warm start and a cold one, with the
// relaxed float products and without.
TEST(RelaxedProducts, SplitVectorsGiveTheSameAnswerToTheBit) {
  for (bool project : {true, false}) {
    const System s = seedSystem(project);
    const VecX exact = exactAnswer(s);
    for (const VecX& start : {VecX(VecX::Zero(s.b.size())), nearby(exact, 1e-4, 3)}) {
      for (Preconditioner p : {Preconditioner::None, Preconditioner::BlockJacobi}) {
        CgWorkspace ws_aos, ws_split;
        VecX x_aos = start, x_split = splitOf(start);
        const CgResult a = conjugateGradient(s.A, s.model.springs, s.filter, s.b, x_aos, p, 1e-8,
                                             500, ws_aos);
        const CgResult b = conjugateGradient(s.A, s.model.springs, s.filter, splitOf(s.b),
                                             x_split, p, 1e-8, 500, ws_split, /*split=*/true);
        EXPECT_EQ(a.iterations, b.iterations);
        EXPECT_EQ(a.float_products, b.float_products);
        EXPECT_EQ(a.relative_residual, b.relative_residual);
        const VecX joined = splitOf(x_aos);
        EXPECT_EQ(0, std::memcmp(joined.data(), x_split.data(), sizeof(double) * joined.size()));
      }
    }
  }
}

}  // namespace
}  // namespace cloth_sim
