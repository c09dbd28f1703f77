// Smoothed Coulomb friction against colliders (contact.friction_smoothing):
// IPC's f1 below the smoothing speed eps, Coulomb's mu f_n above it. Exact
// discrete answers of backward Euler on a plane, the law's derivatives
// against finite differences, and the stiffened cloth on a table's edge
// (contact hard case c4) without the stick/slip chatter of exact Coulomb.
// Smoothed throughout (exact_sticking: false), and the default: exact
// sticking at rest, smoothed in every step where a contact slides.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cloth_sim/contact.hpp"
#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

using test::bareScene;
using test::floorPlane;

constexpr double kThickness = 0.002;
constexpr double kG = 9.81;
constexpr double kEps = 1e-3;  // m/s

/// Particles on a floor, friction smoothed throughout (exact_sticking false)
/// or with the default settings (exact sticking at rest, eps = kEps).
Scene particlesOnFloor(double mu, Method method, bool exact_sticking = false) {
  Scene s = bareScene(3, 3);
  s.cloth.origin = Vec3(0.0, 0.0, kThickness);
  s.contact.thickness = kThickness;
  s.contact.friction_smoothing = kEps;
  s.contact.exact_sticking = exact_sticking;
  s.colliders = {floorPlane(mu)};
  s.solver.method = method;
  s.solver.dt = 0.01;
  return s;
}

TEST(SmoothedFriction, SignRisesFromZeroToOneWithSlopeTwoOverEps) {
  EXPECT_EQ(ContactSet::smoothedSign(0.0, kEps), 0.0);
  EXPECT_EQ(ContactSet::smoothedSign(kEps, kEps), 1.0);
  EXPECT_EQ(ContactSet::smoothedSign(5.0 * kEps, kEps), 1.0);
  EXPECT_NEAR(ContactSet::smoothedSign(0.5 * kEps, kEps), 0.75, 1e-15);
  const double d = 1e-9;
  EXPECT_NEAR(ContactSet::smoothedSign(d, kEps) / d, 2.0 / kEps, 1e-3);
  for (double y = 0.0; y < 2.0 * kEps; y += 0.01 * kEps) {  // monotone
    EXPECT_LE(ContactSet::smoothedSign(y, kEps), ContactSet::smoothedSign(y + 1e-6, kEps));
  }
}

// Held by friction within its cone (mu > tan theta), a particle creeps at
// the speed where mu f_n f1(u) balances the tangential load:
// f1(u) = tan(theta) / mu, u = eps (1 - sqrt(1 - tan(theta) / mu)), and
// never faster. Exact Coulomb holds it still (test_contact.cpp).
TEST(SmoothedFriction, WithinTheConeAParticleCreepsAtTheBalancedSpeed) {
  const double theta = 0.3, mu = 0.35;
  const double creep = kEps * (1.0 - std::sqrt(1.0 - std::tan(theta) / mu));
  for (Method m : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene s = particlesOnFloor(mu, m);
    s.gravity = kG * Vec3(std::sin(theta), 0.0, -std::cos(theta));
    Simulation sim(s);
    for (int n = 0; n < 200; ++n) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << st.failure;
      // The landing step (friction's normal force not known yet, then
      // stopping a slide) may be halved under Newton (contact.cpp, law).
      if (n > 0) EXPECT_EQ(st.rejected, 0) << toString(m) << " step " << n;
      for (int i = 0; i < sim.numNodes(); ++i) {
        // Backward Euler approaches it from below (bdf2 may overshoot it).
        if (m != Method::Bdf2) {
          ASSERT_LE(sim.velocities()[3 * i], creep * (1.0 + 1e-6)) << toString(m) << " step " << n;
        }
        ASSERT_NEAR(sim.position(i).z(), kThickness, 1e-12);
      }
    }
    for (int i = 0; i < sim.numNodes(); ++i) {
      EXPECT_NEAR(sim.velocities()[3 * i], creep, 1e-8 * creep) << toString(m);
    }
  }
}

