// Simulation::retune, the node's live tuning: a refused change names the field
// and changes nothing; an accepted one acts like the same scene from the start.
#include <gtest/gtest.h>

#include <cmath>

#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

using test::hangingCloth;

constexpr int kStretch = static_cast<int>(SpringType::Stretch);
constexpr int kBend = static_cast<int>(SpringType::Bend);

TEST(Retune, ReportsWhatTheSimulationUses) {
  Scene s = hangingCloth(5);
  s.air_drag = 0.01;
  Simulation sim(s);
  ASSERT_TRUE(sim.setStiffness("shear", 700.0, 0.25));
  const Tuning t = sim.tuning();
  EXPECT_TRUE(t.springs[kStretch].enabled);
  EXPECT_EQ(t.springs[kStretch].stiffness, 5000.0);
  EXPECT_EQ(t.springs[static_cast<int>(SpringType::Shear)].stiffness, 700.0);
  EXPECT_EQ(t.springs[static_cast<int>(SpringType::Shear)].damping, 0.25);
  EXPECT_EQ(t.gravity, Vec3(0.0, 0.0, -9.81));
  EXPECT_EQ(t.air_drag, 0.01);
  EXPECT_EQ(t.solver.dt, s.solver.dt);
  EXPECT_EQ(t.solver.method, s.solver.method);
}

TEST(Retune, BadValuesAreRefusedNamingTheFieldAndChangeNothing) {
  Scene s = hangingCloth(5);
  s.springs[kBend].enabled = false;
  s.springs[kBend].stiffness = 0.0;
  Simulation sim(s), twin(s);
  for (int n = 0; n < 5; ++n) {
    sim.step();
    twin.step();
  }
  const Tuning good = sim.tuning();
  auto refused = [&](const Tuning& t, const std::string& fragment) {
    const Status status = sim.retune(t);
    EXPECT_FALSE(status.ok) << fragment;
    EXPECT_NE(status.message.find(fragment), std::string::npos) << status.message;
  };
  Tuning t = good;
  t.springs[kStretch].stiffness = -3.0;
  refused(t, "springs.stretch.stiffness: must be > 0, got -3");
  t = good;
  t.springs[kStretch].enabled = false;  // 0 in a scene file turns a group off
  t.springs[kStretch].stiffness = 0.0;
  refused(t, "springs.stretch.stiffness: must stay > 0");
  t = good;
  t.springs[kBend] = SpringGroupParams{true, 5.0, 0.0};
  refused(t, "springs.bend: the scene does not model the bend group");
  t = good;
  t.springs[kStretch].damping = NAN;
  refused(t, "springs.stretch.damping");
  t = good;
  t.gravity = Vec3(0.0, INFINITY, 0.0);
  refused(t, "gravity");
  t = good;
  t.air_drag = -1.0;
  refused(t, "air_drag");
  t = good;
  t.solver.dt = 0.0;
  refused(t, "solver.dt");
  t = good;
  t.solver.tolerance = 2.0;
  refused(t, "solver.tolerance");
  t = good;
  t.solver.dt = -1.0;  // the first bad field is named, nothing of the rest applies
  t.air_drag = 0.5;
  refused(t, "solver.dt");

  const Tuning now = sim.tuning();
  EXPECT_EQ(now.air_drag, good.air_drag);
  EXPECT_EQ(now.solver.dt, good.solver.dt);
  EXPECT_EQ(now.springs[kStretch].stiffness, good.springs[kStretch].stiffness);
  // Untouched: the same trajectory as a twin that was never asked.
  for (int n = 0; n < 10; ++n) {
    ASSERT_TRUE(sim.step().ok);
    twin.step();
  }
  EXPECT_EQ(sim.positions(), twin.positions());
  EXPECT_EQ(sim.velocities(), twin.velocities());
}

TEST(Retune, AcceptedChangesActLikeTheSceneHadThem) {
  // Retuned after construction == built with those settings, step for step.
  Scene s = hangingCloth(6);
  Scene changed = s;
  changed.springs[kStretch].stiffness = 2e4;
  changed.springs[kStretch].damping = 1.0;
  changed.gravity = Vec3(0.0, 1.0, -5.0);
  changed.air_drag = 0.02;
  changed.solver.method = Method::Bdf2;
  changed.solver.dt = 0.005;
  changed.solver.preconditioner = Preconditioner::Cholesky;
  changed.solver.tolerance = 1e-9;

  Simulation sim(s), reference(changed);
  Tuning t = sim.tuning();
  t.springs = changed.springs;
  t.gravity = changed.gravity;
  t.air_drag = changed.air_drag;
  t.solver = changed.solver;
  const Status status = sim.retune(t);
  ASSERT_TRUE(status.ok) << status.message;
  EXPECT_EQ(sim.dt(), 0.005);
  EXPECT_EQ(sim.group(SpringType::Stretch).stiffness, 2e4);
  for (int n = 0; n < 40; ++n) {
    const StepStats a = sim.step();
    const StepStats b = reference.step();
    ASSERT_TRUE(a.ok) << a.failure;
    ASSERT_EQ(a.ok, b.ok);
  }
  EXPECT_EQ(sim.positions(), reference.positions());
}

TEST(Retune, MidRunChangeTakesEffectAndKeepsEnergyBooks) {
  // Gravity turned off mid-fall: a free cloth then coasts (no more speed-up).
  Scene s = hangingCloth(4);
  s.pins = {};
  s.springs = {};
  Simulation sim(s);
  for (int n = 0; n < 10; ++n) ASSERT_TRUE(sim.step().ok);
  const double vz = sim.velocities()[2];
  EXPECT_LT(vz, -0.5);
  Tuning t = sim.tuning();
  t.gravity = Vec3::Zero();
  ASSERT_TRUE(sim.retune(t).ok);
  for (int n = 0; n < 10; ++n) ASSERT_TRUE(sim.step().ok);
  EXPECT_NEAR(sim.velocities()[2], vz, 1e-9);
  EXPECT_EQ(sim.potentialEnergy(), 0.0);
}

TEST(Retune, ResetReturnsToTheScene) {
  Scene s = hangingCloth(5);
  Simulation sim(s);
  Tuning t = sim.tuning();
  t.solver.method = Method::Newton;
  t.solver.dt = 0.02;
  t.gravity = Vec3(0.0, 0.0, -1.0);
  t.springs[kStretch].stiffness = 10.0;
  ASSERT_TRUE(sim.retune(t).ok);
  sim.reset();
  const Tuning back = sim.tuning();
  EXPECT_EQ(back.solver.method, s.solver.method);
  EXPECT_EQ(back.solver.dt, s.solver.dt);
  EXPECT_EQ(back.gravity, s.gravity);
  EXPECT_EQ(back.springs[kStretch].stiffness, 5000.0);
  Simulation fresh(s);
  for (int n = 0; n < 10; ++n) {
    sim.step();
    fresh.step();
  }
  EXPECT_EQ(sim.positions(), fresh.positions());
}

}  // namespace
}  // namespace cloth_sim
