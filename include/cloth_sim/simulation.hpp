// The simulation: a model, its state, its pins and a time stepper. Every
// client (CLI, benchmark, ROS node) drives the cloth through this class only.
// Runtime requests are validated first; a rejected request changes nothing.
#pragma once

#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cloth_sim/energy_window.hpp"
#include "cloth_sim/collider.hpp"
#include "cloth_sim/forces.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/self_collision.hpp"
#include "cloth_sim/step_size_control.hpp"
#include "cloth_sim/step_stats.hpp"
#include "cloth_sim/stepper.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// Where a collider is and how it drifts (move_collider, like a pin target).
struct ColliderState {
  Pose pose;                     ///< now
  Vec3 velocity = Vec3::Zero();  ///< drifts at this velocity ...
  double velocity_until = 0.0;   ///< ... until this simulated time
};

/// Where a pinned node must be at the end of each step.
struct PinTarget {
  Vec3 position = Vec3::Zero();  ///< target now
  Vec3 velocity = Vec3::Zero();  ///< target drifts at this velocity ...
  double velocity_until = 0.0;   ///< ... until this simulated time
};

/// The settings that may change while the simulation runs (the node's live
/// tuning): each spring group's stiffness and damping, gravity, air drag and
/// the solver settings. `springs[t].enabled` says whether the group is modelled.
struct Tuning {
  std::array<SpringGroupParams, kNumSpringTypes> springs{};
  Vec3 gravity = Vec3::Zero();
  double air_drag = 0.0;
  Scene::Solver solver;
};

class Simulation {
 public:
  /// Validates the scene (throws SceneError) and sets up the initial state.
  explicit Simulation(const Scene& scene);

  const Scene& scene() const { return scene_; }
  const Model& model() const { return model_; }
  int numNodes() const { return model_.numNodes(); }
  const VecX& positions() const { return x_; }   ///< 3n
  const VecX& velocities() const { return v_; }  ///< 3n
  Vec3 position(int node) const { return x_.segment<3>(3 * node); }
  double time() const { return t_; }
  double dt() const { return scene_.solver.dt; }
  long stepCount() const { return step_count_; }

  /// Applies the scene events that are due, then advances by solver.dt, or
  /// with solver.error_tolerance by the step the error control picks (never
  /// past the next event: events land on their times).
  StepStats step();
  /// Same, advancing by h (the node divides its timer tick evenly). h > 0.
  /// No error control: h is taken as given (recovery may still split it).
  StepStats step(double h);
  /// Advances to time t_end (> time()) exactly: with solver.error_tolerance
  /// by error-controlled steps, else by equal steps no longer than solver.dt.
  /// Stops at the first failed step (its stats say why). Defined in
  /// simulation_adaptive.cpp.
  StepStats advanceTo(double t_end);
  /// One step that ends no later than t_limit: error-controlled (no further
  /// than the next event either; a step whose error estimate is too large is
  /// taken back and redone smaller), else of solver.dt, cut short at t_limit.
  StepStats stepToward(double t_limit);
  /// Whether the scene asks for error-controlled stepping.
  bool adaptive() const { return scene_.solver.error_tolerance.has_value(); }
  /// The size error control proposes for the next step (solver.dt without it).
  double nextStepSize() const { return adaptive() ? step_control_.proposal() : scene_.solver.dt; }

