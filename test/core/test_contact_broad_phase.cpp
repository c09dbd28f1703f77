// The contact broad phase (ContactBroadPhase): it never drops a node-collider
// pair the exact queries would answer (randomised swept paths, every shape,
// moving and turning colliders, a fast node through a thin box), and it
// prunes (on a cloth with one small sphere at a corner only the patches near
// the sphere are queried).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "cloth_sim/contact.hpp"
#include "cloth_sim/contact_broad_phase.hpp"
#include "cloth_sim/simulation.hpp"

namespace cloth_sim {
namespace {

constexpr double kTolerance = ContactSet::kPenetrationTolerance;

std::vector<Collider> everyShape() {
  std::vector<Collider> out;
  ColliderParams p;
  p.type = ColliderParams::Type::Plane;
  p.point = Vec3(0.1, 0.2, -0.1);
  p.normal = Vec3(0.2, -0.3, 1.0);
  out.push_back(Collider::fromParams(p, 0.3));
  p = ColliderParams();
  p.type = ColliderParams::Type::Sphere;
  p.center = Vec3(0.1, -0.2, 0.3);
  p.radius = 0.25;
  out.push_back(Collider::fromParams(p, 0.3));
  p = ColliderParams();
  p.type = ColliderParams::Type::Box;
  p.center = Vec3(-0.2, 0.1, 0.0);
  p.half_extents = Vec3(0.3, 0.2, 0.01);  // thin: paths cross it in one step
  p.rpy = Vec3(0.3, -0.2, 0.7);
  out.push_back(Collider::fromParams(p, 0.3));
  p = ColliderParams();
  p.type = ColliderParams::Type::Capsule;
  p.a = Vec3(-0.2, 0.1, 0.0);
  p.b = Vec3(0.3, -0.1, 0.2);
  p.radius = 0.1;
  out.push_back(Collider::fromParams(p, 0.3));
  return out;
}

/// Whether the exact queries (ContactSet's) find anything for the pair: a
/// first contact on the swept path, or an end inside the thickness.
bool bruteForceFinds(const Collider& c, const Pose& start, const Pose& end, const Vec3& p0,
                     const Vec3& p1, double thickness) {
  if (thickness - c.closest(p1, end).distance > 0.0) return true;
  return firstContact(c, start, end, p0, p1, thickness, kTolerance).has_value();
}

/// Checks the broad phase's answer on paths x0 -> x1 against brute force;
/// counts the pairs brute force finds and those the broad phase drops.
void expectNoMiss(const ContactBroadPhase& broad, const CollidersOverStep& colliders,
                  const VecX& x0, const VecX& x1, int* found, int* dropped) {
  const auto& all = *colliders.colliders;
  const std::vector<int>& candidates = broad.candidates();
  ASSERT_TRUE(std::is_sorted(candidates.begin(), candidates.end()));
  const int n = static_cast<int>(x0.size() / 3);
  for (int i = 0; i < n; ++i) {
    const bool candidate = std::binary_search(candidates.begin(), candidates.end(), i);
    bool any = false;
    for (size_t k = 0; k < all.size(); ++k) {
      const bool may = broad.mayTouch(i, static_cast<int>(k));
      any = any || may;
      const bool finds = bruteForceFinds(all[k], colliders.start[k], colliders.end[k],
                                         x0.segment<3>(3 * i), x1.segment<3>(3 * i),
                                         colliders.thickness);
      if (finds) {
        ++*found;
        ASSERT_TRUE(may) << "node " << i << " collider " << k << " dropped";
      }
      if (!may) ++*dropped;
    }
    ASSERT_EQ(candidate, any) << "node " << i;
  }
}

/// A rows x cols cloth whose 8 x 8 patches lie in small clusters scattered
/// around the colliders: most patches far from any, some against one.
VecX scatteredPatches(int rows, int cols, std::mt19937& rng) {
  std::uniform_real_distribution<double> where(-0.8, 0.8), jitter(-0.04, 0.04);
  const int side = ContactBroadPhase::kPatchSide;
  std::vector<Vec3> centre(((rows + side - 1) / side) * ((cols + side - 1) / side));
  for (Vec3& c : centre) c = Vec3(where(rng), where(rng), where(rng));
  VecX x(3 * rows * cols);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const Vec3& m = centre[(r / side) * ((cols + side - 1) / side) + c / side];
      x.segment<3>(3 * (r * cols + c)) = m + Vec3(jitter(rng), jitter(rng), jitter(rng));
    }
  }
  return x;
}

Pose randomPose(const Collider& c, std::mt19937& rng, double move) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Pose p = c.scenePose();
  p.translation += move * Vec3(u(rng), u(rng), u(rng));
  p.rotation = rotationFromRpy(move * Vec3(u(rng), u(rng), u(rng))) * p.rotation;
  return p;
}

