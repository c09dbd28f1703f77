#include "cloth_sim/spring_layout.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "cloth_sim/model.hpp"

namespace cloth_sim {

std::shared_ptr<const SpringLayout> layOutSprings(int num_nodes,
                                                  const std::vector<Spring>& springs) {
  auto layout = std::make_shared<SpringLayout>();
  layout->num_nodes = num_nodes;
  auto& directions = layout->directions;
  for (size_t k = 0; k < springs.size(); ++k) {
    const Spring& s = springs[k];
    const int lo = std::min(s.i, s.j), hi = std::max(s.i, s.j);
    if (lo < 0 || hi >= num_nodes || lo == hi) {
      throw std::invalid_argument("spring " + std::to_string(k) + " joins nodes " +
                                  std::to_string(s.i) + " and " + std::to_string(s.j) +
                                  " of " + std::to_string(num_nodes));
    }
    size_t d = 0;
    while (d < directions.size() &&
           (directions[d].type != s.type || directions[d].offset != hi - lo)) {
      ++d;
    }
    if (d == directions.size()) {
      SpringDirection dir;
      dir.type = s.type;
      dir.offset = hi - lo;
      dir.slots = num_nodes - dir.offset;
      for (std::vector<double>* a : {&dir.valid, &dir.rest_length, &dir.inv_rest_length,
                                     &dir.rest_dir[0], &dir.rest_dir[1], &dir.rest_dir[2]}) {
        a->assign(num_nodes, 0.0);
      }
      directions.push_back(std::move(dir));
    }
    SpringDirection& dir = directions[d];
    if (dir.valid[lo] != 0.0) {
      throw std::invalid_argument("two springs of one type join nodes " + std::to_string(lo) +
                                  " and " + std::to_string(hi));
    }
    dir.valid[lo] = 1.0;
    dir.rest_length[lo] = s.rest_length;
    dir.inv_rest_length[lo] = s.rest_length > 0.0 ? 1.0 / s.rest_length : 0.0;
    const double sign = s.i == lo ? 1.0 : -1.0;  // rest_direction points from i to j
    for (int c = 0; c < 3; ++c) dir.rest_dir[c][lo] = sign * s.rest_direction[c];
    layout->slot.push_back({static_cast<int>(d), lo, hi});
  }
  return layout;
}

}  // namespace cloth_sim
