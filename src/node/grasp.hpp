// Grasps (~grasp, ~release_grasp): which nodes each frame holds. The pins
// themselves are FramePins attachments (or fixed pins for the node's own
// frame); this keeps the bookkeeping and the node selection. No physics.
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

#include "cloth_sim/simulation.hpp"

namespace cloth_sim_ros {

/// Unpinned nodes within `radius` of `centre` (fixed frame), ascending.
std::vector<int> freeNodesWithin(const cloth_sim::Simulation& sim, const cloth_sim::Vec3& centre,
                                 double radius);
/// The unpinned node nearest to `centre`, or -1 if every node is pinned; its
/// distance in *distance.
int nearestFreeNode(const cloth_sim::Simulation& sim, const cloth_sim::Vec3& centre,
                    double* distance);

class Grasps {
 public:
  void add(const std::string& frame, const std::vector<int>& nodes);
  /// Removes frame's grasp; its nodes, ascending (empty if it had none).
  std::vector<int> take(const std::string& frame);
  /// A node released or re-pinned by another request leaves its grasp.
  void forget(int node);
  void clear() { nodes_.clear(); }
  bool has(const std::string& frame) const { return nodes_.count(frame) != 0; }
  /// The frames holding a grasp, for messages.
  std::string frameList() const;
  size_t numNodes() const;

 private:
  std::map<std::string, std::set<int>> nodes_;
};

}  // namespace cloth_sim_ros
