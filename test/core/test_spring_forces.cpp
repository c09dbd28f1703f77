// Analytic spring Jacobians against central finite differences.
#include <gtest/gtest.h>

#include <random>

#include "cloth_sim/spring_forces.hpp"

namespace cloth_sim {
namespace {

struct Case {
  const char* name;
  Vec3 xi, xj, vi, vj;
  double rest_length;
};

std::vector<Case> cases() {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto rnd = [&] { return Vec3(u(rng), u(rng), u(rng)); };
  std::vector<Case> out;
  for (int k = 0; k < 5; ++k) out.push_back({"random", rnd(), rnd(), rnd(), rnd(), 0.7});
  out.push_back({"stretched", Vec3(0, 0, 0), Vec3(1.5, 0.2, -0.1), rnd(), rnd(), 1.0});
  out.push_back({"compressed", Vec3(0, 0, 0), Vec3(0.3, 0.1, 0.05), rnd(), rnd(), 1.0});
  out.push_back({"nearly degenerate", Vec3(0, 0, 0), Vec3(1e-4, -2e-4, 1e-4), rnd(), rnd(), 1.0});
  out.push_back({"zero rest length", Vec3(0, 0, 0), Vec3(0.2, 0.1, -0.3), rnd(), rnd(), 0.0});
  return out;
}

/// Max relative error of analytic vs central-difference blocks, scaled by the block norm.
void expectJacobianMatchesFd(const Case& c, DampingModel model) {
  SpringParams p;
  p.stiffness = 7.0;
  p.damping = 0.9;
  p.rest_length = c.rest_length;
  p.damping_model = model;
  const SpringJacobian J =
      springJacobian(c.xi, c.xj, c.vi, c.vj, p, /*project=*/false, /*damping_dx=*/true);
  const double eps = 1e-6 * std::max(1e-3, (c.xj - c.xi).norm());
  Mat3 K_fd, D_fd;
  for (int a = 0; a < 3; ++a) {
    Vec3 e = Vec3::Zero();
    e[a] = eps;
    K_fd.col(a) = (springForce(c.xi, c.xj + e, c.vi, c.vj, p) -
                   springForce(c.xi, c.xj - e, c.vi, c.vj, p)) / (2 * eps);
    D_fd.col(a) = (springForce(c.xi, c.xj, c.vi, c.vj + e, p) -
                   springForce(c.xi, c.xj, c.vi, c.vj - e, p)) / (2 * eps);
    // df_i/dx_i must be -df_i/dx_j (translation invariance).
    const Vec3 dxi = (springForce(c.xi + e, c.xj, c.vi, c.vj, p) -
                      springForce(c.xi - e, c.xj, c.vi, c.vj, p)) / (2 * eps);
    EXPECT_LE((dxi + K_fd.col(a)).norm(), 1e-6 * std::max(1.0, K_fd.norm())) << c.name;
  }
  EXPECT_LE((J.K - K_fd).norm(), 1e-6 * std::max(1.0, K_fd.norm())) << c.name;
  EXPECT_LE((J.D - D_fd).norm(), 1e-6 * std::max(1.0, D_fd.norm())) << c.name;
}

TEST(SpringJacobian, MatchesFiniteDifferencesAlongSpringDamping) {
  for (const Case& c : cases()) expectJacobianMatchesFd(c, DampingModel::AlongSpring);
}

TEST(SpringJacobian, MatchesFiniteDifferencesRelativeVelocityDamping) {
  for (const Case& c : cases()) expectJacobianMatchesFd(c, DampingModel::RelativeVelocity);
}

TEST(SpringJacobian, ProjectionKeepsStiffnessPositiveSemidefinite) {
  SpringParams p;
  p.stiffness = 100.0;
  p.rest_length = 1.0;
  const Vec3 xi(0, 0, 0), xj(0.2, 0.1, 0.0), v(0, 0, 0);
  const Mat3 K_raw = springJacobian(xi, xj, v, v, p, false).K;
  const Mat3 K = springJacobian(xi, xj, v, v, p, true).K;
  Eigen::SelfAdjointEigenSolver<Mat3> raw(K_raw), projected(K);
  EXPECT_LT(raw.eigenvalues().minCoeff(), -1.0);  // indefinite without projection
  EXPECT_GE(projected.eigenvalues().minCoeff(), -1e-12);
  // Along the axis, projection changes nothing.
  const Vec3 u = (xj - xi).normalized();
  EXPECT_NEAR(u.dot(K * u), u.dot(K_raw * u), 1e-12);
}

TEST(SpringJacobian, StretchedSpringUnchangedByProjection) {
  SpringParams p;
  p.stiffness = 100.0;
  p.rest_length = 1.0;
  const Vec3 xi(0, 0, 0), xj(1.3, 0.1, 0.0), v(0, 0, 0);
  EXPECT_EQ(springJacobian(xi, xj, v, v, p, false).K, springJacobian(xi, xj, v, v, p, true).K);
}

TEST(SpringForce, ZeroLengthSpringIsFiniteAndPushesAlongRestAxis) {
  SpringParams p;
  p.stiffness = 10.0;
  p.damping = 1.0;
  p.rest_length = 0.5;
  p.rest_direction = Vec3(0, 1, 0);
  const Vec3 x(1, 2, 3), v(0.1, 0, 0);
  const Vec3 f = springForce(x, x, v, -v, p);
  ASSERT_TRUE(f.allFinite());
  // f_i = k (0 - L) u: node i pushed away from j, along -u.
  EXPECT_NEAR(f.y(), -10.0 * 0.5, 1e-12);
  const SpringJacobian J = springJacobian(x, x, v, -v, p, false, true);
  EXPECT_TRUE(J.K.allFinite());
  EXPECT_TRUE(J.D.allFinite());
}

TEST(SpringForce, HookeanMagnitudeAndEnergy) {
  SpringParams p;
  p.stiffness = 20.0;
  p.rest_length = 1.0;
  const Vec3 xi(0, 0, 0), xj(0, 0, 1.25), v(0, 0, 0);
  EXPECT_NEAR(springForce(xi, xj, v, v, p).z(), 20.0 * 0.25, 1e-14);
  EXPECT_NEAR(springEnergy(xi, xj, p), 0.5 * 20.0 * 0.0625, 1e-14);
}

}  // namespace
}  // namespace cloth_sim

