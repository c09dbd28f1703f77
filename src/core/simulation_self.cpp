// The cloth against itself inside a step: the self-collision filter on the
// solved step, and the solves again that let the filtered nodes' neighbours
// follow them (Simulation::filterSelfCollision, resolveSelfCollision).
#include <algorithm>
#include <chrono>
#include <vector>

#include "cloth_sim/simulation.hpp"

namespace cloth_sim {

namespace {

/// Nodes within this many self-collision thicknesses of a collider's band
/// are held against moves into it by the self-collision filter, as well as
/// those in contact. Not more: a held node is a wall for impulses pushing
/// it in, which does work where it moves along the normal. A free node
/// pushed into a collider anyway fails the step (halved).
constexpr double kSelfReach = 0.5;

/// Filter moves below this many thicknesses do not call for another solve
/// (the spring energy they store, ~k dx^2 / 2, is negligible) ...
constexpr double kSettledShift = 0.01;
/// ... unless their springs would store more than this fraction of the
/// energy scale (a tenth of the energy check's 1e-6): at stretch 1e7 a heap's
/// 8e-6 m moves (0.004 thicknesses) stored 3.5e-4 J, left unsolved, a gain
/// no halving shrank (the stability map's s1 failed at dt 1e-2 / 2^8).
constexpr double kSettledEnergy = 1e-7;
/// At most this many pairs are held as rows (pair_constraints.hpp); a step
/// whose filter pushes more holds every pushed node on its own instead, as
/// before rows existed. Rows cost a pivoted Cholesky of their Gram matrix
/// and the preconditioner's correction per factor: a heap of layers pushes
/// up to 376 pairs at once (229 independent). With every pair held, the heap
/// under bdf2 took 104-131 ms a step where 20 (session 41); with the
/// correction's sparse forward solves still 1.5-1.7x the CPU time of this
/// limit (8.0 s against 5.2 for 1 s), its pivoted Cholesky now the largest
/// part. A limit of 128 did worse than either in a trial (steps switching
/// between rows and nodes: 120 rejected attempts where 37 and 35).
constexpr size_t kMaxHeldPairs = 32;

using Clock = std::chrono::steady_clock;

/// Books the time since `start` as self-collision time of the step.
void chargeSelfCollision(Clock::time_point start, StepStats* stats) {
  const double spent = std::chrono::duration<double>(Clock::now() - start).count();
  stats->self_collision_s += spent;
  stats->wall_time_s += spent;
}

}  // namespace

void Simulation::filterSelfCollision(double h, StepStats* stats, SelfPinWork* work) {
  const auto start = Clock::now();
  selfCollisionMasses(pin_ends_.nodes, stepper_.contacts(), collider_step_, x_save_, x_,
                      kSelfReach * scene_.self_collision.thickness, &self_masses_);
  x_pre_self_ = x_;  // what the filter moved, for the collider check
  const SelfCollisionResult self = self_collision_.apply(model_, h, x_save_, self_masses_, x_, v_);
  chargeSelfCollision(start, stats);
  if (!self.ok) stats->ok = false, stats->failure = self.failure;
  work->zones += self.zone_pin_work;
  work->impulses_last = self.pin_work - self.zone_pin_work;
  work->impulses += work->impulses_last;
  std::string pushed;
  if (stats->ok && pushedIntoCollider(collider_step_, x_save_, x_pre_self_, x_, &pushed) >= 0) {
    stats->ok = false, stats->failure = pushed;
  }
}

double Simulation::repulsionEnergy(const VecX& x) {
  if (!repulsionOn()) return 0.0;
  const double dt = scene_.solver.dt;
  self_collision_.repulsionTerms(model_, x, x, kRepulsionReach * scene_.self_collision.thickness,
                                 kRepulsionStiffness / (dt * dt), &repulsion_measure_);
  return repulsion_measure_.energy(x);
}

void Simulation::measureSelfCollision(StepStats* stats) {
  const auto start = Clock::now();
  SelfCollisionResult measured;
  self_collision_.measure(x_, &measured);
  stats->self_contacts = measured.contacts;
  stats->min_self_distance = measured.min_distance;
  chargeSelfCollision(start, stats);
}

double Simulation::rowPinWork(const std::vector<double>& lambda) const {
  const std::vector<PairConstraint>& pairs = stepper_.heldPairs().pairs();
  // The row pushes node k by lambda w_k n; a pin holds its node against
  // that while moving by dx: it does -lambda w_k n . dx.
  double work = 0.0;
  for (size_t r = 0; r < pairs.size(); ++r) {
    const PairConstraint& p = pairs[r];
    for (int k = 0; k < 4; ++k) {
      const int i = p.node[k];
      if (!self_pinned_[i]) continue;
      work -= lambda[r] * p.w[k] * p.n.dot(x_.segment<3>(3 * i) - x_save_.segment<3>(3 * i));
    }
  }
  return work / stepper_.reactionScale();
}

void Simulation::resolveSelfCollision(double h, const History& history, std::optional<Method> as,
                                      StepStats* stats, SelfPinWork* pin_work) {
  // The filter moves the nodes of colliding pairs after the solve and leaves
  // their neighbours where the solve put them: the springs between store
  // about k dx^2 / 2, which at stiffness k h^2 / m >> 1 exceeds the kinetic
  // energy the inelastic impulse took out, and the energy check rejects the
  // step until halving makes dx small (a twisted cloth: 1439 rejected steps
  // in 1 s). Solved again with the pairs the filter pushed held at the gaps
  // it left them (one row a pair: pair_constraints.hpp), the neighbours
  // follow inside the implicit solve; the filter then checks the new answer,
  // and what it pushes joins the held set.
  filterSelfCollision(h, stats, pin_work);
  if (as.value_or(scene_.solver.method) == Method::SymplecticEuler) return;  // explicit: no solve
  // Nodes an impact zone moved are held node by node, only along the
  // filter's displacement: across it the node slides with the solve, as a
  // held pair slides across its normal (prescribing all of it lagged a
  // frictionless layer's slide: 7 mm where 15 mm without the second solve,
  // 45 mm converged). Such nodes near a collider are left to their
  // collider contact, which owns their projection (held whole instead, they
  // could not be let go, and a heap on a table rejected 100 steps for
  // energy). Not every node the solve put in collider contact: a layer lying
  // on a layer on the table falls through it in the solve, onto the table,
  // and the filter lifts it back; left free, each re-solve dropped it again
  // and the last filter's lift stayed unsolved (the fold demo at rest:
  // 1e-4-6e-4 J gained a step, every step split or refined).
  const int n = model_.numNodes();
  self_held_.assign(n, 0);
  self_target_.resize(n);
  self_direction_.resize(n);
  // A node that may reach a collider's band in this step is left free too:
  // its collider contact, added inside the solve, would meet the held
  // direction (the contact then wins, Stepper::yieldsToContact, and the
  // held node's target is lost: an energy gain that did not shrink with h).
  // Within kSelfReach thicknesses beyond the band as well, unless the filter
  // moved it away from the collider: held along that move it cannot come
  // nearer. Left free there, a top layer pressed onto the bottom one at the
  // table's edge by the tension of a cloth hanging from pins was lifted by
  // the filter every step and never re-solved (the fold demo with its pins
  // held 2 cm up: 3.3e-4 J gained a step, every step split 5 times deep).
  auto nearCollider = [&](int i, const Vec3& shift) {
    if (collider_step_.empty()) return false;
    const Vec3 p = x_.segment<3>(3 * i);
    const double band = collider_step_.thickness + (p - x_save_.segment<3>(3 * i)).norm();
    // Not a whole self thickness more: a layer resting on a layer on the
    // table is two thicknesses up and must stay held (else it is pushed up
    // each step, unheld: a folded drop gained 5.8e-6 J a step).
    const double margin = kSelfReach * scene_.self_collision.thickness;
    for (size_t k = 0; k < collider_step_.colliders->size(); ++k) {
      const SurfacePoint s = (*collider_step_.colliders)[k].closest(p, collider_step_.end[k]);
      if (s.distance < band) return true;
      if (s.distance < band + margin && !(shift.dot(s.normal) > 0.0)) return true;
    }
    return false;
  };
  self_pinned_.assign(n, 0);
  for (int node : pin_ends_.nodes) self_pinned_[node] = 1;
  // What the filter's last moves of the nodes a solve would hold (shift,
  // per node) store in the springs if left unsolved: sum over springs of
  // k (|dx_i| + |dx_j|)^2 / 2, a bound.
  std::vector<double> shift(n, 0.0);
  auto storedEnergy = [&] {
    double e = 0.0;
    for (const SpringGroup& g : model_.groups) {
      if (!g.present) continue;
      for (int k = g.begin; k < g.end; ++k) {
        const double d = shift[model_.springs[k].i] + shift[model_.springs[k].j];
        e += 0.5 * g.stiffness * d * d;
      }
    }
    return e;
  };
  std::vector<PairConstraint>& pairs = pin_ends_self_.pairs;
  pairs.clear();
  // Each held pair's multiplier in the last solve, read off its own answer
  // (before the filter moved it), exact where rows share nodes.
  std::vector<double> row_lambda;
  bool node_by_node = false;  // too many pairs: every pushed node held on its own
  for (int solve = 1; solve < kSelfSolves && stats->ok; ++solve) {
    bool changed = false;
    // A prescribed node whose constraint pulls it back (its reaction points
    // against the direction the filter pushed it) is let go: a contact only
    // pushes. The filter catches it if it then comes too close. The reaction
    // is the solve's own (Stepper::constraintImpulses): read off f(x1, v1)
    // after a linearized step, a stiff twist let go of nodes that still
    // pushed, the filter pushed them back, and its last push stayed unsolved
    // (stretch 1e8, dt 0.01: 1.7e-6 m, 3.7e-4 J gained at dt/256). A held
    // pair likewise, where its multiplier holds its sides together, but not
    // before the last solve: no solve follows it, so the filter's push of a
    // pair let go there would stay unsolved. A stiff twist's layers near its
    // pins were let go, pushed and held again at every pass, and the last
    // push moved a node 0.13 mm into springs of stretch 1e7 (0.2 J gained at
    // dt/256: the stability map's one failure). Held through the last solve,
    // such a pair at most holds its sides together for that step. A pair's
    // multiplier is read off the solve's own answer, before the filter moved
    // it, and exactly (rows sharing nodes share their load): read per row
    // after the filter, a pair under the twist's pins pulled with -1.05 N
    // where the estimate said +0.01, was held, and with its neighbour pulling
    // too did 2.6e-3 J of work a step (s4 at rest under bdf2).
    const bool last = solve == kSelfSolves - 1;
    if (solve > 1) {
      stepper_.constraintImpulses(model_, x_, v_, &force_);
      for (int i = 0; i < n; ++i) {
        if (self_held_[i] && self_direction_[i].dot(force_.segment<3>(3 * i)) < 0.0) {
          self_held_[i] = 0;
          changed = true;
        }
      }
      size_t kept = 0;
      for (size_t k = 0; k < pairs.size(); ++k) {
        if (!last && k < row_lambda.size() && row_lambda[k] < 0.0) {
          changed = true;
          continue;
        }
        pairs[kept++] = pairs[k];
      }
      pairs.resize(kept);
    }
    // The pairs the filter pushed apart are held at the gap it left them,
    // as one row each: both sides take the reaction (pair_constraints.hpp).
    // Only what impact zones moved is held node by node, along the move.
    for (const PairConstraint& pushed : self_collision_.pushedPairs()) {
      PairConstraint pair = pushed;
      // Never beyond the pair's gap at the step's start, the filter's own
      // bound: a row holding its sides apart (lambda > 0) does
      // lambda (gap - gap0) of work. The filter's sweeps can leave a pair a
      // little beyond it where other pairs lifted its nodes, and held there
      // under the pins' tension of the twist (hard case s4 at rest, bdf2)
      // 4.4e-6 m did 1e-3 J a step, every step rejected.
      pair.target = std::min(pair.gap(x_), pair.gap(x_save_));
      auto same = std::find_if(pairs.begin(), pairs.end(), [&](const PairConstraint& p) {
        return p.node == pair.node;
      });
      if (same == pairs.end()) {
        pairs.push_back(pair);
      } else {
        *same = pair;
      }
    }
    if (pairs.size() > kMaxHeldPairs) node_by_node = true;
    if (node_by_node) pairs.clear();
    std::fill(shift.begin(), shift.end(), 0.0);
    for (int i = 0; i < n; ++i) {
      if (self_pinned_[i]) continue;
      const Vec3 moved = x_.segment<3>(3 * i);
      const Vec3 dx = moved - x_pre_self_.segment<3>(3 * i);
      if (dx.squaredNorm() == 0.0) continue;
      const bool zone = node_by_node || self_collision_.movedInZone(i);
      if (zone && nearCollider(i, dx)) continue;
      shift[i] = dx.norm();
      if (shift[i] > kSettledShift * scene_.self_collision.thickness) changed = true;
      if (!zone) continue;
      if (!self_held_[i]) {
        self_held_[i] = 1;
        self_direction_[i] = dx.normalized();
      }
      self_target_[i] = moved;
    }
    if (!changed) changed = storedEnergy() > kSettledEnergy * energyScale();
    if (!changed) return;
    pin_ends_self_.nodes = pin_ends_.nodes;
    pin_ends_self_.targets = pin_ends_.targets;
    pin_ends_self_.reaction_read = pin_ends_.reaction_read;
    pin_ends_self_.directions.assign(pin_ends_.nodes.size(), Vec3::Zero());
    for (int i = 0; i < n; ++i) {
      if (!self_held_[i]) continue;
      pin_ends_self_.nodes.push_back(i);
      pin_ends_self_.targets.push_back(self_target_[i]);
      pin_ends_self_.directions.push_back(self_direction_[i]);
    }
    x_ = x_save_;
    v_ = v_save_;
    const StepStats again =
        stepper_.step(model_, h, pin_ends_self_, history, x_, v_, as, collider_step_);
    stats->addWork(again);
    stats->residual = std::max(stats->residual, again.residual);
    stats->newton_residual = again.newton_residual;
    stats->linear_converged = stats->linear_converged && again.linear_converged;
    stats->newton_converged = again.newton_converged;
    stats->contacts = again.contacts;
    stats->contact_normal_force = again.contact_normal_force;
    stats->max_penetration = again.max_penetration;
    stats->contact_work = again.contact_work;
    ++stats->self_solves;
    if (!again.ok) {
      stats->ok = false;
      stats->failure = again.failure;
      return;
    }
    // The pins' work through the zones of every pass adds up: what they
    // dragged in an earlier pass is held by the prescriptions in this
    // answer. Through pairs held as rows it is the rows' own: summed from
    // the earlier passes' impulses instead, it missed what the solve's
    // inertia behind a pushed node took (the twist, hard case s4, under
    // newton: 1.6 % of the pins' work gained at every step size, 349
    // rejected attempts).
    pin_work->solved_rows = !node_by_node;
    pin_work->rows = 0.0;
    row_lambda.assign(pairs.size(), 0.0);
    if (!pairs.empty()) {
      stepper_.constraintImpulses(model_, x_, v_, &force_);
      row_lambda = stepper_.heldPairs().multipliers(force_);
      pin_work->rows = rowPinWork(row_lambda);
    }
    filterSelfCollision(h, stats, pin_work);
  }
}

}  // namespace cloth_sim