// Beyond the cone the slip soon exceeds eps, where f1 = 1: from the second
// step on backward Euler's answer is exact Coulomb's, v_{n+1} = v_n + h a,
// a = g (sin - mu cos) (Newton solves f1 exactly at its iterates). By
// default the first step smooths too (a sticking node outside its cone
// smooths the step).
void expectSlidingAsUnderCoulomb(bool exact_sticking) {
  const double theta = 0.3, mu = 0.1;
  const double a = kG * (std::sin(theta) - mu * std::cos(theta));
  for (Method m : {Method::Newton, Method::ImplicitEuler}) {
    Scene s = particlesOnFloor(mu, m, exact_sticking);
    s.gravity = kG * Vec3(std::sin(theta), 0.0, -std::cos(theta));
    Simulation sim(s);
    const double h = s.solver.dt;
    ASSERT_TRUE(sim.step().ok);
    double v = sim.velocities()[0];
    EXPECT_GT(v, kEps);
    for (int n = 0; n < 100; ++n) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << st.failure;
      v += h * a;
      for (int i = 0; i < sim.numNodes(); ++i) {
        ASSERT_NEAR(sim.velocities()[3 * i], v, 1e-9 * v) << toString(m) << " step " << n;
      }
    }
  }
}

TEST(SmoothedFriction, BeyondTheConeAParticleSlidesAsUnderCoulomb) {
  expectSlidingAsUnderCoulomb(false);
}

// The law a Newton iterate sees: the force is minus the potential's
// gradient, and the matrix block minus the force's derivative, checked
// against central differences at slips below, near and above eps.
TEST(SmoothedFriction, ForceAndJacobianMatchTheirPotential) {
  const test::StillFloor floor(0.5, kThickness, kEps);
  const CollidersOverStep& over = floor.over;
  const ConstraintFilter pins(std::vector<char>{1});
  const std::vector<double> mass = {0.01};
  const double h = 0.01;
  const Vec3 gravity(0.0, 0.0, -kG);
  ContactSet contacts;
  contacts.setGrid(1, 1);
  const VecX x0 = Vec3(0.0, 0.0, kThickness);
  contacts.begin(over, pins, x0, VecX::Zero(3), gravity, h);
  ASSERT_TRUE(contacts.holds(0));
  // A pass that pressed with 2 N: friction's cap mu f_n = 1 N from now on.
  const VecX reaction = h * Vec3(0.0, 0.0, 2.0);
  contacts.update(over, pins, mass, x0, x0, VecX::Zero(3), reaction, h, gravity, 1e-12);
  contacts.setFrictionSolve(ContactSet::FrictionSolve::Newton);
  for (const Vec3 slip : {Vec3(0.3 * kEps, 0.2 * kEps, 0.0), Vec3(0.9 * kEps, -0.1 * kEps, 0.0),
                          Vec3(4.0 * kEps, 1.0 * kEps, 0.0)}) {
    const VecX v = slip + Vec3(0.0, 0.0, 0.7);  // the normal part is not friction's
    VecX f = VecX::Zero(3);
    contacts.addFriction(f, 1.0, v);
    EXPECT_NEAR(f.norm(), ContactSet::smoothedSign(slip.norm(), kEps), 1e-12);
    EXPECT_LT(f.dot(slip), 0.0);
    SystemMatrix A;  // only its node blocks are used
    contacts.addFrictionJacobian(A, 1.0, v);
    ASSERT_EQ(A.nodeBlocks().size(), 1u);
    const double d = 1e-6 * kEps;
    for (int k = 0; k < 3; ++k) {
      VecX vp = v, vm = v;
      vp[k] += d;
      vm[k] -= d;
      EXPECT_NEAR(-(contacts.frictionPotential(vp) - contacts.frictionPotential(vm)) / (2 * d),
                  f[k], 1e-6);
      VecX fp = VecX::Zero(3), fm = VecX::Zero(3);
      contacts.addFriction(fp, 1.0, vp);
      contacts.addFriction(fm, 1.0, vm);
      const Vec3 column = -(fp - fm) / (2 * d);
      const Vec3 Ae = A.nodeBlocks()[0].second * Vec3(Vec3::Unit(k));
      EXPECT_LT((column - Ae).norm(), 1e-5 * (2.0 / kEps)) << "column " << k;
    }
    // A descent (a solve stopped on a decrement) takes the same force, and
    // in the matrix the drag f1 / |s| on the whole tangent plane: at least
    // the derivative along the slip (f1' <= f1 / |s|), equal to it across.
    contacts.setFrictionSolve(ContactSet::FrictionSolve::Descent);
    VecX f_descent = VecX::Zero(3);
    contacts.addFriction(f_descent, 1.0, v);
    EXPECT_LT((f_descent - f).norm(), 1e-12);
    SystemMatrix D;
    contacts.addFrictionJacobian(D, 1.0, v);
    ASSERT_EQ(D.nodeBlocks().size(), 1u);
    const Mat3 drag = D.nodeBlocks()[0].second.toMat3();
    const double s = slip.norm(), coefficient = ContactSet::smoothedSign(s, kEps) / s;
    const Mat3 tangent = Vec3(1.0, 1.0, 0.0).asDiagonal();
    EXPECT_LT((drag - coefficient * tangent).norm(), 1e-9 * coefficient);
    const Mat3 exact = A.nodeBlocks()[0].second.toMat3();
    const Vec3 along = slip / s;
    EXPECT_LE(along.dot(exact * along), along.dot(drag * along) * (1.0 + 1e-12));
    contacts.setFrictionSolve(ContactSet::FrictionSolve::Newton);
  }
}

