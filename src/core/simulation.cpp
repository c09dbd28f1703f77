#include "cloth_sim/simulation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>

#include "cloth_sim/forces.hpp"
#include "step_failure_text.hpp"

namespace cloth_sim {

namespace {

/// Checks a list of node indices: range and duplicates. `field` names it.
Status checkIndices(const std::vector<int>& indices, int num_nodes, const std::string& field,
                    bool allow_empty = false) {
  if (indices.empty() && !allow_empty) return Status::error(field + ": empty list");
  std::set<int> seen;
  for (size_t k = 0; k < indices.size(); ++k) {
    const std::string at = field + "[" + std::to_string(k) + "]";
    if (indices[k] < 0 || indices[k] >= num_nodes) {
      return Status::error(at + ": index " + std::to_string(indices[k]) + " out of range [0, " +
                           std::to_string(num_nodes - 1) + "]");
    }
    if (!seen.insert(indices[k]).second) {
      return Status::error(at + ": duplicate index " + std::to_string(indices[k]));
    }
  }
  return Status::success();
}

bool finite(const Vec3& v) { return v.allFinite(); }

/// Relative energy gain (of the energy scale) a step may show: round-off
/// plus what an inexact CG solve (tolerance 1e-2 and up) can add.
constexpr double kEnergyGainTolerance = 1e-6;
/// The same for a step Newton solved to its tolerance (newton, bdf2): what
/// the stability map and the hard-case suites hold every step to.
constexpr double kTightEnergyGainTolerance = 1e-9;
/// A refined implicit_euler step's Newton stops at an iterate that passes the
/// energy check once its decrement (the potential's predicted further
/// decrease) is below this fraction of the energy scale. 1e-4: the demo at
/// stretch 1e6, 3.5 Newton iterations a step instead of 6.6; 1e-5 did not
/// make the pin-jump hard case more accurate (strain 0.053 % against 0.054 %).
constexpr double kRefineAcceptDecrement = 1e-4;


}  // namespace

Simulation::Simulation(const Scene& scene) : scene_(scene), stepper_(scene.solver) {
  validateScene(scene_);
  std::stable_sort(scene_.events.begin(), scene_.events.end(),
                   [](const SceneEvent& a, const SceneEvent& b) { return a.time < b.time; });
  initial_scene_ = scene_;
  reset();
}

void Simulation::reset() {
  scene_ = initial_scene_;
  model_ = buildModel(scene_);
  x_ = initialPositions(scene_, model_.rest_positions);
  v_.resize(x_.size());
  for (int i = 0; i < model_.numNodes(); ++i) v_.segment<3>(3 * i) = scene_.initial.velocity;
  x_prev_.resize(0);
  v_prev_.resize(0);
  has_prev_ = false;
  h_prev_ = 0.0;
  refine_next_ = false;
  refine_skip_ = 0;
  refine_interval_ = 0;
  t_ = 0.0;
  step_count_ = 0;
  next_event_ = 0;
  work_in_total_ = 0.0;
  last_stats_ = StepStats();
  rebuildStepper();
  colliders_.clear();
  collider_states_.clear();
  for (const ColliderParams& params : scene_.colliders) {
    colliders_.push_back(Collider::fromParams(params, scene_.contact.friction));
    collider_states_.push_back(ColliderState{colliders_.back().scenePose()});
  }
  collider_step_.colliders = &colliders_;
  collider_step_.thickness = scene_.contact.thickness;
  // Exact at rest, smoothed in motion, without self-collision only: with it
  // exact_sticking keeps exact stick/slip states throughout. Its re-solves
  // start from the first solve's contacts, and the switch between them cost
  // the heap (self hard case s1, 16 seeds) under bdf2 55 -> 83 s, and
  // newton failed seed 3 (an energy gain at 8 halvings); keeping the step's
  // mode in the re-solves fixed seed 3 but left bdf2 slower still.
  const bool hybrid_off = scene_.self_collision.enabled && scene_.contact.exact_sticking;
  collider_step_.friction_smoothing = hybrid_off ? 0.0 : scene_.contact.friction_smoothing;
  collider_step_.exact_sticking = scene_.contact.exact_sticking;
  max_penetration_ = 0.0;
  self_collision_ = SelfCollision(model_, scene_.self_collision);
  measureState();  // the repulsion's energy needs the self-collision set up
  last_stats_.energy = measures_.total();
  last_stats_.max_strain = measures_.max_strain;
  min_self_distance_ = std::numeric_limits<double>::infinity();
  pins_.clear();
  for (int p : scene_.pins) pins_[p] = PinTarget{position(p), Vec3::Zero(), 0.0};
  size_ = std::hypot(scene_.cloth.cols > 1 ? scene_.cloth.width : 0.0, scene_.cloth.length);
  resetStepControl();
}

std::vector<int> Simulation::pinnedNodes() const {
  std::vector<int> nodes;
  nodes.reserve(pins_.size());
  for (const auto& entry : pins_) nodes.push_back(entry.first);
  return nodes;
}

// ------------------------------------------------------------ stepping ----

StepStats Simulation::step() {
  return adaptive() ? stepToward(std::numeric_limits<double>::infinity())
                    : step(scene_.solver.dt);
}

StepStats Simulation::step(double h) {
  if (!(h > 0.0) || !std::isfinite(h)) {
    StepStats bad;
    bad.ok = false;
    bad.failure = "step: h must be > 0 and finite, got " + fmt(h);
    return bad;
  }
  applyDueEvents();
  // Checkpoint, so a step that fails even after recovery changes nothing:
  // taken before the first halving (stepWithRecovery), as a step that is not
  // split changes nothing when it fails, and here where error control may
  // take the step back.
  checkpoint_.saved = false;
  state_finite_ = false;  // an accepted attempt of this step sets it
  if (adaptive()) saveCheckpoint();
  StepStats stats = stepHoldingSizes(h);
  if (!stats.ok && scene_.solver.recovery && checkpoint_.saved) restoreCheckpoint();
  if (stats.ok) ++step_count_;
  stats.h_max = h;
  stats.h_min = std::ldexp(h, -stats.halvings);
  stats.energy = measures_.total();
  stats.max_strain = measures_.max_strain;
  // The last accepted attempt measured the state it left finite (or not):
  // no second pass over it.
  stats.finite = (stats.ok && state_finite_) || (allFinite(x_) && allFinite(v_));
  last_stats_ = stats;
  return stats;
}

StepStats Simulation::attempt(double h, bool reject_linear, bool reject_newton,
                              std::optional<Method> as) {
  energy_rejected_ = false;
  x_save_ = x_;
  v_save_ = v_;
  const EnergyParts before = measures_;
  const double scale = energyScale();

  pin_ends_.nodes.clear();
  pin_ends_.targets.clear();
  bool pins_move = false, pins_jump = false;
  for (const auto& [node, pin] : pins_) {
    const double drift = std::clamp(pin.velocity_until - t_, 0.0, h);
    const Vec3 end = pin.position + drift * pin.velocity;
    pin_ends_.nodes.push_back(node);
    pin_ends_.targets.push_back(end);
    pins_move = pins_move || end != x_save_.segment<3>(3 * node);
    pins_jump = pins_jump || pin.position != x_save_.segment<3>(3 * node);
  }
  // pinWork reads a linearized step's own reaction only without a jump or
  // self-collision (see there); the stepper computes it only then.
  pin_ends_.reaction_read = !pins_jump && !self_collision_.enabled();
  History history;
  if (has_prev_) history = History{&x_prev_, &v_prev_, h_prev_};

  // Colliders at the start and the end of the step (their drift, like pins').
  collider_step_.start.clear();
  collider_step_.end.clear();
  bool colliders_move = false;
  for (const ColliderState& c : collider_states_) {
    const double drift = std::clamp(c.velocity_until - t_, 0.0, h);
    collider_step_.start.push_back(c.pose);
    collider_step_.end.push_back(Pose{c.pose.rotation, c.pose.translation + drift * c.velocity});
    colliders_move = colliders_move || drift * c.velocity.squaredNorm() > 0.0;
  }

  // Self-repulsion inside the solve (self_repulsion.hpp): pairs closer than
  // kRepulsionReach thicknesses at the step's start, or predicted to come
  // so close, push apart with a stiffness kRepulsionStiffness times their
  // inertia over a scene step. Their energy is part of the energy check as
  // a function of the positions alone (repulsionEnergy: the terms built
  // there, measured there), so a step's start holds what the last one's end
  // did. Measured with the step's frozen terms at the end and built anew at
  // the start, a pair that came within the reach unpredicted was a term
  // only at the next step's start: its energy was credited there and
  // released as motion, which no halving shrank (a folded cloth dropped on
  // a table under bdf2: 4.8e-5 J at dt / 256).
  // implicit_euler scenes only (their refined Newton steps too): in newton
  // and bdf2 scenes, whose every step is a Newton solve, the terms' clamp
  // and friction's stiff smoothing stalled it (the twisted cloth, hard case
  // s4, under bdf2: not done in 400 s where 19 s without; under newton it
  // failed at t = 0.9 s). There the filter acts at the whole thickness.
  const bool repulsed = repulsionOn();
  self_collision_.setProximity(repulsed ? kSelfProximity : 1.0);
  if (repulsed) {
    const double reach = kRepulsionReach * scene_.self_collision.thickness;
    // The stiffness is the scene's step's, not this attempt's: k ~ 1 / h^2
    // of a halved step made the halvings stiffer, the energy a pair held at
    // the start grew with each, and a dropped folded cloth under newton
    // failed (1.1 J gained at dt / 256).
    const double dt = scene_.solver.dt;
    x_predicted_ = x_save_ + h * v_save_;  // where pairs may come close
    self_collision_.repulsionTerms(model_, x_save_, x_predicted_, reach,
                                   kRepulsionStiffness / (dt * dt), &repulsion_);
    stepper_.setRepulsion(&repulsion_);
  } else {
    repulsion_.clear();
    stepper_.setRepulsion(nullptr);
  }
  // The start's repulsion energy is the last measure's (measureState, or
  // the last accepted step's end): the same function of the same positions,
  // so not built and measured again here (a hash query less a step).
  const double before_total = before.total();

  if (refining_ && !pins_move && !colliders_move) {
    // A refined step is held to the energy check, not to a Newton tolerance:
    // Newton stops at the first iterate that passes it once its decrement is
    // below kRefineAcceptDecrement of the energy scale (docs/design.md,
    // "Accepting a step"). Not when pins move (their work is read from the
    // reaction at the end of the step, only as good as Newton's answer:
    // compression at stretch 1e7, dt 0.1, rose 1e-6 beyond it) nor when
    // colliders move (their work comes from the contact passes). Static
    // colliders do none, and self-collision's re-solves are checked after:
    // the stiffened cloth on a table (contact hard case c4) rejected 53
    // attempts where 154 when these ran Newton to its tolerance.
    stepper_.setEnergyStop(
        [this, before_total](const VecX& x1, const VecX& v1) {
          const double gain =
              measureEnergy(model_, x1, v1).total() + repulsion_.energy(x1) - before_total;
          return gain <= 0.0;  // not even the check's round-off allowance
        },
        kRefineAcceptDecrement * scale);
  }
  StepStats stats = stepper_.step(model_, h, pin_ends_, history, x_, v_, as, collider_step_);
  stepper_.setEnergyStop(nullptr, 0.0);
  // The self-collision filter, then the step solved again with the nodes it
  // moved held where it put them (simulation_self.cpp).
  SelfPinWork self_work;
  if (stats.ok && self_collision_.enabled()) {
    resolveSelfCollision(h, history, as, &stats, &self_work);
    if (stats.ok) measureSelfCollision(&stats);
  }
  const double self_pin_work = self_work.total();

  // Work the pins did: reaction at the end of the step times their travel,
  // plus what they did through the self-collision response (impulses they
  // held against, zones they dragged). The nodes the self-collision response
  // prescribes are not pins: their forces are internal (an inelastic stop
  // between two layers takes energy out), so nothing is credited for them.
  const Method taken = as.value_or(scene_.solver.method);
  const double work =
      self_pin_work + (stats.ok && pins_move ? pinWork(x_, v_, h, taken) : 0.0);
  if (stats.ok && reject_linear && !stats.linear_converged) {
    stats.ok = false;
    stats.failure = "linear solver did not reach tolerance (relative residual " +
                    fmt(stats.residual) + ")";
  }
  if (stats.ok && reject_newton && !stats.newton_converged) {
    stats.ok = false;
    stats.failure = newtonFailure(stats);
  }
  EnergyParts after;
  double gain = 0.0;  // beyond the work put in (the energy check, the bdf2 window)
  if (stats.ok) {
    after = measureEnergy(model_, x_, v_);
    // Moving colliders do work on the cloth too; static ones only take
    // energy out (a friction state kept from an earlier pass that would add
    // energy is caught here, and the step split).
    const double contact_work = colliders_move ? std::max(stats.contact_work, 0.0) : 0.0;
    // Backward Euler (linearized or not) must not create energy. BDF2 is only
    // dissipative in its two-step G-norm for linear systems (Dahlquist), not
    // step by step, and its trapezoidal start not at all; the G-norm's
    // nonlinear analogue 1/2 [E(z1) + E(2 z1 - z0)] was tried and rejected
    // more steps than the plain energy (extrapolating a turning stiff spring
    // stretches it). So bdf2 is held to the same per-step bound (over a
    // window while inputs move, below); a step that fails it is retried as
    // backward Euler (stepWithRecovery).
    // The pins' work counts with its sign: where the cloth pushes the pins
    // back (a drag starting from rest, the stiff springs rebounding) its
    // energy must fall by as much. Counted as zero, that let a gain through
    // (the fling at stretch 1e6, dt 0.01: 4 sub-steps read -4.2e-3 J and the
    // energy rose by 1.8e-2 J, the stability map's integrated check failed).
    after.repulsion = repulsionEnergy(x_);
    gain = after.total() - before_total - work - contact_work;
    // Symplectic Euler's energy oscillates by design: for it the check only
    // catches a blow-up.
    // A step Newton solved to its tolerance has no inexact solve to forgive,
    // only round-off: held to kTightEnergyGainTolerance, a gain is BDF2's
    // own (retried as backward Euler) or backward Euler's on a nonconvex
    // energy (split), not noise. Not with colliders or self-collision: their
    // friction is lagged across passes and steps (IPC's lagged friction),
    // an inexactness of its own (held to 1e-9, the stiffened cloth on a
    // table, contact hard case c4, took 134 rejected attempts where 72).
    const bool solved_tight = (taken == Method::Newton || taken == Method::Bdf2) &&
                              scene_.solver.newton_max_iterations > 1 &&
                              stats.newton_converged && !refining_ &&
                              collider_step_.empty() && !self_collision_.enabled();
    const double allowance = scene_.solver.method == Method::SymplecticEuler ? 0.5
                             : solved_tight ? kTightEnergyGainTolerance
                                            : kEnergyGainTolerance;
    // A cloth at rest has a tiny scale, and with stiff springs its energy
    // is then at the step's round-off (stretch 1e8: ~1e-17 J, rising and
    // falling by as much): gains below that are not gains.
    stats.energy_round_off = energyRoundOff(model_, h, before.round_off);  // of v_save_
    // With pins or colliders that move, a bdf2 step may gain what the
    // balance lies below its recent maximum (EnergyWindow): the work is
    // then a one-point quadrature, and a step held to it alone is retried as
    // backward Euler over and over (energy_window.hpp).
    const double credit = (pins_move || colliders_move) && taken == Method::Bdf2
                              ? energy_window_.credit()
                              : 0.0;
    if (scene_.solver.recovery && !(gain <= allowance * scale + stats.energy_round_off + credit)) {
      stats.ok = false;
      stats.failure = "energy jump of " + fmt(gain) + " J beyond the work input";
      energy_rejected_ = true;
    }
  }
  if (!stats.ok) {
    x_ = x_save_;
    v_ = v_save_;
    return stats;
  }
  if (pins_move || colliders_move) {
    energy_window_.accept(gain);
  } else {
    energy_window_.clear();  // steps without inputs are held to the step's own bound
  }
  measures_ = after;
  state_finite_ = after.finite;
  std::swap(x_prev_, x_save_);  // x_prev_ = state before this step
  std::swap(v_prev_, v_save_);
  // BDF2 extrapolates from this state and the one before: nodes that landed
  // restart there at their surfaces (ContactSet::alignWithSurfaces).
  if (scene_.solver.method == Method::Bdf2 &&
      stepper_.contacts().alignWithSurfaces(h, x_, v_, x_prev_, v_prev_)) {
    measures_.kinetic = cloth_sim::kineticEnergy(model_, v_);
    measures_.round_off = roundOffTerms(model_, v_);
    state_finite_ = false;  // v changed since measured
    energy_window_.clear();
  }
  h_prev_ = h;
  has_prev_ = true;
  accepted_h_ = h;
  // The rest of this step goes in sub-steps no longer than this one
  // (stepWithRecovery).
  if (hold_sizes_ && scene_.solver.method != Method::SymplecticEuler) split_above_ = h;
  t_ += h;
  for (size_t k = 0; k < pin_ends_.nodes.size(); ++k) {
    PinTarget& pin = pins_[pin_ends_.nodes[k]];
    pin.position = pin_ends_.targets[k];
    if (t_ >= pin.velocity_until) pin.velocity.setZero();
  }
  for (size_t k = 0; k < collider_states_.size(); ++k) {
    ColliderState& c = collider_states_[k];
    c.pose = collider_step_.end[k];
    if (t_ >= c.velocity_until) c.velocity.setZero();
  }
  max_penetration_ = std::max(max_penetration_, stats.max_penetration);
  min_self_distance_ = std::min(min_self_distance_, stats.min_self_distance);
  stats.work_in = work;
  work_in_total_ += work;
  return stats;
}


// ------------------------------------------------------------ events ----

void Simulation::applyDueEvents() {
  while (next_event_ < scene_.events.size() &&
         scene_.events[next_event_].time <= t_ + 1e-9 * scene_.solver.dt) {
    applyEvent(scene_.events[next_event_]);
    ++next_event_;
  }
}

Status Simulation::applyEvent(const SceneEvent& e) {
  switch (e.kind) {
    case SceneEvent::Kind::SetStiffness:
      return setStiffness(e.all_types ? "all" : toString(e.spring_type), e.stiffness, e.damping);
    case SceneEvent::Kind::MovePin: {
      const Vec3 from = isPinned(e.index) ? pins_.at(e.index).position : position(e.index);
      return movePin(e.index, e.position.value_or(from), e.velocity.value_or(Vec3::Zero()),
                     e.duration);
    }
    case SceneEvent::Kind::Pin: {
      std::vector<int> fresh;
      for (int i : e.indices) {
        if (!isPinned(i)) fresh.push_back(i);
      }
      return fresh.empty() ? Status::success() : pin(fresh);
    }
    case SceneEvent::Kind::MoveCollider: {
      const int k = colliderIndex(e.collider);
      const Vec3 from = k >= 0 ? collider_states_[k].pose.translation : Vec3::Zero();
      return moveCollider(e.collider, e.position.value_or(from),
                          e.velocity.value_or(Vec3::Zero()), e.duration);
    }
    case SceneEvent::Kind::Release:
      if (e.release_all) {
        releaseAll();
        return Status::success();
      } else {
        std::vector<int> pinned;
        for (int i : e.indices) {
          if (isPinned(i)) pinned.push_back(i);
        }
        return pinned.empty() ? Status::success() : release(pinned);
      }
  }
  return Status::success();
}

// ------------------------------------------------------ runtime calls ----

Status Simulation::pin(const std::vector<int>& indices, const std::vector<Vec3>& targets) {
  Status ok = checkIndices(indices, numNodes(), "indices");
  if (!ok) return ok;
  if (!targets.empty() && targets.size() != indices.size()) {
    return Status::error("positions: " + std::to_string(targets.size()) + " given for " +
                         std::to_string(indices.size()) + " indices");
  }
  for (size_t k = 0; k < targets.size(); ++k) {
    if (!finite(targets[k])) {
      return Status::error("positions[" + std::to_string(k) + "]: must be finite");
    }
  }
  for (size_t k = 0; k < indices.size(); ++k) {
    const int i = indices[k];
    pins_[i] = PinTarget{targets.empty() ? position(i) : targets[k], Vec3::Zero(), 0.0};
  }
  return Status::success("pinned " + std::to_string(indices.size()) + " node(s)");
}

Status Simulation::movePin(int index, const Vec3& position, const Vec3& velocity,
                           double duration) {
  Status ok = checkIndices({index}, numNodes(), "index", false);
  if (!ok) return Status::error("index: " + std::to_string(index) + " out of range [0, " +
                                std::to_string(numNodes() - 1) + "]");
  if (!finite(position)) return Status::error("position: must be finite");
  if (!finite(velocity)) return Status::error("velocity: must be finite");
  if (!(duration >= 0.0) || !std::isfinite(duration)) {
    return Status::error("duration: must be >= 0 and finite, got " + fmt(duration));
  }
  pins_[index] = PinTarget{position, velocity, t_ + duration};
  return Status::success();
}

Status Simulation::drivePin(int index, const Vec3& velocity, double duration) {
  if (index < 0 || index >= numNodes()) {
    return Status::error("index: " + std::to_string(index) + " out of range [0, " +
                         std::to_string(numNodes() - 1) + "]");
  }
  const Vec3 from = isPinned(index) ? pins_.at(index).position : position(index);
  return movePin(index, from, velocity, duration);
}

Status Simulation::release(const std::vector<int>& indices) {
  Status ok = checkIndices(indices, numNodes(), "indices");
  if (!ok) return ok;
  for (size_t k = 0; k < indices.size(); ++k) {
    if (!isPinned(indices[k])) {
      return Status::error("indices[" + std::to_string(k) + "]: node " +
                           std::to_string(indices[k]) + " is not pinned");
    }
  }
  for (int i : indices) pins_.erase(i);
  return Status::success("released " + std::to_string(indices.size()) + " node(s)");
}

void Simulation::releaseAll() { pins_.clear(); }

int Simulation::colliderIndex(const std::string& name) const {
  for (size_t k = 0; k < colliders_.size(); ++k) {
    if (colliders_[k].name() == name) return static_cast<int>(k);
  }
  return -1;
}

Status Simulation::moveCollider(const std::string& name, const Vec3& position,
                                const Vec3& velocity, double duration) {
  const int k = colliderIndex(name);
  if (name.empty() || k < 0) return Status::error("name: no collider named '" + name + "'");
  if (!finite(position)) return Status::error("position: must be finite");
  if (!finite(velocity)) return Status::error("velocity: must be finite");
  if (!(duration >= 0.0) || !std::isfinite(duration)) {
    return Status::error("duration: must be >= 0 and finite, got " + fmt(duration));
  }
  ColliderState& c = collider_states_[k];
  c.pose.translation = position;
  c.velocity = velocity;
  c.velocity_until = t_ + duration;
  return Status::success();
}

Status Simulation::setColliderPose(int index, const Pose& pose, const Vec3& velocity) {
  if (index < 0 || index >= static_cast<int>(colliders_.size())) {
    return Status::error("index: collider " + std::to_string(index) + " out of range");
  }
  if (!pose.rotation.allFinite() || !finite(pose.translation)) {
    return Status::error("pose: must be finite");
  }
  const Mat3 orthogonality = pose.rotation.transpose() * pose.rotation - Mat3::Identity();
  if (!(orthogonality.norm() < 1e-6) || !(pose.rotation.determinant() > 0.0)) {
    return Status::error("pose: rotation must be a proper rotation matrix");
  }
  if (!finite(velocity)) return Status::error("velocity: must be finite");
  ColliderState& c = collider_states_[index];
  c.pose = pose;
  c.velocity = velocity;
  c.velocity_until = velocity.isZero(0.0) ? t_ : std::numeric_limits<double>::infinity();
  return Status::success();
}

Status Simulation::setStiffness(const std::string& spring_type, double stiffness,
                                double damping) {
  std::vector<SpringType> types;
  if (spring_type == "all") {
    for (int t = 0; t < kNumSpringTypes; ++t) {
      if (model_.groups[t].present) types.push_back(static_cast<SpringType>(t));
    }
    if (types.empty()) return Status::error("spring_type: the scene has no springs");
  } else {
    SpringType type;
    if (!parseSpringType(spring_type, &type)) {
      return Status::error("spring_type: unknown '" + spring_type +
                           "' (expected stretch, shear, bend or all)");
    }
    if (!model_.groups[static_cast<int>(type)].present) {
      return Status::error("spring_type: group '" + spring_type +
                           "' is not in the scene (the scene decides what is modelled)");
    }
    types.push_back(type);
  }
  if (!(stiffness > 0.0) || !std::isfinite(stiffness)) {
    return Status::error("stiffness: must be > 0 and finite, got " + fmt(stiffness));
  }
  if (damping != -1.0 && (!(damping >= 0.0) || !std::isfinite(damping))) {
    return Status::error("damping: must be >= 0 and finite (or -1 to keep), got " + fmt(damping));
  }
  for (SpringType type : types) {
    SpringGroup& g = model_.groups[static_cast<int>(type)];
    // Changing k changes the stored elastic energy: that is work done on the cloth.
    double stretch_sq = 0.0;
    for (int s = g.begin; s < g.end; ++s) {
      const Spring& sp = model_.springs[s];
      const double e = (position(sp.j) - position(sp.i)).norm() - sp.rest_length;
      stretch_sq += e * e;
    }
    work_in_total_ += 0.5 * (stiffness - g.stiffness) * stretch_sq;
    g.stiffness = stiffness;
    if (damping != -1.0) g.damping = damping;
  }
  measureState();
  return Status::success("set " + spring_type + " stiffness to " + fmt(stiffness));
}

Tuning Simulation::tuning() const {
  Tuning t;
  for (int k = 0; k < kNumSpringTypes; ++k) {
    const SpringGroup& g = model_.groups[k];
    t.springs[k] = SpringGroupParams{g.present, g.stiffness, g.damping};
  }
  t.gravity = model_.gravity;
  t.air_drag = model_.air_drag;
  t.solver = scene_.solver;
  return t;
}

namespace {
bool sameSolver(const Scene::Solver& a, const Scene::Solver& b) {
  return a.method == b.method && a.dt == b.dt && a.tolerance == b.tolerance &&
         a.max_iterations == b.max_iterations && a.preconditioner == b.preconditioner &&
         a.multigrid_reuse == b.multigrid_reuse &&
         a.project_compression == b.project_compression &&
         a.newton_tolerance == b.newton_tolerance &&
         a.newton_max_iterations == b.newton_max_iterations &&
         a.max_halvings == b.max_halvings && a.recovery == b.recovery &&
         a.error_tolerance == b.error_tolerance && a.dt_min == b.dt_min && a.dt_max == b.dt_max;
}
}  // namespace

void Simulation::rebuildStepper() {
  stepper_ = Stepper(scene_.solver);
  stepper_.setSelfCollision(scene_.self_collision.enabled);
}

Status Simulation::retune(const Tuning& tuning) {
  Scene candidate = scene_;
  candidate.springs = tuning.springs;
  candidate.gravity = tuning.gravity;
  candidate.air_drag = tuning.air_drag;
  candidate.solver = tuning.solver;
  try {
    validateScene(candidate);  // the scene file's checks, messages naming the field
  } catch (const SceneError& e) {
    return Status::error(e.what());
  }
  for (int k = 0; k < kNumSpringTypes; ++k) {
    const bool present = model_.groups[k].present;
    if (tuning.springs[k].enabled != present) {
      const std::string name = toString(static_cast<SpringType>(k));
      return Status::error("springs." + name + (present ? ".stiffness: must stay > 0" : "") +
                           ": the scene " + (present ? "models" : "does not model") + " the " +
                           name + " group, and only a scene decides what is modelled");
    }
  }
  for (int k = 0; k < kNumSpringTypes; ++k) {
    const SpringGroup& g = model_.groups[k];
    const SpringGroupParams& want = tuning.springs[k];
    if (g.present && (want.stiffness != g.stiffness || want.damping != g.damping)) {
      setStiffness(toString(static_cast<SpringType>(k)), want.stiffness, want.damping);
    }
  }
  // Changing g changes the potential energy at the same positions: work done on the cloth.
  const double potential_before = gravityEnergy(model_, x_);
  model_.gravity = tuning.gravity;
  model_.has_gravity = tuning.gravity.squaredNorm() > 0.0;
  model_.air_drag = tuning.air_drag;
  work_in_total_ += gravityEnergy(model_, x_) - potential_before;
  scene_.gravity = tuning.gravity;
  scene_.air_drag = tuning.air_drag;
  if (!sameSolver(scene_.solver, tuning.solver)) {
    scene_.solver = tuning.solver;
    rebuildStepper();
    resetStepControl();
  }
  measureState();
  return Status::success();
}

// --------------------------------------------------------- measurements ----

double Simulation::kineticEnergy() const { return cloth_sim::kineticEnergy(model_, v_); }
double Simulation::elasticEnergy() const { return cloth_sim::elasticEnergy(model_, x_); }
double Simulation::potentialEnergy() const { return gravityEnergy(model_, x_); }
double Simulation::maxStrain() const { return cloth_sim::maxStrain(model_, x_); }

std::vector<double> Simulation::nodeStrain() const {
  std::vector<double> strain(numNodes(), 0.0);
  for (const Spring& s : model_.springs) {
    const double e = (position(s.j) - position(s.i)).norm() / s.rest_length - 1.0;
    strain[s.i] = std::max(strain[s.i], e);
    strain[s.j] = std::max(strain[s.j], e);
  }
  return strain;
}

bool Simulation::solveStatic(VecX* x_out, double rel_tol, int max_iterations) const {
  // Pseudo-time continuation: (M + h^2 K) dx = h^2 f, with h grown while the
  // force residual falls and cut when it does not (a damped Newton).
  std::vector<char> free(numNodes(), 1);
  for (const auto& entry : pins_) free[entry.first] = 0;
  VecX x = x_;
  for (const auto& [node, pin] : pins_) x.segment<3>(3 * node) = pin.position;
  const VecX zero_v = VecX::Zero(x.size());
  SystemMatrix A;
  CgWorkspace ws;
  VecX f, rhs, dx = VecX::Zero(x.size()), x_trial, f_trial;
  auto freeNorm = [&](const VecX& v) {
    double s = 0.0;
    for (int i = 0; i < numNodes(); ++i) {
      if (free[i]) s += v.segment<3>(3 * i).squaredNorm();
    }
    return std::sqrt(s);
  };
  computeForces(model_, x, zero_v, f);
  double weight = 0.0;
  for (double m : model_.mass) weight += m * model_.gravity.norm();
  const double scale = std::max(weight, freeNorm(f)) + 1e-300;
  // Spring forces k (l - L) carry a round-off of about eps k L each: a stiff
  // cloth cannot be balanced better than that, whatever rel_tol asks.
  const double target = std::max(
      rel_tol * scale, 10.0 * std::numeric_limits<double>::epsilon() * springForceScale(model_));
  // Accept a trial that lowers the potential energy or the force residual:
  // dx descends on the energy (the projected K is PSD), while the residual
  // alone stalls where the cloth is crumpled (non-convex springs).
  auto potential = [&](const VecX& at) {
    return cloth_sim::elasticEnergy(model_, at) + gravityEnergy(model_, at);
  };
  double h = 1e2;
  double r = freeNorm(f);
  double u = potential(x);
  for (int it = 0; it < max_iterations && r > target; ++it) {
    assembleSystem(model_, x, zero_v, 0.0, h * h, scene_.solver.project_compression, A, f);
    rhs = h * h * f;
    dx.setZero();
    // A fresh sparse factorization each time: stiff scenes defeat block Jacobi.
    if (ws.cholesky) ws.cholesky->invalidate();
    conjugateGradient(A, model_.springs, free, rhs, dx, Preconditioner::Cholesky, 1e-13,
                      20 * numNodes() + 100, ws);
    x_trial = x + dx;
    computeForces(model_, x_trial, zero_v, f_trial);
    const double r_trial = freeNorm(f_trial);
    const double u_trial = potential(x_trial);
    if (r_trial < r || u_trial < u) {
      x = x_trial;
      r = r_trial;
      u = u_trial;
      h = std::min(h * 4.0, 1e8);
    } else {
      h *= 0.25;
      if (h < 1e-12) break;
    }
  }
  *x_out = x;
  return r <= target;
}

}  // namespace cloth_sim
