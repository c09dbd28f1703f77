// Contact with colliders inside the implicit step: exact discrete answers
// (Coulomb friction on a plane), no penetration, no tunnelling, moving
// colliders, and the failures that must be loud.
#include <gtest/gtest.h>

#include <cmath>

#include "cloth_sim/contact.hpp"
#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

using test::bareScene;
using test::enable;
using test::floorPlane;

constexpr double kThickness = 0.002;
constexpr double kG = 9.81;

/// Particles (no springs) lying on z = 0 at the contact thickness.
/// Exact Coulomb with stick/slip states throughout (friction_smoothing 0):
/// the laws these tests check are its discrete answers. The default
/// (exact at rest, smoothed in motion) is tested in test_smoothed_friction.cpp.
Scene particlesOnFloor(double mu, Method method) {
  Scene s = bareScene(3, 3);
  s.cloth.origin = Vec3(0.0, 0.0, kThickness);
  s.contact.thickness = kThickness;
  s.contact.friction_smoothing = 0.0;
  s.colliders = {floorPlane(mu)};
  s.solver.method = method;
  s.solver.dt = 0.01;
  return s;
}

const Method kImplicit[] = {Method::ImplicitEuler, Method::Newton};

// Gravity tilted by theta on a level plane: backward Euler's exact answer is
// x_n = x0 + 1/2 a t (t + h), a = g (sin - mu cos), while mu < tan theta.
TEST(ContactExact, SlidingOnATiltedPlaneMatchesTheDiscreteAnswer) {
  const double theta = 0.3;
  for (Method m : kImplicit) {
    for (double mu : {0.0, 0.1, 0.25}) {  // tan(0.3) = 0.309
      Scene s = particlesOnFloor(mu, m);
      s.gravity = kG * Vec3(std::sin(theta), 0.0, -std::cos(theta));
      Simulation sim(s);
      const VecX x0 = sim.positions();
      const double h = s.solver.dt;
      const double a = kG * (std::sin(theta) - mu * std::cos(theta));
      for (int n = 1; n <= 100; ++n) {
        const StepStats st = sim.step();
        ASSERT_TRUE(st.ok) << st.failure;
        const double t = n * h;
        for (int i = 0; i < sim.numNodes(); ++i) {
          const double expected = x0[3 * i] + 0.5 * a * t * (t + h);
          ASSERT_NEAR(sim.position(i).x(), expected, 1e-9 * std::abs(expected - x0[3 * i]) + 1e-15)
              << toString(m) << " mu " << mu << " node " << i << " step " << n;
          ASSERT_NEAR(sim.position(i).z(), kThickness, 1e-12);
          ASSERT_NEAR(sim.position(i).y(), x0[3 * i + 1], 1e-12);
        }
        ASSERT_EQ(st.contacts, sim.numNodes());
      }
      EXPECT_NEAR(sim.time(), 1.0, 1e-12);
    }
  }
}

TEST(ContactExact, StickingOnATiltedPlaneDoesNotMove) {
  const double theta = 0.3;
  for (Method m : kImplicit) {
    Scene s = particlesOnFloor(0.35, m);  // > tan(0.3)
    s.gravity = kG * Vec3(std::sin(theta), 0.0, -std::cos(theta));
    Simulation sim(s);
    const VecX x0 = sim.positions();
    for (int n = 0; n < 100; ++n) ASSERT_TRUE(sim.step().ok);
    EXPECT_LE((sim.positions() - x0).lpNorm<Eigen::Infinity>(), 1e-12) << toString(m);
    EXPECT_NEAR(sim.time(), 1.0, 1e-12);
  }
}