  // --- runtime requests (the node's services map onto these) ---
  /// Pins nodes. Empty `targets` pins them where they are; else one per index.
  Status pin(const std::vector<int>& indices, const std::vector<Vec3>& targets = {});
  /// Moves one pinned node's target: a jump to `position`, then drift at
  /// `velocity` for `duration` seconds (zero velocity: stay).
  Status movePin(int index, const Vec3& position, const Vec3& velocity = Vec3::Zero(),
                 double duration = 0.0);
  /// Drives one pin's target at a velocity from where it is now.
  Status drivePin(int index, const Vec3& velocity, double duration);
  Status release(const std::vector<int>& indices);
  void releaseAll();
  /// spring_type: "stretch", "shear", "bend" or "all"; stiffness > 0 finite;
  /// damping >= 0 finite, or exactly -1 to keep the current damping.
  Status setStiffness(const std::string& spring_type, double stiffness, double damping = -1.0);
  /// Moves a collider by name: its reference point (plane point, sphere or
  /// box center, capsule end a) jumps to `position`, then drifts at
  /// `velocity` for `duration` s. The drift enters friction.
  Status moveCollider(const std::string& name, const Vec3& position,
                      const Vec3& velocity = Vec3::Zero(), double duration = 0.0);
  /// Places collider `index` at a world pose (the node's tf-attached
  /// colliders), moving at `velocity` until the next call (nonzero: the
  /// steps until then sweep that motion, and friction sees it). The jump to
  /// `pose` itself is not swept: a node it lands inside is pushed out.
  Status setColliderPose(int index, const Pose& pose, const Vec3& velocity = Vec3::Zero());
  /// Replaces the state (3n positions and velocities, finite): tests and
  /// tools start from shapes the scene cannot describe (a folded cloth).
  /// Pins are retargeted to their nodes' new positions, contact and the
  /// multistep history are forgotten. Defined in simulation_state.cpp.
  Status setState(const VecX& x, const VecX& v);
  /// What the simulation runs with now (stiffness changes and retune included).
  Tuning tuning() const;
  /// Changes the tunable settings between steps. Validated as a scene file is
  /// (validateScene on the scene with these fields: the message names the
  /// field, e.g. "springs.stretch.stiffness: must be > 0, got -3"); a spring
  /// group stays as the scene modelled it (present with stiffness > 0, or
  /// absent). A refused change changes nothing. Stiffness and gravity changes
  /// count as work done on the cloth; a solver change restarts the stepper.
  Status retune(const Tuning& tuning);
  /// Back to the initial state, pins, colliders, stiffness and settings of the scene.
  void reset();

  bool isPinned(int node) const { return pins_.count(node) != 0; }
  std::vector<int> pinnedNodes() const;
  const std::map<int, PinTarget>& pins() const { return pins_; }
  const SpringGroup& group(SpringType type) const {
    return model_.groups[static_cast<int>(type)];
  }

  // --- colliders and contact ---
  const std::vector<Collider>& colliders() const { return colliders_; }
  const ColliderState& colliderState(int index) const { return collider_states_[index]; }
  /// Index of a collider by name, -1 if none.
  int colliderIndex(const std::string& name) const;
  /// Nodes in contact at the end of the last step.
  std::vector<int> contactNodes() const { return stepper_.contacts().contactNodes(); }
  /// Cholesky factorizations the stepper made since it was (re)made.
  int factorizations() const { return stepper_.factorizations(); }
  /// Deepest any node went inside surface + thickness, over every step (m).
  double maxPenetration() const { return max_penetration_; }
  /// Smallest distance between non-adjacent parts of the cloth at the end of
  /// every step so far (m; infinity without self_collision or before a near pair).
  double minSelfDistance() const { return min_self_distance_; }

  // --- measurements ---
  double kineticEnergy() const;
  double elasticEnergy() const;
  double potentialEnergy() const;  ///< -m g.x
  double energy() const { return kineticEnergy() + elasticEnergy() + potentialEnergy(); }
  double maxStrain() const;                 ///< max |d|/L - 1 over springs
  std::vector<double> nodeStrain() const;   ///< per node, max over its springs
  double totalWorkIn() const { return work_in_total_; }
  /// Statistics of the last step() call.
  const StepStats& lastStats() const { return last_stats_; }

  /// Static equilibrium of the current pins and forces (Newton on f(x) = 0
  /// with line search), starting from the current positions. Does not change
  /// the simulation. Returns false if it did not converge to rel_tol.
  bool solveStatic(VecX* x_out, double rel_tol = 1e-10, int max_iterations = 200) const;

