// Time steppers: each advances (x, v) by h with pinned nodes driven to given
// end positions. Buffers live here, so a step allocates nothing once sized.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "cloth_sim/contact.hpp"
#include "cloth_sim/linear_solver.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/pair_constraints.hpp"
#include "cloth_sim/recycled_start.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/self_repulsion.hpp"
#include "cloth_sim/step_stats.hpp"

namespace cloth_sim {

/// Pinned nodes and where each must be at the end of the step.
struct PinnedEnds {
  std::vector<int> nodes;
  std::vector<Vec3> targets;
  /// Empty (every pin whole), or one per pin: zero, the whole position is
  /// prescribed; a unit vector n, only n . x (the node slides freely across
  /// n: a self-contact resolved inside the solve). Implicit steppers only.
  std::vector<Vec3> directions;
  /// Pairs of the cloth held at their gap (self-contacts resolved inside the
  /// solve: one row each, equal and opposite reactions). Implicit steppers only.
  std::vector<PairConstraint> pairs;
  /// The pin's direction, or zero when its whole position is prescribed.
  Vec3 direction(size_t k) const { return directions.empty() ? Vec3::Zero() : directions[k]; }
  /// The caller reads the moving pins' reaction after a linearized step
  /// (their work): only then does a moving pin make the step compute it.
  bool reaction_read = true;
};

/// The state before the step, for the multistep method (bdf2).
struct History {
  const VecX* x_prev = nullptr;
  const VecX* v_prev = nullptr;
  /// bdf2 runs only when h_prev == h (else its start step), or at any ratio
  /// under error-controlled stepping (solver.error_tolerance)
  double h_prev = 0.0;
};

class Stepper {
 public:
  explicit Stepper(const Scene::Solver& settings) : settings_(settings) {}
  const Scene::Solver& settings() const { return settings_; }
  /// Cholesky factorizations made so far (cost accounting).
  int factorizations() const { return cg_.factorizations; }
  /// `cholesky` on a step whose kappa (autoStiffness) is at most
  /// kMassDominatedKappa: the matrix is near its block diagonal (the
  /// masses), block-Jacobi CG converges in a few tens of iterations, and a
  /// factor costs more than it saves. Its solves run block Jacobi for up to
  /// kMassDominatedIterations, then go on with the factor, which then serves
  /// the next kMassDominatedBackoff steps. Only the preconditioner changes
  /// (not Newton's forcing or warm starts): answers within the tolerance.
  /// Measured at dt 1e-4 (kappa 0.06-0.3, ms a step, factor / block Jacobi
  /// first): the twist (s4) 0.255 / 0.143, the fling (s3) 0.328 / 0.201,
  /// the stiffened cloth on a table (c4) 0.80 / 0.29, the heap (s1) 1.11 /
  /// 0.70 (its self-repulsion: 41 CG iterations a step where 11). Up to 10
  /// it still pays (session 53, stretch 1e5 at dt 1e-4, kappa 2.8, us a step,
  /// implicit_euler / newton / bdf2, factor against block Jacobi first): the
  /// twist 245 / 156, 472 / 455, 603 / 386; the fling 343 / 232, 649 / 387;
  /// c4 866 / 309, 720 / 505, 733 / 464; the heap 933 / 599, but under
  /// newton 1686 / 2127 (its repulsion again). At kappa 26 (stretch 1e6) the
  /// factor wins on the twist and the heap.
  static constexpr double kMassDominatedKappa = 10.0;
  static constexpr int kMassDominatedIterations = 60;
  static constexpr int kMassDominatedBackoff = 64;
  /// `multigrid` (asked for, or `auto`'s choice) on a step where its V-cycle
  /// stalls: a solve that has not converged after multigridStallIterations
  /// goes on with a Cholesky factor from where it got to, and the next
  /// kMultigridStallBackoff steps use the factor from the start (then the
  /// V-cycle is tried again). Only the preconditioner changes: answers
  /// within the tolerance, and no step rejected for a stalled solve. Up to
  /// kMultigridFactorNodes nodes (256 x 256: a factor takes 2.4 s and 0.5 GB;
  /// its fill grows as n^1.5): beyond, the V-cycle goes on.
  static constexpr int kMultigridStallBackoff = 64;
  static constexpr int kMultigridFactorNodes = 256 * 256;

