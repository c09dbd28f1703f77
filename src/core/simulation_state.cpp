// Simulation::setState (a start the scene file cannot describe) and the
// measure of a state (measureState).
#include "cloth_sim/simulation.hpp"

namespace cloth_sim {

void Simulation::measureState() {
  measures_ = measureEnergy(model_, x_, v_);
  measures_.repulsion = repulsionEnergy(x_);
  energy_window_.clear();  // a new state: no balance carried over
}

Status Simulation::setState(const VecX& x, const VecX& v) {
  const long size = 3L * numNodes();
  if (x.size() != size || v.size() != size) {
    return Status::error("setState: expected " + std::to_string(size) +
                         " coordinates, got " + std::to_string(x.size()) + " and " +
                         std::to_string(v.size()));
  }
  if (!x.allFinite() || !v.allFinite()) return Status::error("setState: not finite");
  x_ = x;
  v_ = v;
  has_prev_ = false;
  for (auto& [node, pin] : pins_) pin.position = position(node);
  stepper_.clearContacts();
  measureState();
  last_stats_.energy = measures_.total();
  last_stats_.max_strain = measures_.max_strain;
  return Status::success();
}

}  // namespace cloth_sim
