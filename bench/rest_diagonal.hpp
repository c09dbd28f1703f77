// The length every benchmark error is divided by: the cloth's diagonal at
// rest (cloth_sim_bench, bullet_check, cloth_sim_self_bench).
#pragma once

#include "cloth_sim/model.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim::bench {

/// The diagonal of the box around the model's rest positions (m).
inline double restDiagonal(const Model& model) {
  const VecX& x = model.rest_positions;
  Vec3 lo = x.head<3>(), hi = x.head<3>();
  for (int i = 1; i < model.numNodes(); ++i) {
    lo = lo.cwiseMin(x.segment<3>(3 * i));
    hi = hi.cwiseMax(x.segment<3>(3 * i));
  }
  return (hi - lo).norm();
}

}  // namespace cloth_sim::bench