// A particle sliding at v0 on a level plane: v <- max(v - h mu g, 0).
TEST(ContactExact, SlidingStopsAfterTheDiscreteDistance) {
  for (Method m : kImplicit) {
    Scene s = particlesOnFloor(0.4, m);
    s.gravity = Vec3(0.0, 0.0, -kG);
    s.initial.velocity = Vec3(1.5, 0.0, 0.0);
    Simulation sim(s);
    const double h = s.solver.dt;
    double v = 1.5, x = sim.position(0).x();
    for (int n = 0; n < 60; ++n) {
      ASSERT_TRUE(sim.step().ok);
      v = std::max(v - h * 0.4 * kG, 0.0);
      x += h * v;
      ASSERT_NEAR(sim.position(0).x(), x, 1e-9) << toString(m) << " step " << n;
      ASSERT_NEAR(sim.velocities()[0], v, 1e-9);
    }
    EXPECT_EQ(v, 0.0);  // it stopped within the run
  }
}

// Free particles thrown sideways onto a frictionless floor. BDF2 (with its
// trapezoidal start) is exact for the parabola of free flight; after the
// inelastic landing each particle must slide on at the thickness with its
// horizontal speed, as backward Euler does. BDF2 extrapolates from the last
// two states, and across the impact that history pointed into the floor:
// it used to pull the particles off it again (a bounce the energy check
// caught and retried as backward Euler).
TEST(ContactExact, Bdf2LandsWithoutABounce) {
  Scene s = particlesOnFloor(0.0, Method::Bdf2);
  const double z0 = 0.1, u = 1.0, h = s.solver.dt;
  s.cloth.origin = Vec3(0.0, 0.0, z0);
  s.gravity = Vec3(0.0, 0.0, -kG);
  s.initial.velocity = Vec3(u, 0.0, 0.0);
  Simulation sim(s);
  const VecX x0 = sim.positions();
  int landed = -1;
  for (int n = 1; n <= 60; ++n) {
    const StepStats st = sim.step();
    ASSERT_TRUE(st.ok) << st.failure;
    EXPECT_EQ(st.rejected + st.order_reduced, 0) << "step " << n;
    const double t = n * h, z = z0 - 0.5 * kG * t * t;
    for (int i = 0; i < sim.numNodes(); ++i) {
      ASSERT_NEAR(sim.position(i).x(), x0[3 * i] + u * t, 1e-12) << "node " << i << " step " << n;
      ASSERT_NEAR(sim.velocities()[3 * i], u, 1e-12) << "node " << i << " step " << n;
      if (z > kThickness) {  // in flight: exact
        ASSERT_NEAR(sim.position(i).z(), z, 1e-12) << "step " << n;
      } else {  // landed: on the floor, at rest along its normal
        ASSERT_NEAR(sim.position(i).z(), kThickness, 1e-12) << "node " << i << " step " << n;
        ASSERT_NEAR(sim.velocities()[3 * i + 2], 0.0, 1e-12) << "node " << i << " step " << n;
        if (landed < 0) landed = n;
      }
    }
  }
  EXPECT_EQ(landed, 15);  // z0 - g t^2 / 2 reaches the thickness at t = 0.142 s
}

TEST(ContactExact, RestingClothCarriesItsWeight) {
  for (Method m : kImplicit) {
    Scene s = bareScene(8, 8);
    enable(s, SpringType::Stretch, 2000.0, 1.0);
    enable(s, SpringType::Shear, 200.0, 0.1);
    enable(s, SpringType::Bend, 2.0, 0.0);
    s.gravity = Vec3(0.0, 0.0, -kG);
    s.cloth.origin = Vec3(0.0, 0.0, kThickness);
    s.contact.thickness = kThickness;
    s.colliders = {floorPlane(0.3)};
    s.solver.method = m;
    Simulation sim(s);
    StepStats st;
    for (int n = 0; n < 20; ++n) {
      st = sim.step();
      ASSERT_TRUE(st.ok) << st.failure;
    }
    const double weight = s.cloth.mass * kG;
    EXPECT_NEAR(st.contact_normal_force, weight, 1e-9 * weight) << toString(m);
    EXPECT_EQ(st.contacts, sim.numNodes());
    EXPECT_LE(sim.maxPenetration(), 1e-12);
  }
}