 private:
  void applyDueEvents();
  // simulation_adaptive.cpp
  void saveCheckpoint();
  void restoreCheckpoint();
  void resetStepControl();
  /// A fresh stepper for scene_.solver (newton's exact local phase off
  /// with self-collision: Stepper::setSelfCollision).
  void rebuildStepper();
  /// Stats of several steps with the state's figures at their end.
  StepStats finish(StepStats total);
  Status applyEvent(const SceneEvent& event);
  /// One step of h, no recovery; on failure the state is left as it was.
  /// reject_linear / reject_newton: a linear solve / Newton iteration short of
  /// its tolerance is a failure. as: see Stepper::step.
  /// An implicit_euler step solved on by Newton towards backward Euler and
  /// accepted on the energy check (stepWithRecovery): `refined` when ok.
  StepStats refine(double h, bool can_split);
  /// Whether a pin starts the next step away from its node (a jump); a
  /// failed attempt leaves it as it was (the state is rolled back).
  bool pinsJump() const;
  /// Whether a pin drifts at a velocity during the next step.
  bool pinsDrift() const;
  /// Whether every node is slower than kRestSpeed (simulation_recovery.cpp).
  bool nearRest() const;
  /// Work the pins did over a step from (x_save_, v_save_) to (x1, v1) (J),
  /// solved by `taken`; pin_ends_.reaction_read says whether a linearized
  /// step's own reaction may be read.
  double pinWork(const VecX& x1, const VecX& v1, double h, Method taken);
  // simulation_self.cpp
  /// The pins' work through one attempt's self-collision response (J), by
  /// the way it reached the cloth (resolveSelfCollision).
  struct SelfPinWork {
    double zones = 0.0;          ///< zones the pins dragged, every filter pass
    double impulses = 0.0;       ///< impulses held against pins, every pass
    double impulses_last = 0.0;  ///< the same, the last filter pass
    double rows = 0.0;           ///< through the held pairs of the last re-solve
    bool solved_rows = false;    ///< the last re-solve held the pushed pairs as rows
    /// A re-solve holding the pairs as rows replaces the earlier passes'
    /// impulses: what the pins pushed through a pair is then the row's own
    /// multiplier times their travel.
    double total() const { return zones + (solved_rows ? impulses_last + rows : impulses); }
  };
  /// The self-collision filter on the solved step x_save_ -> x_ (its time
  /// and figures into stats; a failure or a node pushed into a collider
  /// fails it); adds the pins' work through it to `work`.
  void filterSelfCollision(double h, StepStats* stats, SelfPinWork* work);
  /// Work the pins did through the pairs held as rows in the last solve
  /// (x_save_ -> x_), from the solve's multipliers: a pin is eliminated from
  /// the rows, so its reaction (pinWork) leaves out what it pushed on them.
  /// lambda: the rows' multipliers (PairProjection::multipliers).
  double rowPinWork(const std::vector<double>& lambda) const;
  /// The self-collision response to the solved step x_save_ -> x_: the
  /// filter, then the step solved again with every node the filter moved
  /// prescribed where it put it (along its displacement), so that its
  /// neighbours follow inside the implicit solve instead of being left
  /// stretched; repeated while the filter still moves nodes (at most
  /// kSelfSolves solves). Fills stats (a failure fails it) and the pins'
  /// work through the response.
  void resolveSelfCollision(double h, const History& history, std::optional<Method> as,
                            StepStats* stats, SelfPinWork* pin_work);
  /// The step's self contacts and closest self distance, at its end (once,
  /// after the last filter).
  void measureSelfCollision(StepStats* stats);
  StepStats attempt(double h, bool reject_linear, bool reject_newton,
                    std::optional<Method> as = std::nullopt);
  /// attempt(h); a bdf2 step that gains energy is retried as backward Euler;
  /// on rejection two half steps, down to max_halvings deep; there, a
  /// newton/bdf2 step whose Newton iteration does not converge is taken as a
  /// linearized backward-Euler step.
  StepStats stepWithRecovery(double h, int depth);
  /// A whole step: stepWithRecovery with the sub-step sizes held, and where
  /// that fails, again from the step's start with every size tried.
  StepStats stepHoldingSizes(double h);
  /// The step as two halves, each with recovery (from the checkpoint).
  StepStats splitInHalves(double h, int depth);
  /// Energy scale for the blow-up test: kinetic + elastic + m|g| times size.
  double energyScale() const;
  void accumulate(const StepStats& part, StepStats* total) const;

