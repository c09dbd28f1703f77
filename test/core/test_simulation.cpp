// Simulation behaviour a user relies on: energy, pins, runtime requests, reset.
#include <algorithm>
#include <string>

#include <gtest/gtest.h>

#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

using test::bareScene;
using test::enable;
using test::hangingCloth;

TEST(Energy, NeverIncreasesWithFixedPinsAndDamping) {
  for (Method method : {Method::ImplicitEuler, Method::Newton}) {
    Scene s = hangingCloth(8, method);
    s.solver.dt = 0.02;
    Simulation sim(s);
    double previous = sim.energy();
    for (int n = 0; n < 300; ++n) {
      const StepStats stats = sim.step();
      ASSERT_TRUE(stats.ok) << stats.failure;
      ASSERT_LE(stats.energy, previous + 1e-12 * std::abs(previous)) << toString(method) << " step " << n;
      previous = stats.energy;
    }
  }
}

TEST(Pins, SitExactlyOnTargetsWhateverTheIterationCap) {
  for (int cap : {1, 2, 5}) {
    for (bool recovery : {false, true}) {
      Scene s = hangingCloth(8);
      s.solver.max_iterations = cap;
      s.solver.recovery = recovery;
      s.solver.max_halvings = 2;
      Simulation sim(s);
      ASSERT_TRUE(sim.drivePin(7, Vec3(0.3, 0.0, 0.2), 0.5));
      for (int n = 0; n < 30; ++n) {
        const StepStats stats = sim.step();
        ASSERT_TRUE(stats.finite);
        // A garbage solve may be refused (energy gain): then it says so and rolls back.
        ASSERT_TRUE(stats.ok || !stats.failure.empty());
        for (const auto& [node, pin] : sim.pins()) {
          ASSERT_EQ(sim.position(node), pin.position) << "cap " << cap << " node " << node;
        }
      }
      // Node 7 moved with its pin at the given velocity for the time actually simulated.
      EXPECT_NEAR((sim.position(7) - sim.model().rest_positions.segment<3>(21)).norm(),
                  sim.time() * std::hypot(0.3, 0.2), 1e-12);
      EXPECT_EQ(sim.position(0), sim.model().rest_positions.segment<3>(0));
    }
  }
}

TEST(Pins, PinnedNodeStaysWhileOthersFall) {
  Scene s = hangingCloth(6);
  Simulation sim(s);
  for (int n = 0; n < 50; ++n) ASSERT_TRUE(sim.step().ok);
  EXPECT_EQ(sim.position(0), sim.model().rest_positions.segment<3>(0));
  EXPECT_LT(sim.position(35).z(), s.cloth.origin.z() - 0.1);
}

TEST(Requests, BadRequestsAreRejectedAndChangeNothing) {
  Scene s = hangingCloth(4);
  Simulation sim(s);
  for (int n = 0; n < 5; ++n) sim.step();
  const VecX x = sim.positions(), v = sim.velocities();
  const auto pins = sim.pinnedNodes();
  const double k = sim.group(SpringType::Stretch).stiffness;
  auto expectUnchanged = [&](const Status& status, const std::string& fragment) {
    EXPECT_FALSE(status.ok);
    EXPECT_NE(status.message.find(fragment), std::string::npos) << status.message;
    EXPECT_EQ(sim.positions(), x);
    EXPECT_EQ(sim.velocities(), v);
    EXPECT_EQ(sim.pinnedNodes(), pins);
    EXPECT_EQ(sim.group(SpringType::Stretch).stiffness, k);
  };
  expectUnchanged(sim.pin({16}), "indices[0]: index 16 out of range [0, 15]");
  expectUnchanged(sim.pin({-1}), "indices[0]");
  expectUnchanged(sim.pin({}), "indices: empty list");
  expectUnchanged(sim.pin({3, 5, 3}), "indices[2]: duplicate index 3");
  expectUnchanged(sim.pin({3, 5}, {Vec3(0, 0, 0)}), "positions: 1 given for 2 indices");
  expectUnchanged(sim.pin({3}, {Vec3(0, NAN, 0)}), "positions[0]: must be finite");
  expectUnchanged(sim.release({2}), "indices[0]: node 2 is not pinned");
  expectUnchanged(sim.release({0, 99}), "indices[1]: index 99 out of range");
  expectUnchanged(sim.setStiffness("stretch", -3.0), "stiffness: must be > 0 and finite, got -3");
  expectUnchanged(sim.setStiffness("stretch", NAN), "stiffness");
  expectUnchanged(sim.setStiffness("stretch", INFINITY), "stiffness");
  expectUnchanged(sim.setStiffness("stretch", 10.0, -0.5), "damping: must be >= 0");
  expectUnchanged(sim.setStiffness("stretch", 10.0, NAN), "damping");
  expectUnchanged(sim.setStiffness("wool", 10.0), "spring_type: unknown 'wool'");
  expectUnchanged(sim.movePin(0, Vec3(INFINITY, 0, 0)), "position: must be finite");
  expectUnchanged(sim.drivePin(40, Vec3(1, 0, 0), 1.0), "index: 40 out of range");

  Scene no_bend = s;
  no_bend.springs[static_cast<int>(SpringType::Bend)].enabled = false;
  Simulation sim2(no_bend);
  const Status st = sim2.setStiffness("bend", 10.0);
  EXPECT_FALSE(st.ok);
  EXPECT_NE(st.message.find("'bend' is not in the scene"), std::string::npos) << st.message;
}