TEST(ContactExact, NoCollidersRunsNoContactCode) {
  Scene s = particlesOnFloor(0.3, Method::ImplicitEuler);
  s.colliders.clear();
  s.gravity = Vec3(0, 0, -kG);
  Simulation sim(s);
  const StepStats st = sim.step();
  EXPECT_EQ(st.contact_passes, 0);
  EXPECT_EQ(st.contacts, 0);
  EXPECT_LT(sim.position(0).z(), kThickness);  // it fell through where a floor would be
}

/// A 12 x 12 cloth 0.4 m above `collider`'s top, dropped.
Scene drop(const ColliderParams& collider, Method method) {
  Scene s = bareScene(12, 12);
  enable(s, SpringType::Stretch, 3000.0, 0.5);
  enable(s, SpringType::Shear, 300.0, 0.1);
  enable(s, SpringType::Bend, 5.0, 0.01);
  s.gravity = Vec3(0.0, 0.0, -kG);
  s.cloth.width = s.cloth.length = 0.6;
  s.cloth.origin = Vec3(-0.3, 0.3, 0.7);
  s.cloth.mass = 0.1;
  s.contact.thickness = kThickness;
  s.contact.friction = 0.4;
  s.colliders = {floorPlane(), collider};
  s.solver.method = method;
  s.solver.dt = 0.005;
  return s;
}

std::vector<ColliderParams> obstacles() {
  ColliderParams ball;
  ball.name = "ball";
  ball.type = ColliderParams::Type::Sphere;
  ball.center = Vec3(0.0, 0.0, 0.2);
  ball.radius = 0.2;
  ColliderParams box;
  box.name = "box";
  box.type = ColliderParams::Type::Box;
  box.center = Vec3(0.02, -0.01, 0.15);
  box.half_extents = Vec3(0.15, 0.1, 0.15);
  box.rpy = Vec3(0.1, -0.05, 0.6);
  ColliderParams rod;
  rod.name = "rod";
  rod.type = ColliderParams::Type::Capsule;
  rod.a = Vec3(-0.5, 0.05, 0.25);
  rod.b = Vec3(0.5, -0.05, 0.3);
  rod.radius = 0.03;
  return {ball, box, rod};
}

TEST(Contact, DroppedClothRestsOutsideEveryShapeAndNeverGainsEnergy) {
  for (const ColliderParams& obstacle : obstacles()) {
    Simulation sim(drop(obstacle, Method::ImplicitEuler));
    double energy = sim.energy();
    // The core's bound on a step's energy gain: 1e-6 of the energy scale
    // (kinetic + elastic + weight times cloth size), for each sub-step a
    // split step took, plus the step's round-off.
    const double scale = 0.1 * kG * std::hypot(0.6, 0.6);
    for (int n = 0; n < 600; ++n) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << obstacle.name << " step " << n << ": " << st.failure;
      // Static colliders only: energy may only go down.
      ASSERT_LE(sim.energy(), energy + 1e-6 * (scale + sim.kineticEnergy() + sim.elasticEnergy()) *
                                           st.substeps + st.energy_round_off)
          << obstacle.name << " step " << n << " (" << st.substeps << " sub-steps)";
      energy = sim.energy();
    }
    EXPECT_NEAR(sim.time(), 3.0, 1e-9);
    EXPECT_LE(sim.maxPenetration(), 1e-6) << obstacle.name;
    // Every node outside surface + thickness, checked directly.
    for (size_t k = 0; k < sim.colliders().size(); ++k) {
      const Collider& c = sim.colliders()[k];
      for (int i = 0; i < sim.numNodes(); ++i) {
        ASSERT_GE(c.closest(sim.position(i), sim.colliderState(static_cast<int>(k)).pose).distance,
                  kThickness - 1e-6)
            << obstacle.name << " node " << i;
      }
    }
    // It came to rest on the obstacle (not on the floor everywhere).
    // Kinetic energy below 1 % of what the drop released (0.1 kg, ~0.4 m).
    EXPECT_LT(sim.kineticEnergy(), 0.01 * 0.1 * kG * 0.4) << obstacle.name;
    double top = -INFINITY;
    for (int i = 0; i < sim.numNodes(); ++i) top = std::max(top, sim.position(i).z());
    EXPECT_GT(top, 0.2) << obstacle.name;
  }
}

