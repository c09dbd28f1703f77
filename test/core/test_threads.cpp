// solver.threads: the sweeps and the product give the same numbers on any
// thread count, the multigrid's parted smoother keeps the V-cycle SPD and
// solves to the same answer, and the scene field is checked like the others.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "cloth_sim/forces.hpp"
#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

bool sameBits(const VecX& a, const VecX& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

/// A rows x cols cloth (above the one-thread limit of 1024 nodes) hanging
/// from two corners and swung for a while, so its springs point every which way.
Simulation swungCloth(int rows, int cols, Preconditioner p, int threads, int steps) {
  Scene scene = test::bareScene(rows, cols);
  test::enable(scene, SpringType::Stretch, 1e4, 0.02);
  test::enable(scene, SpringType::Shear, 1e3, 0.01);
  test::enable(scene, SpringType::Bend, 1.0, 0.0);
  scene.damping_model = DampingModel::RelativeVelocity;
  scene.gravity = Vec3(0.0, 0.0, -9.81);
  scene.pins = {0, cols - 1};
  scene.solver.method = Method::Bdf2;
  scene.solver.newton_max_iterations = 1;
  scene.solver.dt = 1.0 / 160;
  scene.solver.tolerance = 1e-2;
  scene.solver.preconditioner = p;
  scene.solver.recovery = false;
  scene.solver.threads = threads;
  Simulation sim(scene);
  for (int k = 0; k < steps; ++k) EXPECT_TRUE(sim.step().ok) << "step " << k;
  return sim;
}

TEST(Threads, SweepsAndProductsGiveTheSameBitsOnAnyCount) {
  Simulation sim = swungCloth(40, 36, Preconditioner::BlockJacobi, 1, 20);
  const Model& model = sim.model();
  const VecX& x = sim.positions();
  const VecX& v = sim.velocities();
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  VecX w(x.size()), p(x.size());
  for (int k = 0; k < w.size(); ++k) w[k] = noise(rng), p[k] = noise(rng);

  SystemMatrix A1;
  VecX f1, kw1, y1, yf1, fc1;
  assembleSystem(model, x, v, 0.01, 1e-4, true, A1, f1, &w, &kw1);
  A1.multiplyAll(p, y1);
  computeForces(model, x, v, fc1);
  for (int threads : {2, 3, 4}) {
    SystemMatrix A;
    VecX f, kw, y, fc;
    A.setThreads(threads);
    assembleSystem(model, x, v, 0.01, 1e-4, true, A, f, &w, &kw, nullptr, false, threads);
    A.multiplyAll(p, y);
    computeForces(model, x, v, fc, nullptr, threads);
    EXPECT_TRUE(sameBits(f, f1)) << threads << " threads: forces of the assembly";
    EXPECT_TRUE(sameBits(kw, kw1)) << threads << " threads: K w";
    EXPECT_TRUE(sameBits(y, y1)) << threads << " threads: A p";
    EXPECT_TRUE(sameBits(fc, fc1)) << threads << " threads: computeForces";
  }
  // The float product too (CG's relaxed products), split by component.
  const int n = model.numNodes();
  std::vector<double> ps(3 * n), ys1(3 * n), ys2(3 * n);
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) ps[c * n + i] = p[3 * i + c];
  }
  SystemMatrix A2;
  VecX f2;
  A2.setThreads(2);
  assembleSystem(model, x, v, 0.01, 1e-4, true, A2, f2, nullptr, nullptr, nullptr, false, 2);
  SystemMatrix A1f;
  VecX f1f;
  assembleSystem(model, x, v, 0.01, 1e-4, true, A1f, f1f);
  A1f.multiplySplitFloat(ps.data(), ys1.data());
  A2.multiplySplitFloat(ps.data(), ys2.data());
  EXPECT_EQ(0, std::memcmp(ys1.data(), ys2.data(), ys1.size() * sizeof(double)));
}

