// The springs by direction: springs of one type whose ends are the same
// index offset apart (a grid's rows, columns, diagonals and bends) form a
// direction, and a direction keeps one slot per node: slot p holds the
// spring whose lower-index end is p (ends p and p + offset), or nothing. The
// per-spring loops (forces, the system matrix, its product, the energy) then
// run as sweeps over contiguous per-slot arrays, which the compiler
// vectorises, instead of gathering and scattering per spring. A grid has at
// most six directions; empty slots (row ends) cost their share of a sweep.
#pragma once

#include <memory>
#include <vector>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

struct Spring;

struct SpringDirection {
  SpringType type = SpringType::Stretch;
  int offset = 0;  ///< upper end - lower end
  int slots = 0;   ///< num_nodes - offset: slot p < slots may hold a spring
  // Per slot, zero where there is no spring:
  std::vector<double> valid;        ///< 1 where a spring
  std::vector<double> rest_length;  ///< L
  std::vector<double> inv_rest_length;
  std::vector<double> rest_dir[3];  ///< unit, lower end to upper end, by component
};

/// Where spring k lives: its direction and slot (= its lower end), and its
/// upper end.
struct SpringSlot {
  int direction = 0;
  int node = 0;
  int other = 0;
};

struct SpringLayout {
  int num_nodes = 0;
  std::vector<SpringDirection> directions;
  std::vector<SpringSlot> slot;  ///< per spring
};

/// Lays out `springs` between num_nodes nodes. Throws std::invalid_argument if
/// a spring joins a node to itself or to one outside [0, num_nodes), or two
/// springs of one type join the same two nodes.
std::shared_ptr<const SpringLayout> layOutSprings(int num_nodes,
                                                  const std::vector<Spring>& springs);

}  // namespace cloth_sim