  /// Advances x and v in place by h. Fills the solver parts of StepStats
  /// (iterations, residuals, timings, ok/failure); energy and strain are the
  /// caller's. On failure x and v hold garbage: the caller rolls back.
  /// `as`, when given, overrides the scene's method for this step: the
  /// recovery retries a bdf2 step as backward Euler (Method::Newton) and, as
  /// a last resort, takes a linearized step (Method::ImplicitEuler).
  /// With colliders, the step is solved with the contact constraints and
  /// friction and solved again until the contact set is consistent
  /// (ContactSet::update); x and v are then on the right side of every
  /// collider. The contact state carries over to the next step as its start.
  StepStats step(const Model& model, double h, const PinnedEnds& pins,
                 const History& history, VecX& x, VecX& v,
                 std::optional<Method> as = std::nullopt,
                 const CollidersOverStep& colliders = {});
  /// Newton also stops once its decrement, the decrease of the incremental
  /// potential its next full step predicts (-g.delta / 2, J), is at most
  /// this; 0 (the default): only its residual tolerance. The recovery sets
  /// it for implicit_euler's refined steps, which are accepted on the
  /// energy, not on a Newton tolerance.
  void setDecrementStop(double joules) { decrement_stop_ = joules; }
  /// Newton's iterations in place of newton_max_iterations (0: that);
  /// the recovery's refined steps set it.
  void setIterationCap(int cap) { iteration_cap_ = cap; }
  /// Newton also stops at the first iterate (x1, v1) that `accept` takes
  /// (the recovery's energy check for a refined step) once its decrement is
  /// at most `decrement` (J); empty: never.
  void setEnergyStop(std::function<bool(const VecX&, const VecX&)> accept, double decrement) {
    energy_stop_ = std::move(accept);
    energy_stop_decrement_ = decrement;
  }
  /// Self-repulsion terms the implicit steppers add to their forces, matrix
  /// and incremental potential (null: none). The caller owns them and keeps
  /// them over the step; implicit_euler solves again while its answer
  /// changes their active set (SelfRepulsion::updateActiveSet).
  void setRepulsion(SelfRepulsion* repulsion) { repulsion_ = repulsion; }
  /// Whether the cloth collides with itself. Without it (the default), a
  /// Newton solve to the tolerance holds its damping axes and may go on with
  /// the exact Hessian once it converges (see newtonSolve): the newton
  /// method's always, bdf2's (and its retries as backward Euler) in a step
  /// without colliders. With it, only the newton method holds its axes and
  /// takes the exact phase.
  void setSelfCollision(bool on) { self_collision_ = on; }
  /// Whether bdf2's steps, and its retries as backward Euler, hold their
  /// damping axes and may take the exact phase in a step with (or without)
  /// colliders: only without colliders and self-collision (see newtonSolve).
  bool bdf2HoldsAxes(bool colliders) const { return !self_collision_ && !colliders; }
  /// f(x, v): the model's forces (computeForces) plus the repulsion's.
  void forces(const Model& model, const VecX& x, const VecX& v, VecX& f,
              const std::vector<Vec3>* damping_axes = nullptr) const;
  /// Contacts of the last step.
  const ContactSet& contacts() const { return contact_; }
  /// ContactSet::setSlideHeldPulls: the recovery's retry of a step that
  /// gained energy with held contacts pulling.
  void setSlideHeldPulls(bool on) { contact_.setSlideHeldPulls(on); }
  /// Forgets the contact state (reset, or colliders changed).
  void clearContacts() { contact_.clear(); }
  /// After an implicit step whose pins have directions (or any newton/bdf2
  /// step): b h times the force its constraints put on each node at the end,
  /// M (v1 - av) - b h f(x1, v1) (av: v0 for backward Euler), into out (3n);
  /// after implicit_euler's linearized step, what its linear system's
  /// constraints supplied, A dv - rhs: its answer does not balance
  /// f(x1, v1), and the difference swamped the constraint (the twist at
  /// stretch 1e8: +3.9e-3 N s from the system, -1.7 from f(x1, v1); a
  /// third of the held nodes' signs wrong over the run at 1e7 and 1e8, a
  /// tenth at the scene's 2e3).
  void constraintImpulses(const Model& model, const VecX& x1, const VecX& v1, VecX* out);
  /// The last step's held pairs (PinnedEnds::pairs), as its filter restricted them.
  const PairProjection& heldPairs() const { return filter_.pairs(); }
  /// Whether the last solve was implicit_euler's linearized step with its
  /// reaction kept (A dv - rhs; constraintImpulses returns it), and its
  /// scale b h (= h): constraintImpulses / reactionScale() is a force.
  bool linearizedReaction() const { return linearized_; }
  double reactionScale() const { return bh_; }
  /// The along-spring damping axes the last step's forces used, one per
  /// spring, or null where they were the springs' own (see newtonSolve).
  const std::vector<Vec3>* dampingAxes() const { return axes_held_ ? &damping_axes_ : nullptr; }