TEST(Requests, GoodRequestsTakeEffect) {
  Scene s = hangingCloth(6);
  Simulation sim(s);
  ASSERT_TRUE(sim.setStiffness("all", 1e4, 3.0));
  EXPECT_EQ(sim.group(SpringType::Shear).stiffness, 1e4);
  EXPECT_EQ(sim.group(SpringType::Shear).damping, 3.0);
  ASSERT_TRUE(sim.setStiffness("shear", 700.0, -1.0));
  EXPECT_EQ(sim.group(SpringType::Shear).damping, 3.0);  // -1 keeps damping
  ASSERT_TRUE(sim.release({0}));
  EXPECT_FALSE(sim.isPinned(0));
  ASSERT_TRUE(sim.pin({10}));
  const Vec3 held = sim.position(10);
  for (int n = 0; n < 20; ++n) ASSERT_TRUE(sim.step().ok);
  EXPECT_EQ(sim.position(10), held);
  EXPECT_LT(sim.position(0).z(), s.cloth.origin.z() - 0.01);  // released corner falls
}

/// Largest strain among the stretch springs (shear springs strain by shearing).
double maxStretchStrain(const Simulation& sim) {
  const SpringGroup& g = sim.group(SpringType::Stretch);
  double strain = 0.0;
  for (int k = g.begin; k < g.end; ++k) {
    const Spring& s = sim.model().springs[k];
    strain = std::max(strain, (sim.position(s.j) - sim.position(s.i)).norm() / s.rest_length - 1.0);
  }
  return strain;
}

TEST(Requests, StifferClothStretchesLess) {
  Simulation soft(hangingCloth(8)), stiff(hangingCloth(8));
  ASSERT_TRUE(stiff.setStiffness("stretch", 5e5));
  for (int n = 0; n < 200; ++n) {
    ASSERT_TRUE(soft.step().ok);
    ASSERT_TRUE(stiff.step().ok);
  }
  ASSERT_NEAR(soft.time(), 200 * soft.dt(), 1e-9);
  ASSERT_EQ(stiff.time(), soft.time());
  // 100x stiffer, at least 10x less stretch. Not 100x: the top row is a
  // taut string between the pins, whose strain under a load falls as
  // k^(-2/3) (~22x); the converged backward-Euler answer shows ~15x (2.2e-3
  // against 1.4e-4 at t = 2 s).
  EXPECT_LT(maxStretchStrain(stiff), 0.1 * maxStretchStrain(soft));
}

