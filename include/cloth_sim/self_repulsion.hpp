// Repulsion and friction between close parts of the cloth inside the
// implicit solve (Bridson, Fedkiw & Anderson 2002's repulsion springs, taken
// implicitly; friction lagged and smoothed as IPC's, Li et al. 2020).
// Each point-triangle pair closer than a reach at the step's start, or
// predicted to come so close, becomes a term over its four nodes with the
// closest points' weights w (sum 0) and normal n frozen there:
// - normal: its gap g(x) = n . sum_k w_k x_k is linear in x, its energy
//   1/2 k (reach - g)^2 while g < reach (0 beyond); the Hessian of an active
//   term, k (w (x) n)(w (x) n)^T, is exact and PSD (rank 1);
// - friction: the tangential relative velocity u = (I - n n^T) sum_k w_k v_k
//   meets a force -mu lambda f1(|u|) u / |u| with lambda the normal force at
//   the step's start (lagged) and f1 Coulomb's sign smoothed below
//   kFrictionSmoothing (m/s): a dissipation potential mu lambda f0(|u|) that
//   Newton's incremental potential includes, and a drag block
//   mu lambda f1(|u|) / |u| (w (x) T)(w (x) T)^T (its PSD part) in the matrix.
//
// Why: layers resting on layers were otherwise pushed apart by the
// post-step filter after every solve and solved again with the pushed nodes
// held (the fold demo at rest: 1.4 re-solves and 7 contact passes a step,
// and an energy floor of ~7e-7 J a step from the holds; docs/design.md).
#pragma once

#include <array>
#include <vector>

#include "cloth_sim/pair_gap.hpp"
#include "cloth_sim/system_matrix.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// One repulsion term: gap g(x) = n . sum_k w[k] x_{node[k]} (PairGap).
struct RepulsionTerm : PairGap {
  double stiffness = 0.0;  ///< k (N/m)
  double reach = 0.0;      ///< the gap below which the term pushes (m)
  /// mu lambda: the friction coefficient times the normal force at the
  /// step's start (N; 0: no friction)
  double friction = 0.0;
  /// In a linearized step's system (addToSystem with `linearized`): its
  /// quadratic is on, unclamped. Starts as g(x0) < reach; updateActiveSet.
  bool active = true;
  /// The tangential part of sum_k w_k v_k.
  Vec3 slip(const VecX& v) const {
    Vec3 u = Vec3::Zero();
    for (int k = 0; k < 4; ++k) u += w[k] * v.segment<3>(3 * node[k]);
    return u - n * n.dot(u);
  }
};

class SelfRepulsion {
 public:
  /// Below this slip speed (m/s) friction's force grows from 0 to mu lambda
  /// (IPC's f1; a sticking layer creeps at a fraction of it under load).
  static constexpr double kFrictionSmoothing = 1e-3;
  void clear() { terms_.clear(); }
  bool empty() const { return terms_.empty(); }
  int size() const { return static_cast<int>(terms_.size()); }
  void add(const RepulsionTerm& term) { terms_.push_back(term); }
  void replace(int k, const RepulsionTerm& term) { terms_[k] = term; }
  const std::vector<RepulsionTerm>& terms() const { return terms_; }

  /// Sum over the terms of 1/2 k (reach - g(x))^2 where g(x) < reach (J).
  double energy(const VecX& x) const;
  /// Friction's dissipation potential at velocities v: sum mu lambda f0(|u|)
  /// (W; its gradient in v is minus the friction forces).
  double frictionPotential(const VecX& v) const;
  /// f += the terms' forces at (x, v): k (reach - g) w_k n on node k where
  /// g < reach, and friction.
  void addForces(const VecX& x, const VecX& v, VecX& f) const;
  /// The terms into the system matrix A = M - a df/dv - b df/dx: b k (w (x) n)
  /// (w (x) n)^T and friction's a mu lambda f1 / |u| (w (x) T)(w (x) T)^T, with
  /// their forces at (x, v) into f and, if given, df/dx w into dfdx_w (as
  /// assembleSystem). Newton's iterates (`linearized` false): the normal
  /// parts pushing at x (g(x) < reach), exact. A linearized step: the active
  /// ones, their force linear in the gap (a force that clamps at the reach
  /// has no useful linearization there).
  void addToSystem(const VecX& x, const VecX& v, double a, double b, bool linearized,
                   SystemMatrix& A, VecX& f, const VecX* w = nullptr,
                   VecX* dfdx_w = nullptr) const;
  /// A linearized step's active set at its answer x: on where g(x) < reach.
  /// Returns how many terms changed (a linearized step with a changed set
  /// is solved again: a term left on beyond its reach pulls, one left off
  /// inside it lets the pair through).
  int updateActiveSet(const VecX& x);

 private:
  std::vector<RepulsionTerm> terms_;
};

}  // namespace cloth_sim