TEST(ContactBroadPhase, NeverDropsAPairTheExactQueriesFind) {
  const std::vector<Collider> shapes = everyShape();
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-1.0, 1.0), unit(0.0, 1.0);
  int found = 0, dropped = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const int rows = 5 + trial % 13, cols = 3 + (trial * 7) % 19;
    CollidersOverStep colliders;
    colliders.colliders = &shapes;
    // Up to 10 cm: paths that pass the shape within the thickness only.
    colliders.thickness = trial % 5 == 0 ? 0.0 : 0.1 * unit(rng);
    const bool moving = trial % 3 != 0;
    for (const Collider& c : shapes) {
      colliders.start.push_back(moving ? randomPose(c, rng, 0.1) : c.scenePose());
      colliders.end.push_back(moving ? randomPose(c, rng, 0.1) : colliders.start.back());
    }
    const VecX x0 = scatteredPatches(rows, cols, rng);
    VecX x1 = x0, v0(x0.size());
    for (int i = 0; i < rows * cols; ++i) {
      // Most nodes move a little; one in ten fast (up to 1 m in the step).
      const double reach = unit(rng) < 0.1 ? 1.0 : 0.03;
      x1.segment<3>(3 * i) += reach * Vec3(u(rng), u(rng), u(rng));
      v0.segment<3>(3 * i) = reach * Vec3(u(rng), u(rng), u(rng));
    }
    ContactBroadPhase broad;
    // Grids, and (every fourth trial) no grid: runs of consecutive nodes.
    if (trial % 4 != 0) broad.setGrid(rows, cols);
    broad.build(colliders, x0, x1);
    expectNoMiss(broad, colliders, x0, x1, &found, &dropped);
    // The predicted path of ContactSet::begin.
    const double h = 0.01 + 0.1 * unit(rng);
    const Vec3 g(0.0, 0.0, -9.81);
    VecX predicted(x0.size());
    for (int i = 0; i < rows * cols; ++i) {
      predicted.segment<3>(3 * i) = x0.segment<3>(3 * i) + h * v0.segment<3>(3 * i) + h * h * g;
    }
    broad.buildPredicted(colliders, x0, v0, g, h);
    expectNoMiss(broad, colliders, x0, predicted, &found, &dropped);
  }
  // The draw exercised both sides: pairs found, pairs pruned.
  EXPECT_GT(found, 1000);
  EXPECT_GT(dropped, 10000);
}

TEST(ContactBroadPhase, KeepsAFastNodeCrossingAThinBoxInOneStep) {
  // 1 m in a step through a 1 cm box; both ends 0.5 m from it. Every other
  // node falls the same 1 m 2.5 m to the side of the box, so neither the
  // start nor the end positions of the fast node's patch meet the box: only
  // their hull (the swept box) does.
  ColliderParams p;
  p.type = ColliderParams::Type::Box;
  p.half_extents = Vec3(0.5, 0.5, 0.005);
  const std::vector<Collider> plate = {Collider::fromParams(p, 0.3)};
  CollidersOverStep colliders;
  colliders.colliders = &plate;
  colliders.start = colliders.end = {plate[0].scenePose()};
  colliders.thickness = 0.002;
  const int rows = 16, cols = 16;
  VecX x0(3 * rows * cols), x1(3 * rows * cols);
  for (int i = 0; i < rows * cols; ++i) {
    x0.segment<3>(3 * i) = Vec3(3.0 + 0.01 * (i % cols), 0.01 * (i / cols), 0.5);
    x1.segment<3>(3 * i) = x0.segment<3>(3 * i) - Vec3(0.0, 0.0, 1.0);
  }
  const int fast = 9 * cols + 10;  // patch (1, 1)
  x0.segment<3>(3 * fast) = Vec3(0.1, 0.0, 0.5);
  x1.segment<3>(3 * fast) = Vec3(0.1, 0.0, -0.5);
  ContactBroadPhase broad;
  broad.setGrid(rows, cols);
  broad.build(colliders, x0, x1);
  EXPECT_TRUE(firstContact(plate[0], colliders.start[0], colliders.end[0],
                           x0.segment<3>(3 * fast), x1.segment<3>(3 * fast), 0.002, kTolerance));
  EXPECT_TRUE(broad.mayTouch(fast, 0));
  EXPECT_EQ(broad.numNearPatches(), 1);
  EXPECT_EQ(broad.candidates().size(), 64u);  // the fast node's patch only
  int found = 0, dropped = 0;
  expectNoMiss(broad, colliders, x0, x1, &found, &dropped);
  EXPECT_EQ(found, 1);
  EXPECT_EQ(dropped, rows * cols - 64);
}