TEST(Reset, RestoresInitialStateExactly) {
  Scene s = hangingCloth(6);
  Simulation sim(s);
  const VecX x0 = sim.positions();
  ASSERT_TRUE(sim.setStiffness("stretch", 100.0));
  ASSERT_TRUE(sim.release({0}));
  ASSERT_TRUE(sim.pin({20}));
  for (int n = 0; n < 30; ++n) ASSERT_TRUE(sim.step().ok);
  ASSERT_GT(sim.time(), 0.0);
  ASSERT_NE(sim.positions(), x0);  // it moved, so the reset has something to undo
  sim.reset();
  EXPECT_EQ(sim.positions(), x0);
  EXPECT_TRUE(sim.velocities().isZero(0.0));
  EXPECT_EQ(sim.time(), 0.0);
  EXPECT_EQ(sim.pinnedNodes(), (std::vector<int>{0, 5}));
  EXPECT_EQ(sim.group(SpringType::Stretch).stiffness, 5000.0);
  // And it replays the same trajectory bit for bit.
  Simulation fresh(s);
  for (int n = 0; n < 10; ++n) {
    ASSERT_TRUE(sim.step().ok);
    ASSERT_TRUE(fresh.step().ok);
  }
  ASSERT_GT(sim.time(), 0.0);
  EXPECT_EQ(sim.positions(), fresh.positions());
}

TEST(Recovery, ExplicitStepperFailsLoudlyAndKeepsStateFinite) {
  Scene s = hangingCloth(8, Method::SymplecticEuler);
  s.springs[0].stiffness = 1e8;
  s.solver.dt = 1.0 / 30.0;
  s.solver.max_halvings = 3;
  Simulation sim(s);
  bool failed = false;
  for (int n = 0; n < 50 && !failed; ++n) {
    const StepStats stats = sim.step();
    EXPECT_TRUE(sim.positions().allFinite());
    if (!stats.ok) {
      failed = true;
      EXPECT_FALSE(stats.failure.empty());
    }
  }
  EXPECT_TRUE(failed);
}

TEST(Recovery, ImplicitSteppersSurviveVeryStiffCloth) {
  for (Method method : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    Scene s = hangingCloth(8, method);
    s.springs[0].stiffness = 1e8;
    s.solver.dt = 1.0 / 30.0;
    s.solver.tolerance = 1e-8;
    s.solver.preconditioner = Preconditioner::Cholesky;
    Simulation sim(s);
    for (int n = 0; n < 60; ++n) {
      const StepStats stats = sim.step();
      ASSERT_TRUE(stats.ok) << toString(method) << ": " << stats.failure;
      ASSERT_TRUE(stats.finite);
    }
    EXPECT_LT(maxStretchStrain(sim), 1e-4) << toString(method);
  }
}

// Pins dragged at 10 m/s (hard case 07b: 0.1 m a step at dt 0.01): the
// energy check weighs each linearized step against the pins' work. Read off
// f(x1, v1), a state the linearized answer does not balance, that work was
// several times what went in, and a step that overstretched the cloth by
// 42 % was accepted; read off the step's own linear system, it is refined
// instead and the cloth stretches 0.5 %.
TEST(Recovery, DraggedPinsDoNotOverstretchALinearizedStep) {
  Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/07b_pin_drag.yaml");
  ASSERT_EQ(s.solver.method, Method::ImplicitEuler);
  Simulation sim(s);
  double strain = 0.0;
  long refined = 0;
  while (sim.time() < 0.7 - 1e-9) {
    const StepStats stats = sim.step();
    ASSERT_TRUE(stats.ok) << "t = " << sim.time() << ": " << stats.failure;
    strain = std::max(strain, sim.maxStrain());
    refined += stats.refined;
  }
  EXPECT_LT(strain, 0.02);
  EXPECT_GT(refined, 0);  // the drag's linearized steps that gained energy were solved on
}

TEST(Recovery, PinsTheClothPushesBackTakeTheirWorkOut) {
  // A stiff cloth at rest whose edge starts moving at 1.2 m/s: the split
  // sub-steps' refined Newton answers read negative pin work (the cloth
  // pushing back), which once counted as none and let 2.2e-2 J through.
  Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/self/s3_fling.yaml",
                      {"springs.stretch.stiffness=1e6", "solver.dt=0.01"});
  ASSERT_EQ(s.solver.method, Method::ImplicitEuler);
  Simulation sim(s);
  const double e0 = sim.energy();
  const StepStats stats = sim.step();
  ASSERT_TRUE(stats.ok) << stats.failure;
  EXPECT_GT(sim.energy(), e0 + 1e-3);  // the drag put energy in
  EXPECT_LE(sim.energy(), e0 + sim.totalWorkIn() + 1e-6 * sim.energy());
}

