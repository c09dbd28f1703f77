// Scene events run and have their documented effect (issue 17): pin,
// release, move_pin (jump, drag, and on a node that was not pinned: a grab),
// set_stiffness. A simulation that ignored its events fails every test here.
// Every test asserts that its steps succeeded and that time advanced.
#include <gtest/gtest.h>

#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

using test::hangingCloth;

/// Steps until time t (within round-off), asserting every step succeeds.
::testing::AssertionResult runUntil(Simulation& sim, double t) {
  while (sim.time() < t - 1e-9) {
    const double before = sim.time();
    const StepStats s = sim.step();
    if (!s.ok) return ::testing::AssertionFailure() << "step failed at t = " << before << ": " << s.failure;
    if (!(sim.time() > before)) return ::testing::AssertionFailure() << "time did not advance";
  }
  return ::testing::AssertionSuccess();
}

SceneEvent event(double time, SceneEvent::Kind kind) {
  SceneEvent e;
  e.time = time;
  e.kind = kind;
  return e;
}

TEST(SceneEvents, PinHoldsTheNodesWhereTheyAreAtThatTime) {
  Scene scene = hangingCloth(5);
  SceneEvent pin = event(0.1, SceneEvent::Kind::Pin);
  pin.indices = {12, 24};
  scene.events = {pin};
  Simulation sim(scene);
  ASSERT_TRUE(runUntil(sim, 0.1));
  EXPECT_FALSE(sim.isPinned(12));
  const Vec3 at_event = sim.position(12), corner = sim.position(24);
  ASSERT_TRUE(runUntil(sim, 0.11));  // the event applies before this step
  EXPECT_TRUE(sim.isPinned(12));
  EXPECT_TRUE(sim.isPinned(24));
  ASSERT_TRUE(runUntil(sim, 0.5));
  EXPECT_LT((sim.position(12) - at_event).norm(), 1e-12);
  EXPECT_LT((sim.position(24) - corner).norm(), 1e-12);

  // Without the event the same nodes keep falling.
  Scene free = hangingCloth(5);
  Simulation reference(free);
  ASSERT_TRUE(runUntil(reference, 0.5));
  EXPECT_LT(reference.position(24).z(), corner.z() - 0.05);
}

TEST(SceneEvents, ReleaseListedNodesLetsThemFall) {
  Scene scene = hangingCloth(5);
  SceneEvent release = event(0.2, SceneEvent::Kind::Release);
  release.indices = {0};
  scene.events = {release};
  Simulation sim(scene);
  const Vec3 start = sim.position(0);
  ASSERT_TRUE(runUntil(sim, 0.2));
  EXPECT_EQ(sim.position(0), start);  // pinned until then
  ASSERT_TRUE(runUntil(sim, 0.6));
  EXPECT_FALSE(sim.isPinned(0));
  EXPECT_TRUE(sim.isPinned(4));
  EXPECT_LT(sim.position(0).z(), start.z() - 0.05);
  EXPECT_LT((sim.position(4) - Vec3(sim.model().rest_positions.segment<3>(12))).norm(), 1e-12);
}

TEST(SceneEvents, MovePinJumpsAndDragsTheTarget) {
  Scene scene = hangingCloth(5);
  const Vec3 jump(0.2, 0.1, 1.6), velocity(0.5, 0.0, -0.25);
  SceneEvent move = event(0.1, SceneEvent::Kind::MovePin);
  move.index = 4;
  move.position = jump;
  SceneEvent drag = event(0.3, SceneEvent::Kind::MovePin);
  drag.index = 4;
  drag.velocity = velocity;
  drag.duration = 0.2;
  scene.events = {move, drag};
  Simulation sim(scene);
  ASSERT_TRUE(runUntil(sim, 0.11));
  EXPECT_LT((sim.position(4) - jump).norm(), 1e-12) << "the pin jumps to position";
  ASSERT_TRUE(runUntil(sim, 0.3));
  EXPECT_LT((sim.position(4) - jump).norm(), 1e-12);
  ASSERT_TRUE(runUntil(sim, 0.4));
  EXPECT_LT((sim.position(4) - (jump + 0.1 * velocity)).norm(), 1e-9) << "half way through the drag";
  ASSERT_TRUE(runUntil(sim, 0.8));
  EXPECT_LT((sim.position(4) - (jump + 0.2 * velocity)).norm(), 1e-9) << "the drag stops after duration";
}

