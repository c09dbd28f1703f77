// PairProjection (pair_constraints.hpp): self-contact pairs held at their gap
// inside a solve, as rows coupling four nodes; and what holding them that way
// does for a step (momentum kept, no energy made: the fling at stretch 1e8).
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "cloth_sim/constraint_filter.hpp"
#include "cloth_sim/pair_constraints.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"
#include "../common/cloth_checks.hpp"

namespace cloth_sim {
namespace {

constexpr int kNodes = 12;

VecX randomVector(std::mt19937& rng, int size) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  VecX v(size);
  for (int i = 0; i < size; ++i) v[i] = u(rng);
  return v;
}

/// A point-triangle pair (node p over triangle a, b, c with barycentric
/// weights) and an edge-edge pair sharing node a; plus the same point-triangle
/// pair again (a dependent row, as a contact seen twice).
std::vector<PairConstraint> somePairs() {
  PairConstraint pt;
  pt.node = {0, 1, 2, 3};
  pt.w = {1.0, -0.2, -0.5, -0.3};
  pt.n = Vec3(0.1, 0.2, 1.0).normalized();
  pt.target = 0.002;
  PairConstraint ee;
  ee.node = {1, 4, 5, 6};
  ee.w = {0.6, 0.4, -0.7, -0.3};
  ee.n = Vec3(-0.3, 1.0, 0.2).normalized();
  ee.target = 0.001;
  PairConstraint far;  // a group of its own
  far.node = {8, 9, 10, 11};
  far.w = {1.0, -0.1, -0.1, -0.8};
  far.n = Vec3(1.0, 0.0, 0.0);
  far.target = 0.0;
  return {pt, ee, pt, far};
}

/// The rows' values C v with the given node projectors applied to the rows.
double rowValue(const PairConstraint& p, const VecX& v) {
  Vec3 rel = Vec3::Zero();
  for (int k = 0; k < 4; ++k) rel += p.w[k] * v.segment<3>(3 * p.node[k]);
  return p.n.dot(rel);
}

TEST(PairProjection, ProjectsOntoThePairsNullSpaceAndCommutesWithTheNodeFilter) {
  ConstraintFilter filter;
  filter.reset(kNodes);
  filter.eliminate(2);  // a pinned triangle node
  const Vec3 up(0.0, 0.0, 1.0);
  filter.project(5, Mat3::Identity() - up * up.transpose());  // on a table
  filter.holdPairs(somePairs());
  std::mt19937 rng(7);
  for (int trial = 0; trial < 5; ++trial) {
    VecX v = randomVector(rng, 3 * kNodes);
    filter.apply(v);
    // Every pair's gap unchanged by v, the pin still, the table node in plane
    // (the repeated pair is dependent: kept once, held all the same).
    for (const PairConstraint& p : somePairs()) EXPECT_NEAR(rowValue(p, v), 0.0, 1e-12);
    EXPECT_EQ(v.segment<3>(6).norm(), 0.0);
    EXPECT_NEAR(v[3 * 5 + 2], 0.0, 1e-15);
    // A projector: applying it again changes nothing.
    VecX again = v;
    filter.apply(again);
    EXPECT_LT((again - v).norm(), 1e-12 * v.norm());
    // Symmetric: u . P w = P u . w.
    VecX u = randomVector(rng, 3 * kNodes), w = randomVector(rng, 3 * kNodes);
    VecX pu = u, pw = w;
    filter.apply(pu);
    filter.apply(pw);
    EXPECT_NEAR(u.dot(pw), pu.dot(w), 1e-13);
  }
  // The split layout gives the same.
  VecX v = randomVector(rng, 3 * kNodes), split(3 * kNodes);
  for (int i = 0; i < kNodes; ++i) {
    for (int c = 0; c < 3; ++c) split[c * kNodes + i] = v[3 * i + c];
  }
  filter.apply(v);
  filter.applySplit(split.data());
  for (int i = 0; i < kNodes; ++i) {
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(split[c * kNodes + i], v[3 * i + c], 1e-15);
  }
}

TEST(PairProjection, MeetPutsEveryPairAtItsGapWithTheSmallestAllowedChange) {
  ConstraintFilter filter;
  filter.reset(kNodes);
  filter.eliminate(2);
  filter.holdPairs(somePairs());
  std::mt19937 rng(11);
  const VecX base = 0.01 * randomVector(rng, 3 * kNodes);
  VecX v = randomVector(rng, 3 * kNodes);
  const VecX before = v;
  const double scale = 1e-3;
  filter.pairs().meet(base, scale, v);
  const VecX end = base + scale * v;
  for (const PairConstraint& p : somePairs()) EXPECT_NEAR(p.gap(end), p.target, 1e-14);
  // The pinned node's velocity is not touched, nor nodes outside every pair.
  EXPECT_EQ((v - before).segment<3>(6).norm(), 0.0);
  EXPECT_EQ((v - before).segment<3>(3 * 7).norm(), 0.0);
  // Smallest: the change has no part the filter would keep (it is in the
  // rows' span), so nothing smaller meets the rows.
  VecX change = v - before;
  filter.apply(change);
  EXPECT_LT(change.norm(), 1e-12 * (v - before).norm());
}

TEST(PairProjection, MultiplierSignSaysWhetherThePairPushesOrHolds) {
  PairProjection pairs;
  std::vector<PairConstraint> list = somePairs();
  pairs.assign(list);
  pairs.restrict([](int) { return Mat3::Identity(); });
  VecX reaction = VecX::Zero(3 * kNodes);
  const double lambda = 0.3;  // pushes the point off the triangle
  for (int k = 0; k < 4; ++k) reaction.segment<3>(3 * list[0].node[k]) += lambda * list[0].w[k] * list[0].n;
  // The point-triangle pair is listed twice: one of the two is kept and reads it.
  auto pointTriangle = [&](const VecX& r) {
    const std::vector<double> m = pairs.multipliers(r);
    return m[0] + m[2];
  };
  EXPECT_NEAR(pointTriangle(reaction), lambda, 1e-14);
  EXPECT_NEAR(pointTriangle(-reaction), -lambda, 1e-14);
  // A table under the triangle: its push up on those nodes is not the pair's.
  const Vec3 up(0.0, 0.0, 1.0);
  pairs.restrict([&](int node) {
    return node == 0 ? Mat3::Identity() : Mat3(Mat3::Identity() - up * up.transpose());
  });
  VecX table = reaction;
  for (int k = 1; k < 4; ++k) table.segment<3>(3 * list[0].node[k]) += 5.0 * up;
  EXPECT_NEAR(pointTriangle(table), lambda, 1e-14);
}

// The rows' multipliers from a reaction C^T lambda, where rows share a node
// (the point-triangle and the edge-edge pair share node 1) and a pin and a
// table add reactions of their own that the rows' restriction takes out.
// Read row by row (c . r / |c|^2), a row sharing a node took part of its
// neighbour's load: under the twist's pins one pulled with -1.05 N where
// that estimate said +0.01, and was kept holding.
TEST(PairProjection, MultipliersAreExactWhereRowsShareNodes) {
  PairProjection pairs;
  const std::vector<PairConstraint> list = somePairs();
  pairs.assign(list);
  const Vec3 up(0.0, 0.0, 1.0);
  const auto projector = [&](int node) {
    if (node == 2) return Mat3(Mat3::Zero());                           // pinned
    if (node == 5) return Mat3(Mat3::Identity() - up * up.transpose());  // on a table
    return Mat3(Mat3::Identity());
  };
  pairs.restrict(projector);
  const double lambda[4] = {-1.05, 2.8, 0.0, 0.4};  // the repeat (row 2) is dependent
  VecX reaction = VecX::Zero(3 * kNodes);
  for (size_t r = 0; r < list.size(); ++r) {
    for (int k = 0; k < 4; ++k) {
      const int i = list[r].node[k];
      reaction.segment<3>(3 * i) += lambda[r] * (projector(i) * (list[r].w[k] * list[r].n));
    }
  }
  reaction.segment<3>(3 * 2) += Vec3(3.0, -1.0, 7.0);  // the pin's own reaction
  reaction.segment<3>(3 * 5) += 4.0 * up;              // the table's push
  const std::vector<double> exact = pairs.multipliers(reaction);
  ASSERT_EQ(exact.size(), list.size());
  // One of the two repeated rows is kept and carries the load; the other reads 0.
  EXPECT_NEAR(exact[0] + exact[2], lambda[0], 1e-12);
  EXPECT_EQ(exact[0] * exact[2], 0.0);
  EXPECT_NEAR(exact[1], lambda[1], 1e-12);
  EXPECT_NEAR(exact[3], lambda[3], 1e-12);
}

TEST(PairProjection, APairLeftOnlyItsNormalsTiltIsNotHeld) {
  // Two layers on a table: every node of the pair may only slide across the
  // table, and the pair's normal is the table's to within a tilt. Held, its
  // row would close the gap through the tilt alone (a node moved 4.4e7 m in
  // the heap, s1): such a row is left to the filter; a tilt that leaves the
  // row a fair part of its norm is held.
  const Vec3 up(0.0, 0.0, 1.0);
  auto onTable = [&](int) { return Mat3(Mat3::Identity() - up * up.transpose()); };
  for (const double tilt : {1e-9, 0.05, 0.5}) {
    PairConstraint pair;
    pair.node = {0, 1, 2, 3};
    pair.w = {1.0, -0.2, -0.5, -0.3};
    pair.n = Vec3(tilt, 0.0, 1.0).normalized();
    pair.target = 0.002;
    PairProjection pairs;
    pairs.assign({pair});
    pairs.restrict(onTable);
    // Row c_k = w_k S n: |c|^2 = 1.38 sin^2, widest sin: held while
    // 1 / (1.38 sin) <= 4, i.e. sin >= 0.18.
    EXPECT_EQ(pairs.rows().size(), tilt > 0.2 ? 1u : 0u) << "tilt " << tilt;
    // What is held meets its gap; what is not leaves v alone.
    VecX v = VecX::Zero(3 * kNodes);
    const VecX base = VecX::Zero(3 * kNodes);
    pairs.meet(base, 1e-3, v);
    EXPECT_LT(v.lpNorm<Eigen::Infinity>(), 4.0 * pair.target / 1e-3 * (1.0 + 1e-12));
  }
}

// The stability map's fling (hard case s3) under bdf2 at stretch 1e8, dt
// 1e-3: held node by node, the re-solve after the filter gave the pushed
// nodes' stiff neighbours their velocity and gained 4e-3 J where the filter
// had taken 2e-4 J out, at every halving (a failure at t = 0.564 s, 8
// halvings). Held as pairs it passes, with no intersection.
TEST(PairProjection, FlingAtStretch1e8UnderBdf2Passes) {
  Simulation sim(loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/self/s3_fling.yaml",
                           {"solver.method=bdf2", "solver.dt=0.001",
                            "springs.stretch.stiffness=1e8"}));
  while (sim.time() < 0.62) {
    const StepStats s = sim.step();
    ASSERT_TRUE(s.ok) << "t = " << sim.time() << ": " << s.failure;
    ASSERT_TRUE(s.finite);
    ASSERT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0) << "t = " << sim.time();
  }
}