TEST(Contact, NewtonAndBdf2KeepEveryNodeOutside) {
  for (Method m : {Method::Newton, Method::Bdf2}) {
    Simulation sim(drop(obstacles()[0], m));
    for (int n = 0; n < 200; ++n) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << toString(m) << " step " << n << ": " << st.failure;
    }
    EXPECT_LE(sim.maxPenetration(), 1e-6) << toString(m);
  }
}

TEST(Contact, FastNodeDoesNotTunnelThroughAThinBox) {
  // 30 m/s at dt 1/30 s toward a box 1 cm thick: 1 m per step.
  for (Method m : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene s = bareScene(2, 2);
    s.cloth.width = s.cloth.length = 0.1;
    s.cloth.origin = Vec3(-0.05, 0.05, 1.4);
    s.initial.velocity = Vec3(0.0, 0.0, -30.0);
    s.contact.thickness = kThickness;
    ColliderParams box;
    box.name = "plate";
    box.type = ColliderParams::Type::Box;
    box.center = Vec3::Zero();
    box.half_extents = Vec3(0.5, 0.5, 0.005);
    s.colliders = {box};
    s.solver.method = m;
    s.solver.dt = 1.0 / 30.0;
    Simulation sim(s);
    for (int n = 0; n < 10; ++n) ASSERT_TRUE(sim.step().ok) << toString(m);
    for (int i = 0; i < sim.numNodes(); ++i) {
      EXPECT_NEAR(sim.position(i).z(), 0.005 + kThickness, 1e-9) << toString(m);
    }
    EXPECT_LE(sim.maxPenetration(), 1e-9);
  }
}

TEST(Contact, MovingTrayCarriesTheClothAndLosesItWhenItAcceleratesTooFast) {
  const double mu = 0.5, h = 0.01;
  for (double accel : {0.5 * mu * kG, 2.0 * mu * kG}) {
    Scene s = particlesOnFloor(mu, Method::ImplicitEuler);
    s.colliders[0].name = "tray";
    s.gravity = Vec3(0.0, 0.0, -kG);
    Simulation sim(s);
    const double x0 = sim.position(0).x();
    double tray_x = 0.0;
    for (int n = 0; n < 100; ++n) {
      const double v = accel * (n + 1) * h;  // the tray's velocity over this step
      ASSERT_TRUE(sim.moveCollider("tray", Vec3(tray_x, 0, 0), Vec3(v, 0, 0), h).ok);
      ASSERT_TRUE(sim.step().ok);
      tray_x += v * h;
    }
    const double carried = sim.position(0).x() - x0;
    if (accel < mu * kG) {
      EXPECT_NEAR(carried, tray_x, 1e-9) << "sticks and rides along";
    } else {
      // It slides: accelerated by kinetic friction only, mu g.
      const double t = 1.0;
      EXPECT_NEAR(carried, 0.5 * mu * kG * t * (t + h), 1e-9);
      EXPECT_LT(carried, 0.6 * tray_x);
    }
    EXPECT_NEAR(sim.position(0).z(), kThickness, 1e-12);
  }
}

TEST(Contact, MoveColliderEventLiftsTheClothExactly) {
  Scene s = particlesOnFloor(0.3, Method::Newton);
  s.gravity = Vec3(0.0, 0.0, -kG);
  SceneEvent lift;
  lift.kind = SceneEvent::Kind::MoveCollider;
  lift.collider = "floor";
  lift.time = 0.0;
  lift.velocity = Vec3(0.0, 0.0, 0.2);
  lift.duration = 0.5;
  s.events = {lift};
  Simulation sim(s);
  for (int n = 0; n < 100; ++n) ASSERT_TRUE(sim.step().ok);
  for (int i = 0; i < sim.numNodes(); ++i) {
    EXPECT_NEAR(sim.position(i).z(), 0.1 + kThickness, 1e-12);
  }
  EXPECT_NEAR(sim.colliderState(0).pose.translation.z(), 0.1, 1e-12);
}

