#include "grasp.hpp"

#include <limits>

namespace cloth_sim_ros {

std::vector<int> freeNodesWithin(const cloth_sim::Simulation& sim, const cloth_sim::Vec3& centre,
                                 double radius) {
  std::vector<int> nodes;
  for (int i = 0; i < sim.numNodes(); ++i) {
    if (!sim.isPinned(i) && (sim.position(i) - centre).norm() <= radius) nodes.push_back(i);
  }
  return nodes;
}

int nearestFreeNode(const cloth_sim::Simulation& sim, const cloth_sim::Vec3& centre,
                    double* distance) {
  int best = -1;
  *distance = std::numeric_limits<double>::infinity();
  for (int i = 0; i < sim.numNodes(); ++i) {
    const double d = (sim.position(i) - centre).norm();
    if (!sim.isPinned(i) && d < *distance) {
      *distance = d;
      best = i;
    }
  }
  return best;
}

void Grasps::add(const std::string& frame, const std::vector<int>& nodes) {
  nodes_[frame].insert(nodes.begin(), nodes.end());
}

std::vector<int> Grasps::take(const std::string& frame) {
  auto it = nodes_.find(frame);
  if (it == nodes_.end()) return {};
  std::vector<int> nodes(it->second.begin(), it->second.end());
  nodes_.erase(it);
  return nodes;
}

void Grasps::forget(int node) {
  for (auto it = nodes_.begin(); it != nodes_.end();) {
    it->second.erase(node);
    it = it->second.empty() ? nodes_.erase(it) : std::next(it);
  }
}

std::string Grasps::frameList() const {
  std::string out;
  for (const auto& entry : nodes_) out += (out.empty() ? "'" : ", '") + entry.first + "'";
  return out;
}

size_t Grasps::numNodes() const {
  size_t n = 0;
  for (const auto& entry : nodes_) n += entry.second.size();
  return n;
}

}  // namespace cloth_sim_ros