// The stability map's one failure of session 41: the twist at stretch 1e7
// under implicit_euler, dt 0.1. Pairs near the pins were let go (pulling),
// pushed and held again at every pass, and the filter's last push, which no
// solve followed, gained 0.2 J at dt/256. Not let go before the last solve,
// the run passes, with no intersection.
TEST(PairProjection, TwistAtStretch1e7AndDtTenthPasses) {
  Simulation sim(loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/self/s4_twist.yaml",
                           {"solver.method=implicit_euler", "solver.dt=0.1",
                            "springs.stretch.stiffness=1e7"}));
  while (sim.time() < 1.0 - 1e-9) {
    const StepStats s = sim.step();
    ASSERT_TRUE(s.ok) << "t = " << sim.time() << ": " << s.failure;
    ASSERT_TRUE(s.finite);
    ASSERT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0) << "t = " << sim.time();
  }
}

// The twist (hard case s4) under newton, as the suite runs it: from 0.8 s its
// flaps wrap around the pinned middle and the pins push them through pairs
// held as rows. A pin is eliminated from the rows, so its reaction leaves
// out what it pushes on them; counted from the filter's impulses instead
// (the pushed node's own mass, not the solve's inertia behind it), the
// pins' work was short by 1.6 % and every step gained 1e-6 J beyond it at
// every step size: 200 rejected sub-steps in [0.8, 0.9) s, 6 with the rows'
// own multipliers.
TEST(PairProjection, PinsPushingThroughHeldPairsAreCreditedTheirWork) {
  Simulation sim(loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/self/s4_twist.yaml",
                           {"solver.method=newton"}));
  int rejected = 0;
  while (sim.time() < 0.9 - 1e-9) {
    const bool window = sim.time() >= 0.8 - 1e-9;
    const StepStats s = sim.step();
    ASSERT_TRUE(s.ok) << "t = " << sim.time() << ": " << s.failure;
    if (window) rejected += s.rejected;
  }
  EXPECT_LE(rejected, 20);
  EXPECT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0);
}

}  // namespace
}  // namespace cloth_sim