TEST(ContactBroadPhase, KeepsStillNodesAMovingColliderSweepsThrough) {
  // A ball from x = -1 to x = +1 in one step through a still patch at the
  // origin: far from both of its poses, on its way.
  ColliderParams p;
  p.type = ColliderParams::Type::Sphere;
  p.radius = 0.05;
  const std::vector<Collider> ball = {Collider::fromParams(p, 0.3)};
  CollidersOverStep colliders;
  colliders.colliders = &ball;
  colliders.start = colliders.end = {ball[0].scenePose()};
  colliders.start[0].translation = Vec3(-1, 0, 0);
  colliders.end[0].translation = Vec3(1, 0, 0);
  const VecX x = VecX::Zero(3 * 4);
  ContactBroadPhase broad;
  broad.setGrid(2, 2);
  broad.build(colliders, x, x);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(broad.mayTouch(i, 0));
  // Moved 1 m aside, the same patch is dropped.
  VecX aside = x;
  for (int i = 0; i < 4; ++i) aside[3 * i + 1] = 1.0;
  broad.build(colliders, aside, aside);
  EXPECT_TRUE(broad.candidates().empty());
}

TEST(ContactBroadPhase, KeepsPatchesWithANonFiniteCoordinate) {
  ColliderParams p;
  p.type = ColliderParams::Type::Sphere;
  p.radius = 0.05;
  const std::vector<Collider> ball = {Collider::fromParams(p, 0.3)};
  CollidersOverStep colliders;
  colliders.colliders = &ball;
  colliders.start = colliders.end = {ball[0].scenePose()};
  VecX x = VecX::Constant(3 * 256, 5.0);  // 16 x 16, far from the ball
  VecX x1 = x;
  x1[3 * 200 + 2] = std::nan("");
  ContactBroadPhase broad;
  broad.setGrid(16, 16);
  broad.build(colliders, x, x1);
  EXPECT_EQ(broad.numNearPatches(), 1);
  EXPECT_TRUE(broad.mayTouch(200, 0));
  EXPECT_FALSE(broad.mayTouch(0, 0));
}

const std::string kCornerScene =
    std::string(CLOTH_SIM_SOURCE_DIR) + "/bench/scenes/hang64_corner_sphere.yaml";

TEST(ContactBroadPhase, QueriesOnlyThePatchesNearASmallSphere) {
  // hang64 with a 5 cm sphere under one corner: the broad phase keeps the
  // patches whose swept box meets the sphere's box (+ thickness), and the
  // steps query a few hundred of the 4096 nodes a pass.
  const Scene scene = loadScene(kCornerScene);
  Simulation sim(scene);
  const int n = sim.numNodes();
  ASSERT_EQ(n, 4096);
  const Collider& sphere = sim.colliders()[0];
  ASSERT_EQ(sphere.type(), Collider::Type::Sphere);
  const Vec3 centre = sim.colliderState(0).pose.translation;
  const double reach = sphere.radius() + scene.contact.thickness;
  CollidersOverStep colliders;
  colliders.colliders = &sim.colliders();
  colliders.start = colliders.end = {sim.colliderState(0).pose};
  colliders.thickness = scene.contact.thickness;
  long queries = 0, detections = 0;
  int touched = 0;
  for (int step = 0; step < 48; ++step) {
    const VecX x0 = sim.positions();
    const StepStats st = sim.step();
    ASSERT_TRUE(st.ok) << st.failure;
    queries += st.contact_queries;
    detections += st.contact_passes + 1;  // begin, and an update after each solve
    touched = std::max(touched, st.contacts);
    // The broad phase on this step's paths against an independent count:
    // the 8 x 8 patches whose box of start and end positions meets the box
    // around the sphere.
    const VecX& x1 = sim.positions();
    ContactBroadPhase broad;
    broad.setGrid(64, 64);
    broad.build(colliders, x0, x1);
    size_t expected = 0;
    for (int pr = 0; pr < 8; ++pr) {
      for (int pc = 0; pc < 8; ++pc) {
        Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
        for (int r = 8 * pr; r < 8 * pr + 8; ++r) {
          for (int c = 8 * pc; c < 8 * pc + 8; ++c) {
            for (const VecX* x : {&x0, &x1}) {
              lo = lo.cwiseMin(x->segment<3>(3 * (64 * r + c)));
              hi = hi.cwiseMax(x->segment<3>(3 * (64 * r + c)));
            }
          }
        }
        const bool meets = (lo.array() <= (centre.array() + reach)).all() &&
                           (hi.array() >= (centre.array() - reach)).all();
        if (meets) expected += 64;
      }
    }
    EXPECT_EQ(broad.candidates().size(), expected) << "step " << step;
    int found = 0, dropped = 0;
    expectNoMiss(broad, colliders, x0, x1, &found, &dropped);
  }
  EXPECT_GT(touched, 0);  // the cloth reached the sphere
  EXPECT_GT(queries, 0);
  // Brute force would query every node each detection: 4096 a detection.
  EXPECT_LT(queries, detections * n / 8);
  std::printf("[ broad    ] %ld node queries in %ld detections (%.0f a detection of %d nodes)\n",
              queries, detections, static_cast<double>(queries) / detections, n);
}

}  // namespace
}  // namespace cloth_sim
