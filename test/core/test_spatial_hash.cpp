// The broad phase finds every pair brute force finds, and its work grows
// linearly with a flat cloth's nodes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "cloth_sim/collision_geometry.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/spatial_hash.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

bool adjacent(const std::vector<int>& a, const std::vector<int>& b) {
  for (int i : a)
    for (int j : b)
      if (i == j) return true;
  return false;
}

TEST(SpatialHash, FindsEveryPairBruteForceFinds) {
  const Model model = buildModel(test::bareScene(9, 11));
  const CollisionMesh mesh = buildCollisionMesh(model.numNodes(), model.triangles);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.15, 0.15);
  for (int trial = 0; trial < 5; ++trial) {
    // A crumpled cloth and a random motion (some nodes move far).
    VecX x0 = model.rest_positions, x1 = x0;
    for (int k = 0; k < x0.size(); ++k) {
      x0[k] += u(rng);
      x1[k] = x0[k] + (k % 17 == 0 ? 5.0 : 1.0) * u(rng);
    }
    const double gap = 0.02;
    SpatialHash hash;
    CandidatePairs pairs;
    hash.findPairs(mesh, x0, x1, gap, &pairs);
    std::vector<Box> node_box(model.numNodes());
    for (int i = 0; i < model.numNodes(); ++i) node_box[i] = sweptNodeBox(x0, x1, i, 0.5 * gap);
    auto boxOf = [&](const std::vector<int>& nodes) {
      Box b = node_box[nodes[0]];
      for (int i : nodes) b = Box{b.lo.cwiseMin(node_box[i].lo), b.hi.cwiseMax(node_box[i].hi)};
      return b;
    };
    std::vector<std::pair<int, int>> pt, ee;
    for (int i = 0; i < model.numNodes(); ++i)
      for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const auto& tri = mesh.triangles[t];
        const std::vector<int> tn = {tri[0], tri[1], tri[2]};
        if (!adjacent({i}, tn) && node_box[i].overlaps(boxOf(tn))) pt.emplace_back(i, int(t));
      }
    for (size_t a = 0; a < mesh.edges.size(); ++a)
      for (size_t b = a + 1; b < mesh.edges.size(); ++b) {
        const std::vector<int> ea = {mesh.edges[a][0], mesh.edges[a][1]};
        const std::vector<int> eb = {mesh.edges[b][0], mesh.edges[b][1]};
        if (!adjacent(ea, eb) && boxOf(ea).overlaps(boxOf(eb))) ee.emplace_back(int(a), int(b));
      }
    EXPECT_GT(pt.size(), 50u);
    EXPECT_GT(ee.size(), 50u);
    EXPECT_EQ(pairs.point_triangle, pt);
    EXPECT_EQ(pairs.edge_edge, ee);
  }
}

TEST(SpatialHash, KeptPairsGiveWhatAFreshQueryGives) {
  // A step's queries: small moves (answered from the kept pairs), a gap
  // change, a static measure, and a move beyond the margin (hashed again).
  // Each answer must equal a hash without reuse, pair for pair.
  const Model model = buildModel(test::bareScene(9, 11));
  const CollisionMesh mesh = buildCollisionMesh(model.numNodes(), model.triangles);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  VecX x0 = model.rest_positions;
  for (int k = 0; k < x0.size(); ++k) x0[k] += 0.15 * u(rng);
  VecX x1 = x0;
  for (int k = 0; k < x1.size(); ++k) x1[k] += 0.05 * u(rng);
  const double margin = 0.01;
  SpatialHash kept, fresh;
  kept.setReuseMargin(margin);
  CandidatePairs a, b;
  struct Query {
    double move, gap;
    bool still;  // x0 = x1 (a measure)
  };
  const Query queries[] = {{0.0, 0.02, false},  {0.003, 0.02, false}, {0.003, 0.002, false},
                           {0.0, 0.02, true},   {0.004, 0.02, false}, {0.2, 0.02, false},
                           {0.002, 0.02, false}};
  for (const Query& q : queries) {
    for (int k = 0; k < x1.size(); ++k) x1[k] += q.move * u(rng);
    const VecX& start = q.still ? x1 : x0;
    kept.findPairs(mesh, start, x1, q.gap, &a);
    fresh.findPairs(mesh, start, x1, q.gap, &b);
    EXPECT_GT(a.point_triangle.size() + a.edge_edge.size(), 20u);
    EXPECT_EQ(a.point_triangle, b.point_triangle);
    EXPECT_EQ(a.edge_edge, b.edge_edge);
  }
  // Hashed: the first query, the 0.2 m move and whichever small moves
  // added up past the margin; the rest came from the kept pairs.
  EXPECT_GE(kept.hashedQueries(), 2);
  EXPECT_GE(kept.reusedQueries(), 3);
  EXPECT_EQ(kept.hashedQueries() + kept.reusedQueries(), 7);
  EXPECT_EQ(fresh.reusedQueries(), 0);
}