// The fold demo with smoothed friction: its towel at rest takes one
// contact pass a step where exact Coulomb takes three (the stick/slip
// chatter of its table contacts), and its stretch-2800 variant lays the
// towel without a rejected step (with f1' in the refined steps' Newton
// instead of the drag, it stalled stopping sliding nodes and was halved).
TEST(SmoothedFriction, FoldedTowelAtRestTakesOnePassAStep) {
  for (double stretch : {3000.0, 2800.0}) {
    Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/fold.yaml");
    s.contact.friction_smoothing = kEps;
    s.contact.exact_sticking = false;
    s.springs[static_cast<int>(SpringType::Stretch)].stiffness = stretch;
    Simulation sim(s);
    long rest_passes = 0, rest_steps = 0;
    while (sim.time() < 4.0 - 1e-9) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << st.failure;
      EXPECT_EQ(st.rejected, 0) << "stretch " << stretch << " t = " << sim.time();
      if (sim.time() > 3.0) rest_passes += st.contact_passes, ++rest_steps;
    }
    EXPECT_LT(static_cast<double>(rest_passes) / rest_steps, 1.2) << "stretch " << stretch;
  }
}

// Contact hard case c4 (a cloth on a table's edge stiffened from 1e3 to
// 1e8 N/m): with exact Coulomb, nodes on the cone's boundary flip between
// stick and slip at every pass, and the stepper rejects steps by the
// hundred (bdf2: 208 in 2 s, 44 s; 7-15 passes a step). Smoothed, no step
// is rejected, the passes stay few, and the cloth stays on the table:
// smoothed throughout, and by default (exact sticking at rest; its scene
// names no friction settings; session 46: bdf2 180 rejected, 3.3 s with
// exact Coulomb -> 0, 0.19 s).
TEST(SmoothedFriction, StiffenedClothOnATableRunsWithoutRejectedSteps) {
  for (const bool exact_sticking : {false, true})
  for (Method m : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    SCOPED_TRACE(exact_sticking ? "exact sticking at rest (default)" : "smoothed throughout");
    Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) +
                        "/config/scenes/hard/contact/c4_stiffen_on_table.yaml");
    s.solver.method = m;
    EXPECT_EQ(s.contact.friction_smoothing, kEps) << "the default";
    s.contact.exact_sticking = exact_sticking;
    Simulation sim(s);
    long passes = 0;
    VecX before;  // at the stiffening (t = 0.8 s)
    for (int n = 0; n < 200; ++n) {
      if (n == 80) before = sim.positions();
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << toString(m) << " step " << n << ": " << st.failure;
      EXPECT_EQ(st.rejected, 0) << toString(m) << " step " << n;
      EXPECT_LE(st.max_penetration, 1e-6);
      passes += st.contact_passes;
    }
    // newton and bdf2 take an exploring pass (Stepper::step) and one to the
    // tolerance where the first does not converge in its iterations.
    const double pass_bound = m == Method::ImplicitEuler ? 2.0 : 3.0;
    EXPECT_LT(static_cast<double>(passes) / 200, pass_bound) << toString(m);
    // The half on the table top contracts by its sag's strain (2e-3 of
    // 0.3 m) when stiffened; friction holds it there (exact Coulomb: 1.1 mm
    // under implicit_euler; frictionless, it slides off the edge).
    int on_top = 0;
    for (int i = 0; i < sim.numNodes(); ++i) {
      const Vec3 p = before.segment<3>(3 * i);
      if (p.z() > 0.8025 || p.x() > 0.5) continue;
      ++on_top;
      EXPECT_LT((sim.position(i) - p).head<2>().norm(), 1e-3) << toString(m) << " node " << i;
    }
    EXPECT_GT(on_top, 80);
  }
}