TEST(Contact, SqueezedWithNoRoomFailsLoudlyAndChangesNothing) {
  for (Method m : kImplicit) {
    Scene s = particlesOnFloor(0.3, m);
    s.gravity = Vec3(0.0, 0.0, -kG);
    s.cloth.origin = Vec3(0.0, 0.0, 0.0015);
    ColliderParams lid;
    lid.name = "lid";
    lid.type = ColliderParams::Type::Plane;
    lid.point = Vec3(0.0, 0.0, 0.003);  // 3 mm gap, the nodes need 4
    lid.normal = -Vec3::UnitZ();
    s.colliders.push_back(lid);
    Simulation sim(s);
    const VecX x0 = sim.positions();
    const StepStats st = sim.step();
    EXPECT_FALSE(st.ok) << toString(m);
    EXPECT_NE(st.failure.find("squeezed between colliders 'floor' and 'lid'"), std::string::npos)
        << st.failure;
    EXPECT_TRUE(sim.positions().allFinite());
    EXPECT_EQ(sim.positions(), x0);
    EXPECT_EQ(sim.time(), 0.0);
  }
}

TEST(Contact, ResetRestoresColliders) {
  Scene s = particlesOnFloor(0.3, Method::ImplicitEuler);
  Simulation sim(s);
  ASSERT_TRUE(sim.moveCollider("floor", Vec3(0, 0, 0.5)).ok);
  EXPECT_FALSE(sim.moveCollider("nope", Vec3::Zero()).ok);
  EXPECT_FALSE(sim.moveCollider("floor", Vec3(NAN, 0, 0)).ok);
  sim.reset();
  EXPECT_EQ(sim.colliderState(0).pose.translation, Vec3::Zero());
}