TEST(SpatialHash, DistanceCullLeavesOutOnlyPairsThatStayBeyondItsReach) {
  // Kept pairs and small moves, as a step's queries: each pair a cull leaves
  // out (a fresh query's pair missing from the culled answer) stays farther
  // than `below` all along the motion x0 -> x1, and the reported bound is no
  // more than its distance. On a flat cloth, nearly every pair is left out:
  // they are a mesh spacing apart.
  const Model model = buildModel(test::bareScene(9, 11));
  const CollisionMesh mesh = buildCollisionMesh(model.numNodes(), model.triangles);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const double crumple : {0.0, 0.05}) {
    VecX x0 = model.rest_positions;
    for (int k = 0; k < x0.size(); ++k) x0[k] += crumple * u(rng);
    VecX x1 = x0;
    SpatialHash kept, fresh, stopping;
    kept.setReuseMargin(0.01);
    stopping.setReuseMargin(0.01);
    size_t found = 0, left_out = 0;
    for (int query = 0; query < 6; ++query) {
      for (int k = 0; k < x1.size(); ++k) x1[k] += 0.002 * u(rng);
      const double gap = 0.01;
      const double below = query % 2 ? gap : 3.0 * gap;
      CandidatePairs a, b;
      kept.findPairs(mesh, x0, x1, gap, &a, DistanceCull{below, 1.0});
      fresh.findPairs(mesh, x0, x1, gap, &b);
      // Without the exact bound the scan stops early: the same pairs, and a
      // bound no higher than the exact one.
      CandidatePairs c;
      stopping.findPairs(mesh, x0, x1, gap, &c, DistanceCull{below, 1.0, false});
      EXPECT_EQ(c.point_triangle, a.point_triangle);
      EXPECT_EQ(c.edge_edge, a.edge_edge);
      EXPECT_LE(c.culled_bound, a.culled_bound);
      found += b.point_triangle.size() + b.edge_edge.size();
      double nearest = std::numeric_limits<double>::infinity();
      auto check = [&](const std::array<int, 4>& nodes, bool point_triangle) {
        for (double t = 0.0; t <= 1.0; t += 0.125) {
          const VecX x = (1.0 - t) * x0 + t * x1;
          std::array<Vec3, 4> p;
          for (int k = 0; k < 4; ++k) p[k] = x.segment<3>(3 * nodes[k]);
          const double d = point_triangle ? pointTriangleDistance(p[0], p[1], p[2], p[3])
                                          : edgeEdgeDistance(p[0], p[1], p[2], p[3]);
          EXPECT_GT(d, below);
          nearest = std::min(nearest, d);
        }
      };
      for (const auto& pair : b.point_triangle) {
        if (std::binary_search(a.point_triangle.begin(), a.point_triangle.end(), pair)) continue;
        ++left_out;
        const Eigen::Vector3i& t = mesh.triangles[pair.second];
        check({pair.first, t[0], t[1], t[2]}, true);
      }
      for (const auto& pair : b.edge_edge) {
        if (std::binary_search(a.edge_edge.begin(), a.edge_edge.end(), pair)) continue;
        ++left_out;
        const Eigen::Vector2i& ea = mesh.edges[pair.first];
        const Eigen::Vector2i& eb = mesh.edges[pair.second];
        check({ea[0], ea[1], eb[0], eb[1]}, false);
      }
      // Everything the culled answer has, the fresh one has too.
      EXPECT_TRUE(std::includes(b.point_triangle.begin(), b.point_triangle.end(),
                                a.point_triangle.begin(), a.point_triangle.end()));
      EXPECT_TRUE(std::includes(b.edge_edge.begin(), b.edge_edge.end(), a.edge_edge.begin(),
                                a.edge_edge.end()));
      EXPECT_LE(a.culled_bound, nearest);
      EXPECT_TRUE(std::isinf(b.culled_bound));
    }
    if (crumple == 0.0) EXPECT_GT(left_out, found * 9 / 10);
    EXPECT_GT(left_out, 0u);
  }
}

TEST(SpatialHash, EdgesAreUniqueAndComplete) {
  const Model model = buildModel(test::bareScene(4, 5));
  const CollisionMesh mesh = buildCollisionMesh(model.numNodes(), model.triangles);
  // A 4 x 5 grid: 4*4 horizontal + 3*5 vertical + 3*4 diagonal edges.
  EXPECT_EQ(mesh.edges.size(), 16u + 15u + 12u);
}

TEST(SpatialHash, CandidatesGrowLinearlyOnAFlatCloth) {
  // A flat falling cloth: each node's candidates are its near neighbours, so
  // the pairs per node stay the same from 16x16 to 64x64.
  double per_node[2];
  int k = 0;
  for (int n : {16, 64}) {
    Scene s = test::bareScene(n, n);
    const Model model = buildModel(s);
    const CollisionMesh mesh = buildCollisionMesh(model.numNodes(), model.triangles);
    VecX x1 = model.rest_positions;
    for (int i = 0; i < model.numNodes(); ++i) x1[3 * i + 2] -= 0.2 / n;  // under a cell per step
    SpatialHash hash;
    CandidatePairs pairs;
    hash.findPairs(mesh, model.rest_positions, x1, 0.002, &pairs);
    per_node[k++] = double(pairs.point_triangle.size() + pairs.edge_edge.size()) / model.numNodes();
  }
  EXPECT_LT(per_node[1], 1.2 * per_node[0]);
  EXPECT_LT(per_node[1], 40.0);
}

}  // namespace
}  // namespace cloth_sim
