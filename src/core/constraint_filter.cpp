#include "cloth_sim/constraint_filter.hpp"

namespace cloth_sim {

void ConstraintFilter::unproject(int node) {
  const int k = slot_[node];
  if (k < 0) return;
  pairs_stale_ = !pairs_.empty();
  // Swap with the last entry so the lists stay dense.
  const int last = static_cast<int>(nodes_.size()) - 1;
  nodes_[k] = nodes_[last];
  projectors_[k] = projectors_[last];
  slot_[nodes_[k]] = k;
  nodes_.pop_back();
  projectors_.pop_back();
  slot_[node] = -1;
}

void ConstraintFilter::applySplit(double* v) const {
  const size_t n = free_.size();
  for (int i : eliminated_) v[i] = v[n + i] = v[2 * n + i] = 0.0;
  for (size_t k = 0; k < nodes_.size(); ++k) {
    const size_t i = nodes_[k];
    const Vec3 s = projectors_[k] * Vec3(v[i], v[n + i], v[2 * n + i]);
    v[i] = s[0];
    v[n + i] = s[1];
    v[2 * n + i] = s[2];
  }
  if (!pairs_.empty()) pairs().projectSplit(v, static_cast<int>(n));
}

void ConstraintFilter::restrictPairs() const {
  static long generations = 0;  // one counter for every filter
  pairs_.restrict([this](int node) { return projector(node); });
  pairs_stale_ = false;
  pairs_generation_ = ++generations;
}

}  // namespace cloth_sim