 private:
  StepStats runMethod(const Model& model, double h, const History& history, VecX& x, VecX& v,
                      Method method);
  /// The step's contact passes from (x0_, v0_): solved, checked against the
  /// colliders (ContactSet::update), solved again until the set holds. With
  /// `explore`, passes before the set holds take kExploringIterations
  /// Newton iterations (see step()); `explored`: a pass stopped there.
  StepStats contactPasses(const Model& model, double h, const History& history, VecX& x,
                          VecX& v, Method method, const CollidersOverStep& colliders,
                          bool explore, bool* explored);
  StepStats implicitEuler(const Model& model, double h, VecX& x, VecX& v);
  /// Whether implicitEuler's step may run split (implicitEulerSplit): no
  /// contact, no self-repulsion terms, no projected pins, every pin held
  /// where it is.
  bool splitStepApplies(double h, const VecX& x, const VecX& v) const;
  /// Pin k's velocity change over a step of h from (x, v) that ends it on its
  /// target, whole (for a projected pin the caller keeps n n^T of it). The
  /// split step's test and implicit_euler's prescribed columns read this one.
  Vec3 pinChange(size_t k, const VecX& x, const VecX& v, double h) const {
    const int p = pins_->nodes[k];
    return (pins_->targets[k] - x.segment<3>(3 * p)) / h - v.segment<3>(3 * p);
  }
  StepStats implicitEulerSplit(const Model& model, double h, VecX& x, VecX& v);
  VecX f_split_, kv_split_, rhs_split_, dv_split_;  ///< its vectors, split by component
  bool recycled_split_ = false;  ///< recycled_ holds split vectors
  /// Whether pin k is directional and its node has a collider contact: the
  /// contact's constraint (its projector and prescribed velocity) then wins,
  /// as the filter's projector already does (ConstraintFilter::project).
  bool yieldsToContact(size_t k) const;
  /// Puts each pinned node exactly on its target (its component along the
  /// pin's direction, for a directional pin); returns whether any moved.
  bool placePins(VecX& x) const;
  /// BDF2 from the state one step back; without one (first step, or h
  /// changed) the trapezoidal rule, so the start is second order too (a
  /// backward-Euler start adds an O(h^2) error that dominates settling scenes).
  StepStats bdf2(const Model& model, double h, const History& history, VecX& x, VecX& v);
  /// Solves x1 = ax + beta h v1, M (v1 - av) = beta h f(x1, v1) by Newton,
  /// from v1 = av, with a backtracking line search: backward Euler (beta = 1,
  /// a = (x0, v0)), BDF2 (beta = 2/3), the trapezoidal rule (beta = 1/2).
  /// Under the newton method, along-spring damping acts along the step start's axes,
  /// held over the step (implicit_euler's linear step has them so too): the
  /// damping force is then linear in v1, g is exactly the gradient of
  /// incrementalPotential and the assembled matrix its Hessian (with
  /// compression projected). With the axis turning inside the step neither
  /// held: Newton converged linearly and its line search stalled (the demo
  /// cloth under newton: 16.4 iterations a step and 52 rejected steps in
  /// 1 s; 12.5 and 19 held). Off by O(h), first order like the method.
  /// bdf2's retries as backward Euler hold them at the start too. bdf2's own
  /// steps hold them at the predicted end ax + b h av, off by O(h^2), which
  /// keeps the second order (held at the start, the error-controlled global
  /// error was 7x the tolerance); with the exact local phase that made the
  /// demo under bdf2 2.2x cheaper (2 s: 3329 -> 1275 Newton iterations, 57
  /// -> 29 rejected). With colliders or self-collision only the newton
  /// method holds them (bdf2: a stability-map run of c4 failed; the heap
  /// rejected 517 sub-steps where 26), and implicit_euler's refined steps
  /// never do (docs/stability.md, docs/design.md).
  StepStats newtonSolve(const Model& model, double h, double beta, const VecX& ax,
                        const VecX& av, int max_iterations, VecX& x, VecX& v);
  /// Newton's merit function: 1/2 |v1 - av|_M^2 + U(x1) + b h R(v1), with U
  /// elastic + gravity potential and R the Rayleigh dissipation (drag, spring
  /// damping along the held axes): its gradient in v1 is g.
  double incrementalPotential(const Model& model, double bh, const VecX& av, const VecX& v1,
                              const VecX& x1) const;
  StepStats symplecticEuler(const Model& model, double h, VecX& x, VecX& v);
  /// assembleSystem plus the repulsion's terms (SelfRepulsion::addToSystem).
  void assemble(const Model& model, const VecX& x, const VecX& v, double a, double b,
                const VecX* w, VecX* dfdx_w, const std::vector<Vec3>* damping_axes,
                bool linearized);
  /// assemble without the repulsion's terms: the springs' (assembleSystem).
  void assembleSprings(const Model& model, const VecX& x, const VecX& v, double a, double b,
                       const VecX* w, VecX* dfdx_w, const std::vector<Vec3>* damping_axes);
  /// implicitEuler's assemble, or, at a later contact pass of the same step
  /// (the same x0, v0, h), the springs' terms it kept and the repulsion's
  /// afresh: the springs' part is the same numbers, half a pass's time on a
  /// cloth resting on a table at dt 1e-4 (c4).
  void assembleLinearized(const Model& model, const VecX& x, const VecX& v, double h);
  void setPins(const Model& model, const PinnedEnds& pins);
  /// CG on A_ x = b (x: warm start and answer) with the scene's solver
  /// settings, to `tolerance` (relative; 0: solver.tolerance); with `split`,
  /// b and x split by component (conjugateGradient).
  CgResult solveLinear(const Model& model, const VecX& b, VecX& x, double tolerance = 0.0,
                       bool split = false);
  /// solveLinear's two-stage solves: `first` for up to `cap` iterations; if
  /// that leaves CG short, `*went_on` is set and CG goes on from x with the
  /// preconditioner `then()` gives and the whole budget (iterations summed).
  template <class Then>
  CgResult solveThenGoOn(const Model& model, const VecX& b, VecX& x, double tolerance,
                         bool split, Preconditioner first, int cap, Then then, bool* went_on);
  /// g = M (v1 - av) - beta h f(ax + beta h v1, v1) on free nodes; returns ||g||.
  double residual(const Model& model, double bh, const VecX& ax, const VecX& av,
                  const VecX& v1, VecX& x1, VecX& g);
  /// The same g from forces f already evaluated at (ax + beta h v1, v1).
  double residualFromForces(const Model& model, double bh, const VecX& av, const VecX& v1,
                            const VecX& f, VecX& g) const;