TEST(Threads, PartedVCycleIsSymmetricAndPositive) {
  Simulation sim = swungCloth(48, 40, Preconditioner::BlockJacobi, 1, 30);
  const Model& model = sim.model();
  const double h = 1.0 / 240;
  SystemMatrix A;
  VecX f;
  assembleSystem(model, sim.positions(), sim.velocities(), h, h * h, true, A, f);
  std::vector<char> free(model.numNodes(), 1);
  free[0] = free[39] = 0;
  const int dim = 3 * model.numNodes();
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  auto random = [&] {
    VecX r(dim);
    for (int k = 0; k < dim; ++k) r[k] = noise(rng);
    r.segment<3>(0).setZero();
    r.segment<3>(3 * 39).setZero();
    return r;
  };
  for (int threads : {2, 3}) {
    MultigridPreconditioner mg;
    mg.setThreads(threads);
    ASSERT_TRUE(mg.setup(A, model.springs, free, 48, 40));
    for (int trial = 0; trial < 3; ++trial) {
      const VecX r1 = random(), r2 = random();
      VecX z1, z2;
      mg.apply(r1, z1);
      mg.apply(r2, z2);
      EXPECT_NEAR(r1.dot(z2), r2.dot(z1), 1e-12 * r1.norm() * z2.norm()) << threads << " threads";
      EXPECT_GT(r1.dot(z1), 0.0);
      EXPECT_GT(r2.dot(z2), 0.0);
    }
  }
  // And CG with it solves the system: the same answer as one thread's.
  const VecX b = random();
  VecX x1 = VecX::Zero(dim), x2 = VecX::Zero(dim);
  CgWorkspace ws1, ws2;
  ws1.grid_rows = ws2.grid_rows = 48;
  ws1.grid_cols = ws2.grid_cols = 40;
  ws2.threads = 2;
  const CgResult one = conjugateGradient(A, model.springs, free, b, x1, Preconditioner::Multigrid,
                                         1e-10, 500, ws1);
  const CgResult two = conjugateGradient(A, model.springs, free, b, x2, Preconditioner::Multigrid,
                                         1e-10, 500, ws2);
  ASSERT_TRUE(one.converged);
  ASSERT_TRUE(two.converged);
  EXPECT_LT((x2 - x1).norm(), 1e-8 * x1.norm());
  EXPECT_LE(two.iterations, one.iterations + 2);
}

TEST(Threads, TwoThreadsFollowOne) {
  // Block Jacobi: every number as on one thread.
  const Simulation bj1 = swungCloth(40, 32, Preconditioner::BlockJacobi, 1, 40);
  const Simulation bj2 = swungCloth(40, 32, Preconditioner::BlockJacobi, 2, 40);
  EXPECT_TRUE(sameBits(bj1.positions(), bj2.positions()));
  EXPECT_TRUE(sameBits(bj1.velocities(), bj2.velocities()));
  // Multigrid: another preconditioner, the same steps to CG's tolerance (1e-2
  // here, so within the step's own error; a mm on this 1 m cloth).
  const Simulation mg1 = swungCloth(40, 32, Preconditioner::Multigrid, 1, 40);
  const Simulation mg2 = swungCloth(40, 32, Preconditioner::Multigrid, 2, 40);
  const VecX d = mg2.positions() - mg1.positions();
  EXPECT_LT(d.cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_GT(d.cwiseAbs().maxCoeff(), 0.0);  // the parted smoother did run
}

TEST(Threads, SceneFieldIsCheckedAndNamed) {
  const std::string base = "cloth: {rows: 3, cols: 3}\nsolver: {method: bdf2, threads: ";
  EXPECT_EQ(parseScene(base + "2}").solver.threads, 2);
  EXPECT_EQ(parseScene("cloth: {rows: 3, cols: 3}").solver.threads, 1);
  auto message = [&](const std::string& value) {
    try {
      parseScene(base + value + "}");
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("0").find("solver.threads: must be >= 1, got 0"), std::string::npos);
  EXPECT_NE(message("65").find("solver.threads: must be <= 64, got 65"), std::string::npos);
  EXPECT_NE(message("1.5").find("solver.threads: expected an integer"), std::string::npos);
  EXPECT_NE(message(".nan").find("solver.threads"), std::string::npos);
}

}  // namespace
}  // namespace cloth_sim