// The whole-cloth assembly fuses force and Jacobian for speed; it must agree
// with the per-spring functions tested above.
#include "cloth_sim/forces.hpp"
#include "scene_builders.hpp"

#include <cmath>
#include <cstring>

namespace cloth_sim {
namespace {

TEST(Assembly, MatchesPerSpringForcesAndJacobians) {
  for (DampingModel dm : {DampingModel::AlongSpring, DampingModel::RelativeVelocity}) {
    for (bool project : {true, false}) {
      Scene s = test::hangingCloth(5);
      s.damping_model = dm;
      s.air_drag = 0.3;
      const Model m = buildModel(s);
      VecX x, v, w;
      test::perturbedState(m, 9, &x, &v, &w);  // with one zero-length spring
      SystemMatrix A;
      VecX f, dfdx_w, f_ref;
      const double a = 0.01, b = 1e-4;
      assembleSystem(m, x, v, a, b, project, A, f, &w, &dfdx_w);
      computeForces(m, x, v, f_ref);
      EXPECT_LE((f - f_ref).norm(), 1e-12 * f_ref.norm());
      VecX dfdx_w_ref = VecX::Zero(x.size());
      for (size_t k = 0; k < m.springs.size(); ++k) {
        const Spring& sp = m.springs[k];
        const SpringParams p = springParams(m, sp);
        const SpringJacobian J = springJacobian(x.segment<3>(3 * sp.i), x.segment<3>(3 * sp.j),
                                                v.segment<3>(3 * sp.i), v.segment<3>(3 * sp.j), p, project);
        EXPECT_LE((A.coupling(static_cast<int>(k)) - (a * J.D + b * J.K)).norm(), 1e-12 * (1.0 + J.K.norm()));
        const Vec3 t = J.K * (w.segment<3>(3 * sp.j) - w.segment<3>(3 * sp.i));
        dfdx_w_ref.segment<3>(3 * sp.i) += t;
        dfdx_w_ref.segment<3>(3 * sp.j) -= t;
      }
      EXPECT_LE((dfdx_w - dfdx_w_ref).norm(), 1e-12 * (1.0 + dfdx_w_ref.norm()));
      EXPECT_NEAR(A.diag(0)(0, 0), m.mass[0] + a * 0.3, 1e-15);
    }
  }
}

// Newton's steppers hold along-spring damping on the axes of the step's start
// (Stepper::newtonSolve): the force is then linear in v and its damping does
// not depend on x, so the assembled A = M - a df/dv - b df/dx is exactly the
// derivative of the force, damping included (without projection). Checked
// against central differences of computeForces on the same held axes, from
// a state other than the one the axes came from.
TEST(Assembly, HeldDampingAxesGiveTheExactDerivative) {
  Scene s = test::hangingCloth(5);
  s.damping_model = DampingModel::AlongSpring;
  s.air_drag = 0.3;
  const Model m = buildModel(s);
  VecX x0, v0, x, v, w;
  test::perturbedState(m, 4, &x0, &v0);
  test::perturbedState(m, 9, &x, &v, &w);
  x.segment<3>(3 * 7) += Vec3(0.05, 0.02, -0.03);  // no zero-length spring: smooth for the differences
  std::vector<Vec3> axes;
  springAxes(m, x0, axes);
  SystemMatrix A;
  VecX f, f_ref, Aw;
  const double a = 0.01, b = 1e-4;
  assembleSystem(m, x, v, a, b, /*project_compression=*/false, A, f, nullptr, nullptr, &axes);
  computeForces(m, x, v, f_ref, &axes);
  EXPECT_LE((f - f_ref).norm(), 1e-12 * f_ref.norm());
  // The held axes change the force: this is not the plain one.
  VecX f_plain;
  computeForces(m, x, v, f_plain);
  EXPECT_GT((f - f_plain).norm(), 1e-6 * f.norm());
  A.multiplyAll(w, Aw);
  const double eps = 1e-6;
  VecX fp, fm, dfdv_w, dfdx_w;
  computeForces(m, x, v + eps * w, fp, &axes);
  computeForces(m, x, v - eps * w, fm, &axes);
  dfdv_w = (fp - fm) / (2 * eps);
  computeForces(m, x + eps * w, v, fp, &axes);
  computeForces(m, x - eps * w, v, fm, &axes);
  dfdx_w = (fp - fm) / (2 * eps);
  VecX expected = -a * dfdv_w - b * dfdx_w;
  for (int i = 0; i < m.numNodes(); ++i) expected.segment<3>(3 * i) += m.mass[i] * w.segment<3>(3 * i);
  EXPECT_LE((Aw - expected).norm(), 1e-7 * expected.norm());
  // The Cholesky and multigrid read A through its blocks: they agree with the product.
  VecX Aw_blocks = VecX::Zero(x.size());
  for (int i = 0; i < m.numNodes(); ++i) Aw_blocks.segment<3>(3 * i) = A.fullDiag(i) * w.segment<3>(3 * i);
  for (size_t k = 0; k < m.springs.size(); ++k) {
    const Spring& sp = m.springs[k];
    const Mat3 S = A.coupling(static_cast<int>(k));
    Aw_blocks.segment<3>(3 * sp.i) -= S * w.segment<3>(3 * sp.j);
    Aw_blocks.segment<3>(3 * sp.j) -= S * w.segment<3>(3 * sp.i);
  }
  EXPECT_LE((Aw_blocks - Aw).norm(), 1e-12 * Aw.norm());
}

}  // namespace
}  // namespace cloth_sim