TEST(SmoothedFriction, SceneRefusesANegativeOrNonFiniteSmoothing) {
  const std::string base = "cloth: {rows: 2, cols: 2}\ncontact: {friction_smoothing: ";
  for (const char* bad : {"-1e-3", ".nan", ".inf"}) {
    try {
      parseScene(base + bad + "}\n");
      ADD_FAILURE() << bad << " accepted";
    } catch (const SceneError& e) {
      EXPECT_NE(std::string(e.what()).find("contact.friction_smoothing"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_EQ(parseScene(base + "2e-3}\n").contact.friction_smoothing, 2e-3);
  EXPECT_EQ(parseScene(base + "0}\n").contact.friction_smoothing, 0.0);
  const Scene defaults = parseScene("cloth: {rows: 2, cols: 2}\n");
  EXPECT_EQ(defaults.contact.friction_smoothing, kEps);
  EXPECT_TRUE(defaults.contact.exact_sticking);
  EXPECT_FALSE(parseScene("cloth: {rows: 2, cols: 2}\ncontact: {exact_sticking: false}\n")
                   .contact.exact_sticking);
  try {
    parseScene("cloth: {rows: 2, cols: 2}\ncontact: {exact_sticking: 2}\n");
    ADD_FAILURE() << "exact_sticking: 2 accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("contact.exact_sticking"), std::string::npos) << e.what();
  }
}

// ---- The default: exact sticking at rest, smoothed in motion ----

// Inside the cone nothing slides, so every step is exact Coulomb's: the
// particles stand still to round-off (smoothed throughout they creep,
// WithinTheConeAParticleCreepsAtTheBalancedSpeed).
TEST(DefaultFriction, InsideTheConeAParticleStandsStill) {
  const double theta = 0.3, mu = 0.35;  // tan(0.3) = 0.309 < mu
  for (Method m : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene s = particlesOnFloor(mu, m, true);
    s.gravity = kG * Vec3(std::sin(theta), 0.0, -std::cos(theta));
    Simulation sim(s);
    const VecX x0 = sim.positions();
    for (int n = 0; n < 100; ++n) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << st.failure;
      EXPECT_EQ(st.contact_passes, 1) << toString(m) << " step " << n;
    }
    EXPECT_LE((sim.positions() - x0).lpNorm<Eigen::Infinity>(), 1e-12) << toString(m);
  }
}

TEST(DefaultFriction, BeyondTheConeAParticleSlidesAsUnderCoulomb) {
  expectSlidingAsUnderCoulomb(true);
}

// A slide that friction stops ends stuck, exactly: once a step ends below
// eps the node sticks at the next, and then it does not move at all.
TEST(DefaultFriction, ASlideFrictionStopsEndsStuckExactly) {
  for (Method m : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene s = particlesOnFloor(0.4, m, true);
    s.gravity = Vec3(0.0, 0.0, -kG);
    s.initial.velocity = Vec3(1.5, 0.0, 0.0);  // stops after ~0.38 s
    Simulation sim(s);
    const double x0 = sim.position(0).x();
    for (int n = 0; n < 60; ++n) ASSERT_TRUE(sim.step().ok) << toString(m);
    const VecX stopped = sim.positions();
    for (int n = 0; n < 40; ++n) ASSERT_TRUE(sim.step().ok) << toString(m);
    EXPECT_LE((sim.positions() - stopped).lpNorm<Eigen::Infinity>(), 1e-12) << toString(m);
    EXPECT_LE(sim.velocities().lpNorm<Eigen::Infinity>(), 1e-12) << toString(m);
    // Where backward Euler with exact Coulomb stops it (v <- max(v - h mu
    // g, 0)), to within a step's travel at the smoothing speed.
    if (m == Method::Bdf2) continue;
    double v = 1.5, x = 0.0;
    while (v > 0.0) v = std::max(v - 0.01 * 0.4 * kG, 0.0), x += 0.01 * v;
    EXPECT_NEAR(sim.position(0).x() - x0, x, 10 * 0.01 * kEps)
        << toString(m);
  }
}

// A linearly implicit step (one Newton iteration, as the drop scenes' bdf2)
// takes friction along the slip as a drag f1(|s|) / |s| (FrictionSolve::
// Descent): a slide friction stops within the step slows to rest and is
// never pushed back. And the pass after a landing node's sticking pass
// starts from the predictor, not from that pass's zero slip. With f1' (0 beyond eps) its one solve held the friction
// constant through the stop, reversed the slide, and the energy check
// rejected the step (a cloth dropped on a table, drop32 under bdf2: 8
// rejected sub-steps in 1 s, none with the drag).
TEST(DefaultFriction, OneNewtonIterationStopsASlideWithoutPushingItBack) {
  for (Method m : {Method::Newton, Method::Bdf2}) {
    for (const double speed : {0.05, 0.2, 1.0}) {
      Scene s = particlesOnFloor(0.4, m, true);
      s.gravity = Vec3(0.0, 0.0, -kG);
      s.solver.newton_max_iterations = 1;
      s.initial.velocity = Vec3(speed, 0.0, 0.0);
      Simulation sim(s);
      double kinetic = 0.5 * speed * speed;  // the fastest node's, per unit mass
      const double h = s.solver.dt;
      for (int n = 0; n < 100; ++n) {
        const StepStats st = sim.step();
        ASSERT_TRUE(st.ok) << toString(m) << " step " << n << ": " << st.failure;
        // The landing step slows at most as much as Coulomb's v - h mu g
        // (one iteration of the drag, lagged at the start, slows less), not
        // held by the drag 2 / eps of the sticking pass's zero slip (1 m/s
        // became 0.013).
        if (n == 0) {
          EXPECT_GE(sim.velocities()[0], speed - h * 0.4 * kG - 1e-9) << toString(m);
          EXPECT_LT(sim.velocities()[0], speed) << toString(m);
        }
        EXPECT_EQ(st.rejected, 0) << toString(m) << " " << speed << " m/s, step " << n;
        double most = 0.0;
        for (int i = 0; i < sim.numNodes(); ++i) {
          const Vec3 v = sim.velocities().segment<3>(3 * i);
          // (bdf2 may overshoot the stop by less than eps, as within the cone.)
          ASSERT_GE(v.x(), m == Method::Bdf2 ? -kEps : 0.0)
              << toString(m) << " " << speed << " m/s, step " << n;
          most = std::max(most, 0.5 * v.squaredNorm());
        }
        ASSERT_LE(most, kinetic * (1.0 + 1e-12)) << toString(m) << " " << speed << " m/s, step " << n;
        kinetic = most;
      }
      EXPECT_LE(sim.velocities().lpNorm<Eigen::Infinity>(), 1e-12) << toString(m) << " " << speed;
    }
  }
}

// The same on a cloth dropped onto a table (config/scenes/drop32.yaml: bdf2
// at dt 1/160, one Newton iteration): its skirts swing and settle without a
// step that gains energy. Once it rests, its wrinkles' nodes just above the
// table are not predicted onto it at every step (ContactSet::begin): each was
// pulled down against its springs and let go, a contact pass more a step
// (3.0 passes a step in the last second, 2.05 now).
TEST(DefaultFriction, AClothSettlingOnATableRejectsNoStepAndRestsInFewPasses) {
  Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/drop32.yaml");
  ASSERT_EQ(s.solver.newton_max_iterations, 1);
  Simulation sim(s);
  int rejected = 0, late_steps = 0, late_passes = 0;
  while (sim.time() < 3.0 - 1e-9) {
    const StepStats st = sim.step();
    ASSERT_TRUE(st.ok) << "t = " << sim.time() << ": " << st.failure;
    rejected += st.rejected;
    if (sim.time() > 2.0) {
      ++late_steps;
      late_passes += st.contact_passes;
    }
  }
  EXPECT_EQ(rejected, 0);
  EXPECT_GT(sim.lastStats().contacts, 100);  // it lies on the table
  const double passes = static_cast<double>(late_passes) / late_steps;
  EXPECT_LT(passes, 2.6);
  std::printf("[ drop32   ] %d rejected sub-steps, %.2f contact passes a step at rest\n", rejected,
              passes);
}

// Contact hard case c3: a cloth on a table dragged by one corner at 1 m/s
// across it and over its edge. With exact stick/slip states each contact
// pass freed only the ring of sticking nodes the last one loaded, and
// after the refining passes the rest were held: the cloth strained to
// 0.52 (implicit_euler), 0.92 (newton), 0.56 (bdf2) against its stuck
// neighbours. By default the first node outside its cone smooths the step
// and one solve finds every node that slides: 0.034-0.049 (session 46).
TEST(DefaultFriction, AClothDraggedAcrossATableDoesNotStretch) {
  for (Method m : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) +
                        "/config/scenes/hard/contact/c3_edge_drag.yaml");
    s.solver.method = m;
    Simulation sim(s);
    double strain = 0.0;
    while (sim.time() < 2.5 - 1e-9) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << toString(m) << " t = " << sim.time() << ": " << st.failure;
      strain = std::max(strain, sim.maxStrain());
    }
    EXPECT_LT(strain, 0.08) << toString(m);
    std::printf("[ drag     ] %s: max strain %.4f\n", toString(m), strain);
  }
}

}  // namespace
}  // namespace cloth_sim
