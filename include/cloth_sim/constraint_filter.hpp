// Which directions of each node's velocity change an implicit solve may set
// (Baraff & Witkin 1998, section 5: constraint filtering inside PCG).
//
// Three kinds of node:
//  - free: every direction (the filter is I);
//  - eliminated: none (a pin; the filter is 0). The preconditioners leave
//    these nodes out of their structure, as before contact existed;
//  - projected: the range of a symmetric projector S (a contact: I - n n^T
//    while the node slides on a surface, 0 while it sticks). The
//    preconditioners see these nodes as free and the filter is applied to
//    what they return, so contacts that come and go never rebuild a
//    Cholesky pattern or a multigrid hierarchy.
// With no projected node the filter costs what the old 0/1 pin mask did.
//
// On top of the nodes' own filters, pairs of the cloth held at their gap
// (pair_constraints.hpp: rows coupling four nodes), restricted to what each
// node may do, so that the two projections commute.
#pragma once

#include <vector>

#include "cloth_sim/pair_constraints.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// A projected node's diagonal block D on the filtered system: S D S on the
/// range of S, tr(D)/3 across it. SPD when D is, and its inverse is exact on
/// the range of S (what the Cholesky factor, block Jacobi and the multigrid
/// smoother use for a projected node).
inline Mat3 projectedBlock(const Mat3& D, const Mat3& S) {
  return S * D * S + (Mat3::Identity() - S) * (D.trace() / 3.0);
}

class ConstraintFilter {
 public:
  ConstraintFilter() = default;
  /// From a 0/1 mask (1 = free, 0 = eliminated): the pins-only filter.
  ConstraintFilter(const std::vector<char>& free)  // NOLINT: implicit on purpose
      : free_(free), slot_(free.size(), -1) {
    for (size_t i = 0; i < free.size(); ++i) {
      if (!free[i]) eliminated_.push_back(static_cast<int>(i));
    }
  }

  /// Every node free, no pair held.
  void reset(int num_nodes) {
    free_.assign(num_nodes, 1);
    slot_.assign(num_nodes, -1);
    eliminated_.clear();
    nodes_.clear();
    projectors_.clear();
    pairs_.clear();
    pairs_stale_ = false;
  }
  /// Holds these pairs at their gaps too (replacing any held before).
  void holdPairs(const std::vector<PairConstraint>& pairs) {
    pairs_.assign(pairs);
    pairs_stale_ = !pairs.empty();
  }
  bool holdsPairs() const { return !pairs_.empty(); }
  /// Changes whenever the held pairs' restricted rows do (unique across filters).
  long pairsGeneration() const {
    if (pairs_stale_) restrictPairs();
    return pairs_generation_;
  }
  /// The held pairs, their rows restricted to the nodes' filters as they are now.
  const PairProjection& pairs() const {
    if (pairs_stale_) restrictPairs();
    return pairs_;
  }
  /// The node leaves the solve (a pin).
  void eliminate(int node) {
    pairs_stale_ = !pairs_.empty();
    if (free_[node]) eliminated_.push_back(node);
    free_[node] = 0;
    unproject(node);
  }
  /// The node keeps only the range of S (symmetric projector: S S = S).
  void project(int node, const Mat3& S) {
    if (!free_[node]) return;  // a pin wins over a contact
    pairs_stale_ = !pairs_.empty();
    if (slot_[node] < 0) {
      slot_[node] = static_cast<int>(nodes_.size());
      nodes_.push_back(node);
      projectors_.push_back(S);
    } else {
      projectors_[slot_[node]] = S;
    }
  }
  /// Removes a node's projection (it becomes free again, unless eliminated).
  void unproject(int node);

  int numNodes() const { return static_cast<int>(free_.size()); }
  /// 1 unless eliminated: the structure the preconditioners are built on.
  const std::vector<char>& freeMask() const { return free_; }
  bool isEliminated(int node) const { return !free_[node]; }
  bool isProjected(int node) const { return slot_[node] >= 0; }
  bool hasProjections() const { return !nodes_.empty(); }
  const std::vector<int>& projectedNodes() const { return nodes_; }
  /// S of a node (I when free, 0 when eliminated).
  Mat3 projector(int node) const {
    if (!free_[node]) return Mat3::Zero();
    return slot_[node] < 0 ? Mat3::Identity() : projectors_[slot_[node]];
  }

  /// v <- S v for every node, then off the held pairs' rows.
  void apply(VecX& v) const {
    applyNodes(v);
    if (!pairs_.empty()) pairs().project(v);
  }
  /// v <- S v for every node (the pairs left out).
  void applyNodes(VecX& v) const {
    for (int i : eliminated_) v.segment<3>(3 * i).setZero();
    applyProjections(v);
  }
  /// v <- S v on the projected nodes only (eliminated ones already zero).
  void applyProjections(VecX& v) const {
    for (size_t k = 0; k < nodes_.size(); ++k) {
      const int i = nodes_[k];
      v.segment<3>(3 * i) = projectors_[k] * Vec3(v.segment<3>(3 * i));
    }
  }
  /// v <- S v for a vector split by component (v[c * n + i], n nodes: the
  /// layout of conjugateGradient's vectors).
  void applySplit(double* v) const;

  /// The nodes' filters alike (what a preconditioner is built on; the pairs
  /// act on its output only).
  bool operator==(const ConstraintFilter& o) const {
    return free_ == o.free_ && nodes_ == o.nodes_ && projectors_ == o.projectors_;
  }

 private:
  std::vector<char> free_;
  std::vector<int> slot_;  ///< index into nodes_/projectors_, -1 if not projected
  std::vector<int> eliminated_;  ///< the nodes with free_ 0
  std::vector<int> nodes_;
  std::vector<Mat3> projectors_;
  mutable PairProjection pairs_;
  /// the nodes' filters changed since the pairs' rows were restricted
  mutable bool pairs_stale_ = false;
  mutable long pairs_generation_ = 0;
  void restrictPairs() const;
};

}  // namespace cloth_sim
