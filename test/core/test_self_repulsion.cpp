// Self-repulsion terms (self_repulsion.hpp): forces are minus the energy's
// gradient and friction minus its potential's, the system matrix's pair
// terms are the forces' Jacobian (by finite differences), the
// preconditioners' diagonal holds their node blocks, and a linearized
// step's active set follows its answer.
#include <gtest/gtest.h>

#include <random>

#include "cloth_sim/constraint_filter.hpp"
#include "cloth_sim/forces.hpp"
#include "cloth_sim/linear_solver.hpp"
#include "cloth_sim/self_repulsion.hpp"
#include "cloth_sim/system_matrix.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

/// Three terms on a 4 x 4 cloth: a point over a triangle, two with shared
/// nodes, one beyond its reach at x (it pushes only once closer).
SelfRepulsion someTerms(const VecX& x) {
  SelfRepulsion r;
  auto add = [&](std::array<int, 4> nodes, std::array<double, 4> w, Vec3 n, double reach_over) {
    RepulsionTerm t;
    t.node = nodes;
    t.w = w;
    t.n = n.normalized();
    t.stiffness = 50.0;
    t.reach = t.gap(x) + reach_over;
    r.add(t);
  };
  add({0, 5, 6, 9}, {1.0, -0.2, -0.5, -0.3}, Vec3(0.1, 0.2, 1.0), 1e-3);
  add({5, 10, 11, 15}, {1.0, -0.6, -0.1, -0.3}, Vec3(-0.3, 0.1, 1.0), 2e-3);
  add({3, 6, 7, 12}, {0.7, 0.3, -0.4, -0.6}, Vec3(0.0, 1.0, 0.2), -1e-3);
  return r;
}

TEST(SelfRepulsion, ForcesAreMinusTheEnergyGradient) {
  const Model m = buildModel(test::hangingCloth(4));
  VecX x, v;
  test::perturbedState(m, 3, &x, &v);
  const SelfRepulsion r = someTerms(x);
  VecX f = VecX::Zero(x.size());
  r.addForces(x, v, f);
  ASSERT_GT(f.norm(), 0.0);
  const double e = 1e-7;
  for (int i = 0; i < x.size(); ++i) {
    VecX xp = x, xm = x;
    xp[i] += e, xm[i] -= e;
    const double gradient = (r.energy(xp) - r.energy(xm)) / (2 * e);
    EXPECT_NEAR(-gradient, f[i], 1e-6 * (1.0 + f.norm())) << "coordinate " << i;
  }
}

TEST(SelfRepulsion, PairTermsInTheMatrixAreTheForceJacobianAndItsDiagonalTheirNodeBlocks) {
  const Model m = buildModel(test::hangingCloth(4));
  VecX x, v;
  test::perturbedState(m, 7, &x, &v);
  const SelfRepulsion r = someTerms(x);
  for (bool linearized : {false, true}) {
    SCOPED_TRACE(linearized ? "linearized" : "newton");
    SystemMatrix A, M;
    VecX f, f_m;
    const double b = 0.01;
    assembleSystem(m, x, v, 0.0, 0.0, true, M, f_m);  // M alone
    assembleSystem(m, x, v, 0.0, 0.0, true, A, f);
    VecX w = VecX::Random(x.size()), dfdx_w = VecX::Zero(x.size());
    r.addToSystem(x, v, 0.0, b, linearized, A, f, &w, &dfdx_w);
    // Newton's: the two terms within their reach; linearized: the active
    // ones (all three, as built).
    EXPECT_EQ(A.pairTerms().size(), linearized ? 3u : 2u);
    // J p by central differences of the forces (exact for a linear gap).
    const VecX p = VecX::Random(x.size());
    const double e = 1e-6;
    VecX fp = VecX::Zero(x.size()), fm = VecX::Zero(x.size());
    r.addForces(x + e * p, v, fp);
    r.addForces(x - e * p, v, fm);
    VecX jp = (fp - fm) / (2 * e);
    if (linearized) {  // the third term's quadratic is on, unclamped: its -k (w n)(w n)^T p too
      const RepulsionTerm& t = r.terms()[2];
      const double s = t.stiffness * t.gap(p);
      for (int k = 0; k < 4; ++k) jp.segment<3>(3 * t.node[k]) -= (s * t.w[k]) * t.n;
    }
    VecX ap, mp;
    A.multiplyAll(p, ap);
    M.multiplyAll(p, mp);
    EXPECT_LE((ap - mp + b * jp).norm(), 1e-7 * (b * jp).norm());
    // df/dx w, as the assembly reports it.
    VecX fw = VecX::Zero(x.size()), fmw = VecX::Zero(x.size());
    r.addForces(x + e * w, v, fw);
    r.addForces(x - e * w, v, fmw);
    if (!linearized) EXPECT_LE((dfdx_w - (fw - fmw) / (2 * e)).norm(), 1e-7 * dfdx_w.norm());
    // Block diagonal: the product's on unit vectors at one node.
    for (int node : {0, 5, 6, 12}) {
      for (int c = 0; c < 3; ++c) {
        VecX unit = VecX::Zero(x.size()), column;
        unit[3 * node + c] = 1.0;
        A.multiplyAll(unit, column);
        const Vec3 expected = column.segment<3>(3 * node);
        const Vec3 got = A.fullDiag(node).col(c);
        EXPECT_LE((got - expected).norm(), 1e-12 * expected.norm()) << "node " << node;
      }
    }
  }
}

