// What the self-collision benchmark measures in a cloth state, the same way
// for cloth_sim's and Bullet's trajectories: the number of intersecting
// pairs of non-adjacent triangles (the hard-case suites' exact count,
// test/common/cloth_checks.hpp, reused as is) and the smallest distance
// between non-adjacent primitives (node-triangle, edge-edge) below a cutoff.
#pragma once

#include <algorithm>
#include <array>
#include <limits>
#include <set>
#include <utility>
#include <vector>

#include "../test/common/cloth_checks.hpp"
#include "cloth_sim/collision_geometry.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim::bench {

using cloth_sim::test::selfIntersections;

/// Smallest distance between a node and a triangle not containing it, or
/// between two triangle edges sharing no node, if below `cutoff`; else
/// infinity. Boxes grown by the cutoff and a sweep along x keep it cheap
/// (a 20 x 20 cloth: well under a millisecond when spread out).
inline double minSelfDistance(const Model& m, const VecX& x, double cutoff) {
  const auto p = [&](int i) { return Vec3(x.segment<3>(3 * i)); };
  double best = std::numeric_limits<double>::infinity();
  // Triangles (node-triangle pairs).
  const auto& T = m.triangles;
  std::vector<Eigen::AlignedBox3d> tbox(T.size());
  for (size_t t = 0; t < T.size(); ++t) {
    for (int k = 0; k < 3; ++k) tbox[t].extend(p(T[t][k]));
    tbox[t].min().array() -= cutoff;
    tbox[t].max().array() += cutoff;
  }
  for (int i = 0; i < m.numNodes(); ++i) {
    const Vec3 q = p(i);
    for (size_t t = 0; t < T.size(); ++t) {
      if (T[t][0] == i || T[t][1] == i || T[t][2] == i || !tbox[t].contains(q)) continue;
      best = std::min(best, pointTriangleDistance(q, p(T[t][0]), p(T[t][1]), p(T[t][2])));
    }
  }
  // Edges (edge-edge pairs), swept along x.
  std::set<std::pair<int, int>> unique;
  for (const auto& t : T) {
    for (int k = 0; k < 3; ++k) {
      unique.insert(std::minmax(t[k], t[(k + 1) % 3]));
    }
  }
  std::vector<std::pair<int, int>> edges(unique.begin(), unique.end());
  std::vector<Eigen::AlignedBox3d> ebox(edges.size());
  std::vector<int> order(edges.size());
  for (size_t e = 0; e < edges.size(); ++e) {
    ebox[e].extend(p(edges[e].first));
    ebox[e].extend(p(edges[e].second));
    ebox[e].max().array() += cutoff;
    order[e] = static_cast<int>(e);
  }
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return ebox[a].min().x() < ebox[b].min().x(); });
  for (size_t ia = 0; ia < order.size(); ++ia) {
    const auto& a = edges[order[ia]];
    for (size_t ib = ia + 1; ib < order.size(); ++ib) {
      const auto& b = edges[order[ib]];
      if (ebox[order[ib]].min().x() > ebox[order[ia]].max().x()) break;
      if (!ebox[order[ia]].intersects(ebox[order[ib]])) continue;
      if (a.first == b.first || a.first == b.second || a.second == b.first ||
          a.second == b.second) {
        continue;
      }
      best = std::min(best, edgeEdgeDistance(p(a.first), p(a.second), p(b.first), p(b.second)));
    }
  }
  return best < cutoff ? best : std::numeric_limits<double>::infinity();
}

}  // namespace cloth_sim::bench