  Scene::Solver settings_;
  Preconditioner preconditioner_ = Preconditioner::BlockJacobi;  ///< this step's (auto resolved)
  AutoPreconditioner auto_;  ///< `auto`'s choice across steps
  bool mass_dominated_ = false;  ///< this step
  int mass_dominated_backoff_ = 0;
  int multigrid_stall_backoff_ = 0;  ///< steps left on the factor after a stall
  SelfRepulsion* repulsion_ = nullptr;  ///< setRepulsion's
  ConstraintFilter filter_;  ///< pins (eliminated) and contacts (projected)
  ContactSet contact_;
  bool contact_on_ = false;  ///< this step has colliders
  double bh_ = 0.0;          ///< the last solve's b h (reaction scale)
  bool linearized_ = false;  ///< the last solve was implicitEuler's: reaction_ is A dv - rhs0_
  VecX x0_, v0_, reaction_, rhs0_;
  VecX x_repulsed_, v_repulsed_;  ///< implicit_euler's start, for a solve again with a changed active set
  const PinnedEnds* pins_ = nullptr;
  SystemMatrix A_;
  CgWorkspace cg_;
  /// assembleLinearized's springs' part at this step's start (valid within
  /// one step(): the model does not change there).
  struct StartAssembly {
    bool valid = false;
    double h = 0.0;
    VecX x, v, f, dfdx_v;
  } start_assembly_;
  VecX f_, rhs_, dv_, dfdx_v_, g_, x_trial_, v_trial_, g_trial_, delta_, delta_first_, ax_, av_, pinned_dv_;
  bool pinned_dv_dirty_ = true;  ///< pinned_dv_ holds a nonzero entry
  /// Whether x and v came out of the last runMethod finite, where it knows
  /// (implicit_euler checks in its last pass over them).
  bool finite_known_ = false, finite_ = true;
  /// implicit_euler's warm start: its first passes' answers (without contact).
  RecycledStart recycled_;
  int recycled_iterations_ = 2;  ///< CG iterations of the last first pass
  /// Newton's first corrections (first passes) with block Jacobi or no
  /// preconditioner: the next one's warm start.
  RecycledStart newton_recycled_;
  bool first_pass_ = true;  ///< the step's first contact pass (or no contact)
  VecX x_best_, v_best_, g_best_;  ///< the line search's best trial
  VecX v_start_;                   ///< Newton's first iterate
  /// The last contact pass's answer: the next pass's Newton starts there
  /// (empty on a step's first pass).
  VecX v_pass_;
  double pass_g0_ = 0.0;  ///< ||g|| at the first pass's start: later passes' scale
  std::vector<Vec3> damping_axes_;  ///< along-spring damping axes held over a Newton step
  /// newtonSolve's local phase: assemble without the compression projection.
  bool exact_hessian_ = false;
  bool self_collision_ = false;  ///< setSelfCollision
  Method method_ = Method::ImplicitEuler;  ///< this step's method (the scene's, or step()'s `as`)
  bool axes_held_ = false;        ///< damping_axes_ hold for the last step
  double decrement_stop_ = 0.0;    ///< setDecrementStop
  std::function<bool(const VecX&, const VecX&)> energy_stop_;  ///< setEnergyStop
  double energy_stop_decrement_ = 0.0;
  int iteration_cap_ = 0;  ///< setIterationCap
  int pass_cap_ = 0;  ///< Newton's iterations in an exploring contact pass (0: no cap)
};

}  // namespace cloth_sim