TEST(SelfRepulsion, TheCholeskyPreconditionerFactorsPairTermsWhole) {
  // Terms much stiffer than the springs and the masses: with only their
  // node blocks in the factor, CG needs many iterations (a heap of layers
  // under the Cholesky preconditioner: four times the self-off count);
  // with their couplings it is A's own factor and one or two do. A second
  // matrix with a term moved to other nodes makes the pattern grow.
  const Model m = buildModel(test::hangingCloth(4));
  VecX x, v;
  test::perturbedState(m, 7, &x, &v);
  SelfRepulsion r = someTerms(x);
  const std::vector<char> free(m.numNodes(), 1);
  const ConstraintFilter filter(free);
  CgWorkspace ws;
  for (int round = 0; round < 2; ++round) {
    SCOPED_TRACE(round);
    if (round == 1) {
      RepulsionTerm t = r.terms()[0];
      t.node = {1, 8, 13, 14};
      r.replace(0, t);
      ASSERT_TRUE(ws.cholesky);
      ws.cholesky->invalidate();  // factored again, on the pattern it has
    }
    SystemMatrix A;
    VecX f;
    assembleSystem(m, x, v, 0.0, 1e-4, true, A, f);
    r.addToSystem(x, v, 0.0, 100.0, true, A, f);
    ASSERT_EQ(A.pairTerms().size(), 3u);
    const VecX rhs = VecX::Random(x.size());
    VecX y = VecX::Zero(x.size());
    const CgResult res = conjugateGradient(A, m.springs, filter, rhs, y, Preconditioner::Cholesky,
                                           1e-10, 200, ws);
    EXPECT_TRUE(res.converged);
    EXPECT_LE(res.iterations, 2);
    VecX ay;
    A.multiplyAll(y, ay);
    EXPECT_LE((ay - rhs).norm(), 1e-9 * rhs.norm());
  }
}

TEST(SelfRepulsion, FrictionIsMinusItsPotentialsGradientAndStiffAtRest) {
  const Model m = buildModel(test::hangingCloth(4));
  VecX x, v;
  test::perturbedState(m, 9, &x, &v);
  SelfRepulsion r = someTerms(x);
  for (int k = 0; k < r.size(); ++k) {
    RepulsionTerm t = r.terms()[k];
    t.friction = 0.3 * (k + 1);
    r.replace(k, t);
  }
  // Slips from sliding (|u| >> the smoothing) to sticking (|u| < it).
  for (double scale : {1.0, 1e-4}) {
    const VecX vs = scale * v;
    ASSERT_TRUE(r.terms()[0].slip(vs).norm() > 0.0);
    VecX f = VecX::Zero(x.size()), f_normal = VecX::Zero(x.size());
    r.addForces(x, vs, f);
    r.addForces(x, VecX::Zero(x.size()), f_normal);  // no slip, no friction
    const VecX friction = f - f_normal;
    ASSERT_GT(friction.norm(), 0.0);
    const double e = 1e-6 * scale;
    for (int i = 0; i < x.size(); ++i) {
      VecX vp = vs, vm = vs;
      vp[i] += e, vm[i] -= e;
      const double gradient = (r.frictionPotential(vp) - r.frictionPotential(vm)) / (2 * e);
      EXPECT_NEAR(-gradient, friction[i], 1e-6 * friction.norm()) << "coordinate " << i;
    }
  }
  // At rest (no slip) the drag is exactly the matrix's block: a df/dv p =
  // -a (2 mu lambda / eps) (w (x) T)(w (x) T)^T p.
  SystemMatrix A, M;
  VecX f, f_m;
  const VecX rest = VecX::Zero(x.size());
  assembleSystem(m, x, rest, 0.0, 0.0, true, M, f_m);
  assembleSystem(m, x, rest, 0.0, 0.0, true, A, f);
  const double a = 0.01;
  r.addToSystem(x, rest, a, 0.0, false, A, f);
  const VecX p = VecX::Random(x.size());
  const double e = 1e-9;  // within the smoothing, where the drag is linear at 0
  VecX fp = VecX::Zero(x.size()), fm = VecX::Zero(x.size());
  r.addForces(x, e * p, fp);
  r.addForces(x, -e * p, fm);
  const VecX jp = (fp - fm) / (2 * e);
  VecX ap, mp;
  A.multiplyAll(p, ap);
  M.multiplyAll(p, mp);
  EXPECT_LE((ap - mp + a * jp).norm(), 1e-6 * (a * jp).norm());
}

TEST(SelfRepulsion, ALinearizedStepsActiveSetFollowsItsAnswer) {
  const Model m = buildModel(test::hangingCloth(4));
  VecX x, v;
  test::perturbedState(m, 5, &x, &v);
  SelfRepulsion r = someTerms(x);
  EXPECT_EQ(r.updateActiveSet(x), 1);  // the third is beyond its reach
  EXPECT_TRUE(r.terms()[0].active && r.terms()[1].active && !r.terms()[2].active);
  // The answer: the first pair separated 2 mm (1 mm beyond its reach), the
  // third came 2 mm closer (1 mm within it), the second's nodes stayed.
  VecX x1 = x;
  x1.segment<3>(0) += 2e-3 * r.terms()[0].n;  // node 0, weight 1
  x1.segment<3>(9) -= (2e-3 / 0.7) * r.terms()[2].n;  // node 3, weight 0.7
  EXPECT_EQ(r.updateActiveSet(x1), 2);
  EXPECT_TRUE(!r.terms()[0].active && r.terms()[1].active && r.terms()[2].active);
  EXPECT_EQ(r.updateActiveSet(x1), 0);  // settled
}

}  // namespace
}  // namespace cloth_sim
