// The gap of a pair of the cloth: a point and a triangle, or two edges, as
// four nodes' relative position sum_k w_k x_k (the closest points'
// difference) along a unit normal n. Shared by the self-repulsion terms
// (self_repulsion.hpp) and the pairs held inside a solve (pair_constraints.hpp).
#pragma once

#include <array>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

struct PairGap {
  std::array<int, 4> node{};
  std::array<double, 4> w{};
  Vec3 n = Vec3::UnitZ();
  /// n . sum_k w_k x_k (x: 3n positions)
  double gap(const VecX& x) const {
    double g = 0.0;
    for (int k = 0; k < 4; ++k) g += w[k] * n.dot(x.segment<3>(3 * node[k]));
    return g;
  }
};

}  // namespace cloth_sim