// A node let go because it pulled, and found inside the band again in a
// later pass of the same step, is kept for the rest of the step (no
// cycling). Where it then pulls, its friction cone is empty: on the
// recovery's retry it slides. Kept sticking, the contact pulled a stiffened
// cloth's node onto a table's edge against its springs (c4 at newton, dt
// 0.1: 1.5e-3 J gained at every halving).
TEST(ContactSetPasses, ANodeBackAfterItsReleaseIsHeldAndSlidesWhereItPullsOnARetry) {
  const test::StillFloor floor(0.5, kThickness);
  const CollidersOverStep& over = floor.over;
  const ConstraintFilter pins(std::vector<char>{1});
  const std::vector<double> mass = {1.0};
  const double h = 0.01;
  const Vec3 gravity(0.0, 0.0, -kG);
  ContactSet contacts;
  contacts.setGrid(1, 1);
  const VecX x0 = Vec3(0.0, 0.0, kThickness + 1e-3);
  const VecX v0 = Vec3(0.1, 0.0, -1.0);  // lands within the step: a contact
  contacts.begin(over, pins, x0, v0, gravity, h);
  ASSERT_TRUE(contacts.holds(0));
  auto filterOf = [&] {
    ConstraintFilter f = pins;
    contacts.constrain(f);
    return f.projector(0);
  };
  EXPECT_TRUE(filterOf().isZero()) << "a new contact sticks";
  const VecX on_band = Vec3(0.0, 0.0, kThickness);
  const VecX v1 = (on_band - x0) / h;
  // Pass 1: it sticks and pulls, sideways too: outside the (empty) cone, it slides.
  const VecX pull = h * Vec3(1.0, 0.0, -5.0);
  EXPECT_EQ(contacts.update(over, pins, mass, x0, on_band, v1, pull, h, gravity, 1e-8),
            ContactCheck::Changed);
  EXPECT_EQ(contacts.lastChanges().slid, 1);
  // Pass 2: sliding, it still pulls: let go (its end a hair above the band).
  const VecX above = Vec3(0.0, 0.0, kThickness + 1e-7);
  EXPECT_EQ(contacts.update(over, pins, mass, x0, above, (above - x0) / h, pull, h, gravity, 1e-8),
            ContactCheck::Changed);
  EXPECT_EQ(contacts.lastChanges().released, 1);
  EXPECT_FALSE(contacts.holds(0));
  // Pass 3: free, it ends inside the band: back, and held (new, it sticks).
  const VecX below = Vec3(0.001, 0.0, kThickness - 1e-6);
  EXPECT_EQ(contacts.update(over, pins, mass, x0, below, (below - x0) / h, VecX::Zero(3), h,
                            gravity, 1e-8),
            ContactCheck::Changed);
  ASSERT_TRUE(contacts.holds(0));
  EXPECT_TRUE(filterOf().isZero());
  // Pass 4, past the friction passes: held, it pulls again. It is not let
  // go, and by default it keeps sticking (counted: the recovery's cue).
  EXPECT_EQ(contacts.update(over, pins, mass, x0, on_band, v1, pull, h, gravity, 1e-8),
            ContactCheck::Consistent);
  EXPECT_EQ(contacts.heldPulls(), 1);
  ASSERT_TRUE(contacts.holds(0));
  EXPECT_TRUE(filterOf().isZero());
  // Pass 5, as the recovery retries a step that gained energy: it slides
  // (the filter keeps its tangent plane).
  contacts.setSlideHeldPulls(true);
  EXPECT_EQ(contacts.update(over, pins, mass, x0, on_band, v1, pull, h, gravity, 1e-8),
            ContactCheck::Changed);
  EXPECT_EQ(contacts.lastChanges().slid, 1);
  ASSERT_TRUE(contacts.holds(0));
  const Mat3 tangent = Mat3::Identity() - Vec3::UnitZ() * Vec3::UnitZ().transpose();
  EXPECT_LT((filterOf() - tangent).norm(), 1e-12) << filterOf();
  // Pass 6: sliding and held, however it pulls: nothing changes.
  EXPECT_EQ(contacts.update(over, pins, mass, x0, on_band, v1, pull, h, gravity, 1e-8),
            ContactCheck::Consistent);
  EXPECT_TRUE(contacts.holds(0));
}

// Under newton a contact pass whose set may still change takes 2 Newton
// iterations, and the set that holds is solved to the tolerance of the
// step's first ||g|| (Stepper::step, "exploring" passes). The pinched cloth
// (contact hard case c2) took 7.6-7.8 Newton iterations a step with every
// pass solved to the tolerance of its own ||g||; 5.5 with exploring passes.
// Its answers still meet the tolerance: no step is rejected, none is taken
// linearized, and the cloth stays as strained as before (0.0033).
TEST(ContactPasses, ExploringPassesCutNewtonIterationsOfThePinchedCloth) {
  Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/contact/c2_pinched.yaml");
  s.solver.method = Method::Newton;
  Simulation sim(s);
  long newton = 0, passes = 0;
  const int steps = 200;
  for (int k = 0; k < steps; ++k) {
    const StepStats st = sim.step();
    ASSERT_TRUE(st.ok) << "step " << k << ": " << st.failure;
    EXPECT_EQ(st.rejected, 0) << "step " << k;
    EXPECT_EQ(st.linearized, 0) << "step " << k;
    EXPECT_TRUE(st.newton_converged) << "step " << k;
    newton += st.newton_iterations;
    passes += st.contact_passes;
  }
  const double per_step = static_cast<double>(newton) / steps;
  std::printf("[ passes   ] c2 under newton: %.2f Newton iterations, %.2f contact passes a step\n",
              per_step, static_cast<double>(passes) / steps);
  EXPECT_LT(per_step, 6.5);
  EXPECT_LT(sim.maxStrain(), 0.005);
}

}  // namespace
}  // namespace cloth_sim