TEST(Events, AppliedBetweenStepsAtTheirTime) {
  Scene s = hangingCloth(5);
  SceneEvent release;
  release.time = 0.1;
  release.kind = SceneEvent::Kind::Release;
  release.release_all = true;
  s.events = {release};
  Simulation sim(s);
  for (int n = 0; n < 10; ++n) ASSERT_TRUE(sim.step().ok);
  EXPECT_NEAR(sim.time(), 0.1, 1e-12);
  EXPECT_EQ(sim.pinnedNodes().size(), 2u);
  ASSERT_TRUE(sim.step().ok);  // t = 0.1: the release applies before this step
  EXPECT_TRUE(sim.pinnedNodes().empty());
}

TEST(Model, OnlyTheGroupsTheSceneNamesExist) {
  Scene s = bareScene(4, 5);
  enable(s, SpringType::Shear, 10.0, 0.0);
  const Model m = buildModel(s);
  EXPECT_EQ(m.springs.size(), static_cast<size_t>(2 * 3 * 4));
  EXPECT_FALSE(m.groups[0].present);
  EXPECT_FALSE(m.groups[2].present);
  enable(s, SpringType::Stretch, 10.0, 0.0);
  enable(s, SpringType::Bend, 10.0, 0.0);
  const Model full = buildModel(s);
  // stretch: 4*4 + 3*5, shear: 2*3*4, bend: 4*3 + 2*5
  EXPECT_EQ(full.springs.size(), static_cast<size_t>(31 + 24 + 22));
  EXPECT_EQ(full.triangles.size(), static_cast<size_t>(2 * 3 * 4));
}

TEST(Model, TrianglesFaceUpForHorizontalCloth) {
  Scene s = bareScene(3, 4);
  const Model m = buildModel(s);
  for (const auto& t : m.triangles) {
    const VecX& x = m.rest_positions;
    const Vec3 n = (x.segment<3>(3 * t[1]) - x.segment<3>(3 * t[0]))
                       .cross(x.segment<3>(3 * t[2]) - x.segment<3>(3 * t[0]));
    EXPECT_GT(n.z(), 0.0);
  }
}

// A step that needs deep halvings (the collapsed start at dt 0.1: 8 levels
// under newton) pays for them once: later sub-steps of the step, and the
// next steps, start no coarser than what was last accepted (twice that at a
// step's start). Before, each sub-step was preceded by failed attempts at
// the coarser levels of its half (6 steps: newton 43 rejected attempts,
// bdf2 21; now 17 and 7).
TEST(Recovery, AStepThatNeededHalvingsDoesNotRetryTheCoarserSizes) {
  for (Method method : {Method::Newton, Method::Bdf2}) {
    Scene s = loadScene(std::string(CLOTH_SIM_SOURCE_DIR) +
                        "/config/scenes/hard/05b_collapsed_start.yaml");
    s.solver.method = method;
    s.solver.dt = 0.1;
    Simulation sim(s);
    int rejected = 0, substeps = 0, deepest = 0;
    for (int n = 0; n < 6; ++n) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << toString(method) << " step " << n << ": " << st.failure;
      // A few failed attempts a level on the way down (a retry at the same
      // size counts too: bdf2 as backward Euler, a refined step), none on
      // the way back; the old rule: 31 in the first step under newton.
      EXPECT_LE(st.rejected, 2 * std::max(deepest, st.halvings) + 2) << toString(method) << " " << n;
      deepest = st.halvings;
      rejected += st.rejected;
      substeps += st.substeps;
    }
    EXPECT_GT(substeps, 6) << toString(method);  // it did halve
    EXPECT_LE(rejected, 20) << toString(method);
    EXPECT_TRUE(sim.positions().allFinite());
  }
}

}  // namespace
}  // namespace cloth_sim