namespace cloth_sim {
namespace {

/// Everything an assembly writes that a solve reads, as bits.
struct AssemblyOut {
  VecX f, kv, Ap_double, Ap_float;
};

AssemblyOut assembleAt(const Model& m, const VecX& x, const VecX& v, SystemMatrix& A) {
  AssemblyOut o;
  const double h = 0.01;
  assembleSystem(m, x, v, h, h * h, /*project_compression=*/true, A, o.f, &v, &o.kv);
  const int n = m.numNodes();
  std::vector<double> p(3 * n), y(3 * n);
  for (int k = 0; k < 3 * n; ++k) p[k] = std::sin(0.7 * k);
  A.multiplySplit(p.data(), y.data());
  o.Ap_double = Eigen::Map<VecX>(y.data(), 3 * n);
  A.multiplySplitFloat(p.data(), y.data());
  o.Ap_float = Eigen::Map<VecX>(y.data(), 3 * n);
  return o;
}

bool bitwiseEqual(const VecX& a, const VecX& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

// implicit_euler's assembly takes two shortcuts (forces.cpp): it reads the
// spring lengths measureEnergy took at the same x, and it writes the float
// coefficients itself once a product went float. Neither may change a bit:
// checked against an assembly that took neither, on a cloth with a
// zero-length spring (the sweep's second, degenerate-aware pass) and without.
TEST(Assembly, ShortcutsChangeNoBit) {
  Scene s = test::hangingCloth(6);
  s.damping_model = DampingModel::RelativeVelocity;  // the loop that reads lengths
  s.air_drag = 0.2;
  const Model m = buildModel(s);
  for (bool degenerate : {false, true}) {
    SCOPED_TRACE(degenerate ? "a zero-length spring" : "no degenerate spring");
    VecX x, v, other_x, other_v;
    test::perturbedState(m, 5, &x, &v);  // node 7 on node 8
    if (!degenerate) x.segment<3>(3 * 7) += Vec3(0.03, -0.02, 0.01);
    test::perturbedState(m, 6, &other_x, &other_v);
    // Reference: the lengths were measured elsewhere, the matrix is fresh.
    measureEnergy(m, other_x, other_v);
    SystemMatrix fresh;
    const AssemblyOut ref = assembleAt(m, x, v, fresh);
    // Shortcuts: lengths measured at this x, a matrix whose last assembly
    // took a float product (assembleAt's), so this one writes float copies.
    SystemMatrix reused;
    assembleAt(m, other_x, other_v, reused);
    measureEnergy(m, x, v);
    const AssemblyOut got = assembleAt(m, x, v, reused);
    EXPECT_TRUE(bitwiseEqual(got.f, ref.f));
    EXPECT_TRUE(bitwiseEqual(got.kv, ref.kv));
    EXPECT_TRUE(bitwiseEqual(got.Ap_double, ref.Ap_double));
    EXPECT_TRUE(bitwiseEqual(got.Ap_float, ref.Ap_float));
    EXPECT_TRUE(got.f.allFinite() && got.Ap_float.allFinite());
  }
}

}  // namespace
}  // namespace cloth_sim