  Scene scene_;
  Scene initial_scene_;  ///< as constructed: reset() undoes retune()
  Model model_;
  VecX x_, v_;
  VecX x_prev_, v_prev_;  ///< previous step, for bdf2
  bool has_prev_ = false;
  double h_prev_ = 0.0;
  double size_ = 1.0;  ///< cloth diagonal, m
  double t_ = 0.0;
  long step_count_ = 0;
  std::map<int, PinTarget> pins_;
  std::vector<Collider> colliders_;
  std::vector<ColliderState> collider_states_;
  CollidersOverStep collider_step_;  ///< reused per step
  double max_penetration_ = 0.0;
  SelfCollision self_collision_;
  SelfCollisionMasses self_masses_;  ///< reused per step
  /// Self-repulsion inside the solve: with self-collision, in implicit_euler
  /// scenes only (their refined Newton steps too; see Simulation::attempt).
  bool repulsionOn() const {
    return self_collision_.enabled() && scene_.solver.method == Method::ImplicitEuler;
  }
  SelfRepulsion repulsion_;  ///< the attempt's self-repulsion terms (built at its start)
  SelfRepulsion repulsion_measure_;  ///< repulsionEnergy's terms
  /// The self-repulsion energy of positions x: of the terms built at x
  /// (SelfCollision::repulsionTerms from x to x), measured at x (J); 0
  /// without self-collision.
  double repulsionEnergy(const VecX& x);
  /// measures_ of the current state, the repulsion's energy included.
  void measureState();
  VecX x_pre_self_;                  ///< x1 before the self-collision filter
  double min_self_distance_ = std::numeric_limits<double>::infinity();
  size_t next_event_ = 0;
  double work_in_total_ = 0.0;
  double pending_work_ = 0.0;  ///< work by events since the last step
  StepStats last_stats_;
  bool energy_rejected_ = false;  ///< the last attempt failed on the energy check alone
  bool refining_ = false;     ///< the attempt refines a linearized step (stepWithRecovery)
  bool refine_next_ = false;  ///< the last refined step took > 1 Newton iteration
  /// The last accepted (sub-)step's length, and the length above which a
  /// (sub-)step is split at once, without an attempt (stepWithRecovery):
  /// that length within a step, twice it at the next step's start.
  double accepted_h_ = std::numeric_limits<double>::infinity();
  double split_above_ = std::numeric_limits<double>::infinity();
  bool hold_sizes_ = true;   ///< off while a step is retried with every size tried
  bool sizes_held_ = false;  ///< this step split at once somewhere
  int refine_skip_ = 0;       ///< steps refined at once before the linearized one is tried again
  int refine_interval_ = 0;   ///< refine_skip_'s last value (doubles while the tries fail)
  Stepper stepper_;
  StepSizeControl step_control_;  ///< with solver.error_tolerance
  ConstraintFilter departure_filter_;  ///< reused by the error estimate
  PinnedEnds pin_ends_;  ///< reused per step
  PinnedEnds pin_ends_self_;  ///< pins plus the nodes the self-collision filter moved
  /// Per node, in resolveSelfCollision: held, where, and along which unit
  /// direction (the filter's first displacement of it).
  std::vector<char> self_held_;
  std::vector<Vec3> self_target_, self_direction_;
  std::vector<char> self_pinned_;  ///< per node, reused: pinned
  /// Solves a step may take with self-collision: the first and re-solves
  /// while the filter still moves nodes (resolveSelfCollision).
  static constexpr int kSelfSolves = 4;
  /// Self-repulsion (attempt, self_repulsion.hpp): pairs closer than this
  /// many self thicknesses at a step's start are terms, the filter's
  /// proximity stage then acts below kSelfProximity of the thickness (the
  /// fail-safe), and a term's stiffness is kRepulsionStiffness times its
  /// effective mass over the scene's dt^2. At 1 the corners of the fold
  /// demo's top layer (a quarter of a node's mass over a triangle) sank
  /// 0.06 mm below the thickness each step and were set back by the
  /// filter; at 16 none do (docs/design.md).
  static constexpr double kRepulsionReach = 1.0;
  static constexpr double kSelfProximity = 0.5;
  static constexpr double kRepulsionStiffness = 16.0;
  EnergyParts measures_; ///< of the current state (energy check, stats)
  EnergyWindow energy_window_;  ///< bdf2's balance while pins or colliders move
  bool state_finite_ = false;  ///< an accepted attempt of this step left x_, v_ finite
  VecX x_save_, v_save_, force_;
  VecX x_predicted_;  ///< x0 + h v0: where the repulsion looks for pairs coming close
  struct Checkpoint {
    VecX x, v, x_prev, v_prev;
    bool has_prev = false;
    double t = 0.0, h_prev = 0.0, work = 0.0;
    std::vector<std::pair<int, PinTarget>> pins;
    std::vector<ColliderState> colliders;
    double max_penetration = 0.0;
    double min_self_distance = 0.0;
    bool saved = false;  ///< of this step (step() clears it)
  } checkpoint_;
};

/// Writes an OBJ (vertices, vertex normals, two triangles per cell with
/// consistent winding). Returns false if the file cannot be written.
bool writeObj(const std::string& path, const Model& model, const VecX& positions);
/// Per-vertex normals: area-weighted average of adjacent triangle normals.
std::vector<Vec3> vertexNormals(const Model& model, const VecX& positions);

}  // namespace cloth_sim