TEST(SceneEvents, MovePinOnANodeThatIsNotPinnedGrabsIt) {
  // docs/scene.md: a move_pin whose node is not pinned when the event runs
  // pins it (a grab), from where it is or at `position`.
  Scene scene = hangingCloth(5);
  const Vec3 target(0.5, -0.5, 1.2);
  SceneEvent grab = event(0.1, SceneEvent::Kind::MovePin);
  grab.index = 12;
  grab.position = target;
  scene.events = {grab};
  Simulation sim(scene);
  ASSERT_TRUE(runUntil(sim, 0.1));
  EXPECT_FALSE(sim.isPinned(12));
  ASSERT_TRUE(runUntil(sim, 0.3));
  EXPECT_TRUE(sim.isPinned(12));
  EXPECT_LT((sim.position(12) - target).norm(), 1e-12);
}

TEST(SceneEvents, SetStiffnessChangesTheGroupAndTheSag) {
  Scene scene = hangingCloth(5);
  SceneEvent soften = event(0.1, SceneEvent::Kind::SetStiffness);
  soften.spring_type = SpringType::Stretch;
  soften.stiffness = 50.0;
  soften.damping = 0.5;
  SceneEvent shear = event(0.1, SceneEvent::Kind::SetStiffness);
  shear.all_types = false;
  shear.spring_type = SpringType::Shear;
  shear.stiffness = 5.0;  // damping -1: kept
  scene.events = {soften, shear};
  Simulation sim(scene);
  Simulation reference(hangingCloth(5));
  ASSERT_TRUE(runUntil(sim, 0.1));
  EXPECT_EQ(sim.group(SpringType::Stretch).stiffness, 5000.0);
  ASSERT_TRUE(runUntil(sim, 1.0));
  ASSERT_TRUE(runUntil(reference, 1.0));
  EXPECT_EQ(sim.group(SpringType::Stretch).stiffness, 50.0);
  EXPECT_EQ(sim.group(SpringType::Stretch).damping, 0.5);
  EXPECT_EQ(sim.group(SpringType::Shear).stiffness, 5.0);
  EXPECT_EQ(sim.group(SpringType::Shear).damping, 0.5);  // hangingCloth's, kept
  EXPECT_NE(sim.totalWorkIn(), 0.0);  // changing k of stretched springs is work
  // Softer springs stretch more under the same weight.
  EXPECT_GT(sim.maxStrain(), 5.0 * reference.maxStrain());
}

TEST(SceneEvents, ReleaseAllAndPinOfPinnedNodesFromTheSameScene) {
  // pin of an already pinned node keeps its pin; release of a node that is
  // not pinned is skipped (docs/scene.md).
  Scene scene = hangingCloth(5);
  SceneEvent pin = event(0.05, SceneEvent::Kind::Pin);
  pin.indices = {0, 2};  // 0 is pinned already
  SceneEvent release = event(0.1, SceneEvent::Kind::Release);
  release.indices = {2, 3};  // 3 is not pinned
  SceneEvent all = event(0.2, SceneEvent::Kind::Release);
  all.release_all = true;
  scene.events = {pin, release, all};
  Simulation sim(scene);
  ASSERT_TRUE(runUntil(sim, 0.06));
  EXPECT_EQ(sim.pinnedNodes(), (std::vector<int>{0, 2, 4}));
  ASSERT_TRUE(runUntil(sim, 0.11));
  EXPECT_EQ(sim.pinnedNodes(), (std::vector<int>{0, 4}));
  ASSERT_TRUE(runUntil(sim, 0.21));
  EXPECT_TRUE(sim.pinnedNodes().empty());
}

}  // namespace
}  // namespace cloth_sim
