// Contact between the cloth's nodes and rigid colliders, inside the implicit
// solve (Baraff & Witkin 1998, section 5; docs/design.md "Contact"):
//  - detection: a node whose path over the step comes within `thickness` of a
//    collider (swept, so nothing tunnels) gets a contact: the plane tangent
//    to the collider at the contact point, moved out by the thickness;
//  - constraint: the solve keeps the node's end position on that plane
//    (filter S = I - n n^T and a prescribed normal velocity; two planes at
//    an edge or between two colliders); a sticking node is held entirely,
//    moving with the collider's surface;
//  - friction: a sliding node feels mu times its normal force against its
//    slip, the normal force lagged from the previous pass of the same step.
//    With a friction smoothing eps > 0 (contact.friction_smoothing) a step
//    in which a contact slides has no sticking node: friction is mu f_n
//    f1(|s|) against the slip s, with IPC's f1 rising smoothly from 0 to 1
//    over |s| < eps (Li et al. 2020), so one solve finds every node that
//    slides. With exact_sticking (the default) a step where every contact
//    sticks keeps exact stick states, and a node that ends a step slipping
//    slower than eps sticks again; without it no node ever sticks.
// After each solve `update` checks the answer against Coulomb's law and the
// colliders (adhesion released, stick/slip switched, new contacts added);
// the step is solved again until nothing changes. With no colliders none of
// this runs.
#pragma once

#include <string>
#include <vector>

#include "cloth_sim/collider.hpp"
#include "cloth_sim/contact_broad_phase.hpp"
#include "cloth_sim/constraint_filter.hpp"
#include "cloth_sim/linear_solver.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// What the last update found.
enum class ContactCheck { Consistent, Changed, Failed };

/// What an update changed, by kind (why a step took another pass).
struct ContactChanges {
  int added = 0;     ///< new contacts (swept path or end too close)
  int released = 0;  ///< pulling contacts let go
  int slid = 0;      ///< sticking nodes outside the cone
  int stuck = 0;     ///< sliding nodes whose slip friction would reverse
  int friction = 0;  ///< friction magnitude or direction still lagging
  bool smoothed = false;  ///< the step turned smoothed (a sticking node outside its cone)
};

class ContactSet {
 public:
  /// Contact passes a step may take before it is reported as failed.
  static constexpr int kMaxPasses = 25;
  /// A node's friction force may lag mu times the normal force of the same
  /// step by this fraction before the step is solved again (the lag then
  /// carries to the next step, as IPC's lagged friction does) ...
  static constexpr double kFrictionLag = 0.1;
  /// ... and its direction turn by this many radians.
  static constexpr double kDirectionLag = 0.05;
  /// IPC's smoothed Coulomb sign: f1(s) = 2 s / eps - s^2 / eps^2 below eps,
  /// 1 above (eps > 0).
  static double smoothedSign(double s, double eps);
  /// Passes in which friction is refined: stick/slip switches and the lag of
  /// its magnitude and direction. After them the friction states are kept
  /// as they are (a lag, as IPC's lagged friction has; a node held stuck a
  /// step longer than Coulomb would), while a contact set that still changes
  /// (new contacts, releases) keeps the step going. A switch that would have
  /// made the step gain energy is caught by the step's energy check.
  static constexpr int kFrictionPasses = 2;
  /// A node ends a step at least thickness - kPenetrationTolerance from every
  /// collider (m); deeper counts as a new contact.
  static constexpr double kPenetrationTolerance = 1e-10;
  /// The friction Jacobian's cap / |s| is taken at |s| no less than this (m/s).
  static constexpr double kStopSpeed = 1e-4;
  /// A lagged friction direction that would move its node by less than this
  /// over the step (m) counts as settled.
  static constexpr double kSlipTolerance = 1e-9;

  /// The cloth's grid (node i = row * cols + col), for the broad phase's patches.
  void setGrid(int rows, int cols) { broad_.setGrid(rows, cols); }
  /// The broad phase of the last begin or update.
  const ContactBroadPhase& broadPhase() const { return broad_; }
  /// Node-collider pairs the last begin or update queried exactly (those the
  /// broad phase kept; a node already touching that collider counts too).
  long lastQueries() const { return queries_; }

  /// Drops every contact (a reset).
  void clear() {
    nodes_.clear();
    slot_.clear();
    pulled_.clear();
    released_.clear();
  }

  /// Keeps the contacts a step starts from (all that begin() reads of the
  /// last step), and goes back to them: a step taken again starts where its
  /// first try did.
  void keepStart() { start_nodes_ = nodes_; }
  void backToStart() {
    nodes_ = start_nodes_;
    reindex(static_cast<int>(slot_.size()));
  }

  /// Start of a step from (x0, v0): keeps last step's contacts that still
  /// touch, re-linearised at x0, and adds those the predicted path
  /// x0 + h v0 + h^2 g would make. Pinned nodes (eliminated) get none.
  void begin(const CollidersOverStep& colliders, const ConstraintFilter& pins, const VecX& x0,
             const VecX& v0, const Vec3& gravity, double h);
  /// Projects the contact nodes in the filter (after the pins are set).
  void constrain(ConstraintFilter& filter) const;
  /// Projects out only the contact normals, sticking nodes too (their
  /// tangent kept): the directions in which a contact node's end position is
  /// its surface's, whenever it landed (the error estimate's filter).
  void constrainNormals(ConstraintFilter& filter) const;
  /// The constrained part of node k's end velocity: v1 = S v1 + w, so that
  /// x1 = ax + bh v1 is on every contact plane (and moves with the surface
  /// when sticking).
  Vec3 prescribed(size_t k, const VecX& ax, double bh) const;
  /// v1 <- S v1 + w on every contact node.
  void prescribe(const VecX& ax, double bh, VecX& v1) const;
  /// After an accepted step of length h, on the nodes that landed in it:
  /// the constrained part of the node's state (its normals; all of it when
  /// sticking) moves with its surfaces, at the end of the step and one step
  /// back, the history BDF2 extrapolates from. An inelastic contact ends at
  /// the surface's velocity; the solve's v1 = (x1 - ax) / bh is that only
  /// where the history is smooth. Across the impact BDF2's ax lies behind
  /// the plane, so v1 left it at half the impact speed and the next step's
  /// av pulled the node off again (a bounce, caught by the energy check or
  /// not at all). Contacts kept from the step before are smooth already.
  /// Returns whether any node landed (else nothing changed).
  bool alignWithSurfaces(double h, const VecX& x1, VecX& v1, VecX& x_prev, VecX& v_prev) const;
  /// The same as a velocity change from v0: c = w - (I - S) v0 on the
  /// contact nodes (other entries untouched). Returns whether any is nonzero.
  bool prescribeChange(const VecX& ax, double bh, const VecX& v0, VecX& c) const;
  /// f += scale * friction on the sliding nodes at velocity v: cap = mu times
  /// the lagged normal force against the last pass's slip s0, linearised in
  /// how it turns: -cap s0^ - cap / |s0| P (v - v_surface), P = T - s0^ s0^T.
  /// The turn term lets the solve see the direction follow the slip (a
  /// Newton step on it rather than a fixed-point iteration, which crawls
  /// when the friction is large against the mass); without a known slip
  /// speed (a new slide) it is left out. Smoothed (friction_smoothing eps >
  /// 0): -cap f1(|s|) s^ linearised at s0, i.e. -cap [(f1(|s0|) + f1'(|s0|)
  /// (s0^.s - |s0|)) s0^ + f1(|s0|) / |s0| P s] (a drag 2 cap / eps at rest).
  void addFriction(VecX& f, double scale, const VecX& v) const;
  /// A += scale * cap / |s0| P: minus that force's derivative in v (at v
  /// when smoothed in Newton's iterates; see FrictionSolve).
  void addFrictionJacobian(SystemMatrix& A, double scale, const VecX& v) const;
  /// How a solve takes smoothed friction (friction_smoothing > 0; exact
  /// Coulomb is always linearised at s0).
  enum class FrictionSolve {
    /// A linearly implicit step: linearised at the lagged slip s0; a later
    /// pass relinearises where the last one ended.
    Linearized,
    /// Newton to a tolerance: f1's force, its potential f0 and its PSD
    /// Hessian exactly at each iterate's slip (f1' along it).
    Newton,
    /// Newton stopped on a decrement or the energy check (implicit_euler's
    /// refined steps), or after one iteration (a linearly implicit newton
    /// or bdf2 step): the same force and potential, and along the slip the
    /// drag f1(|s|) / |s| instead of f1', a quadratic above f0 (concave in
    /// |s|^2), so each full step lowers the potential even where a slide
    /// stops. f1' overshoots there (0 beyond eps): the fold demo at stretch
    /// 2800 stalled at ||g|| 8.7e-4 for 4 iterations and was halved. To a
    /// tolerance the drag converges only linearly (contact hard case c4
    /// under newton: 1687 rejected sub-steps where f1' has none).
    Descent,
  };
  void setFrictionSolve(FrictionSolve mode) { friction_solve_ = mode; }
  /// The potential whose gradient in v is minus that force:
  /// sum of cap s0^.(v - v_s) + cap / (2 |s0|) |P (v - v_s)|^2.
  double frictionPotential(const VecX& v) const;

  /// Checks a solved step. `reaction` is b h times the contact force on each
  /// node: M (v1 - av) - b h f(x1, v1), friction left out. Updates normal
  /// forces, releases pulling contacts, switches stick/slip, adds contacts
  /// where the path x0 -> x1 comes too close. Fills maxPenetration().
  /// `solve_tolerance` is the linear solve's relative tolerance: a contact
  /// lets go only when it pulls by more than that fraction of the node's
  /// weight and force (a loose solve's normal forces are that noisy).
  /// In a step's first kFrictionPasses passes friction is refined too,
  /// whether their answers were solved to the tolerance or not (Stepper::
  /// step's exploring passes). Refined on converged answers only, each
  /// change of friction cost a pass to the tolerance: the heap (s1) under
  /// newton took 110 Newton iterations a step where 34, 62-75 where 27-42
  /// over seeds 2-3. The price: a folded cloth dropped on a table under bdf2
  /// gained 1.2e-6 J in a step where < 3e-7 (test_self_collision.cpp).
  ContactCheck update(const CollidersOverStep& colliders, const ConstraintFilter& pins,
                      const std::vector<double>& mass, const VecX& x0, const VecX& x1,
                      const VecX& v1, const VecX& reaction, double bh,
                      const Vec3& gravity, double solve_tolerance);
  /// What the last update changed.
  const ContactChanges& lastChanges() const { return changes_; }
  /// Contacts back after their release in this step (held) that stuck and
  /// pulled in the last update.
  int heldPulls() const { return held_pulls_; }
  /// From now on a held contact that pulls slides (its friction cone is
  /// empty) instead of sticking; off by default (see update).
  void setSlideHeldPulls(bool on) { slide_held_pulls_ = on; }
  /// Why the last update failed.
  const std::string& failure() const { return failure_; }

  // --- after a consistent update ---
  int numContacts() const { return static_cast<int>(nodes_.size()); }
  /// Sum of the normal force magnitudes (N).
  double normalForce() const;
  /// Deepest any node went inside surface + thickness at the end of the step (m, >= 0).
  double maxPenetration() const { return max_penetration_; }
  /// Work the contact forces did on the nodes over the step (J).
  double work(const VecX& x0, const VecX& x1, const VecX& reaction, double bh) const;
  bool empty() const { return nodes_.empty(); }
  /// Whether node i has a contact.
  bool holds(int i) const { return i < static_cast<int>(slot_.size()) && slot_[i] >= 0; }
  std::vector<int> contactNodes() const;
  /// Per contactNodes() entry: the surface normal at the end of the step
  /// for a node on one surface, zero for one wedged between two.
  std::vector<Vec3> contactNormals() const;

 private:
  static constexpr int kMaxPlanes = 2;
  struct Plane {
    int collider = -1;
    Vec3 local_point = Vec3::Zero();   ///< on the surface, collider frame
    Vec3 local_normal = Vec3::UnitZ();
    Vec3 normal = Vec3::UnitZ();       ///< world, end of step
    double offset = 0.0;               ///< n . x1 = offset
    Vec3 surface_velocity = Vec3::Zero();  ///< of the contact point over the step
    double normal_force = 0.0;       ///< N, last check
  };
  struct NodeContact {
    int node = -1;
    int num_planes = 0;
    Plane plane[kMaxPlanes];
    bool sticking = true;
    Vec3 slip = Vec3::Zero();   ///< unit slip direction (sliding)
    double slip_speed = 0.0;    ///< |slip| at the last check (0: not known)
    double friction = 0.0;      ///< friction force magnitude used in the solve (N)
    bool held = false;          ///< released once this step and back: kept
    bool fresh = true;          ///< not in contact at the step's start (it landed)
    int flips = 0;              ///< stick/slip switches this step
    // derived by refresh():
    Mat3 tangent = Mat3::Identity();  ///< projector on the tangent space
    Vec3 surface_velocity = Vec3::Zero();
    double mu = 0.0;
  };

  /// Sets a plane from a surface point in collider k's frame (world values at
  /// the end pose, the surface velocity from start to end).
  void setPlane(Plane& p, int collider, const SurfacePoint& local,
                const CollidersOverStep& colliders, double h) const;
  /// The velocity whose speed along each of c's plane normals is t0 (t1):
  /// the normals' dual basis, for two planes at an angle.
  static Vec3 normalVelocity(const NodeContact& c, double t0, double t1);
  /// Projector and friction coefficient from the planes. False: no room.
  bool refresh(NodeContact& c, const CollidersOverStep& colliders);
  /// Adds collider k's plane to node contact c (or replaces a parallel one).
  bool addPlane(NodeContact& c, int collider, const SurfacePoint& local,
                const CollidersOverStep& colliders);
  void reindex(int num_nodes);
  /// A sliding node's friction linearised at its lagged slip s0:
  /// -cap (base + along (s0^.s - |s0|)) s0^ - turn P s, P = T - s0^ s0^T.
  /// Exact Coulomb: base 1, along 0, turn cap / max(|s0|, kStopSpeed).
  /// Smoothed: base f1(|s0|), along f1'(|s0|), turn cap f1(|s0|) / |s0|;
  /// in Newton's iterates (setFrictionSolve) s0 is s itself, so the
  /// force is f1's exactly.
  struct FrictionLaw {
    Vec3 dir = Vec3::Zero();  ///< s0^ (zero when not known)
    double speed = 0.0;       ///< |s0|
    double base = 1.0, along = 0.0;  ///< per unit of cap
    double turn = 0.0;               ///< N s/m
  };
  FrictionLaw law(const NodeContact& c, const Vec3& s) const;
  /// A new contact starts stuck under exact Coulomb with friction; smoothed
  /// friction has no stick state.
  bool sticksOnArrival(double friction) const { return smoothing_ <= 0.0 && friction > 0.0; }
  /// Smoothed friction taken at each Newton iterate's own slip (FrictionSolve).
  bool smoothedAtIterate() const {
    return smoothing_ > 0.0 && friction_solve_ != FrictionSolve::Linearized;
  }
  /// That force (N) at slip s.
  static Vec3 linearFriction(const NodeContact& c, const FrictionLaw& l, const Vec3& s);
  /// Appends a node with no planes yet; returns its slot.
  int addNode(int node, bool sticking);
  /// Whether the node in `slot` (-1: none) has a plane of this collider.
  bool touches(int slot, int collider) const;

  ContactBroadPhase broad_;
  long queries_ = 0;
  std::vector<NodeContact> nodes_;
  std::vector<NodeContact> start_nodes_;  ///< keepStart()'s
  std::vector<int> slot_;  ///< per node: index in nodes_, -1 if not in contact
  std::vector<int> released_;  ///< nodes released this step (cycling guard)
  std::vector<char> pulled_;   ///< per node: let go for pulling, not found on a surface since
  int passes_ = 0;             ///< updates this step
  int held_pulls_ = 0;         ///< heldPulls()
  bool slide_held_pulls_ = false;
  ContactChanges changes_;
  double h_ = 0.0;
  double smoothing_ = 0.0;  ///< friction smoothing eps of this step (m/s); 0: stick/slip
  /// eps for steps in which a contact slides, with exact sticking at rest
  /// (CollidersOverStep::exact_sticking); 0: the step's mode is fixed.
  double motion_smoothing_ = 0.0;
  void smoothAll(const CollidersOverStep& colliders);
  /// mu times the normal force, summed over c's planes (their last normal_force).
  static double frictionCap(const NodeContact& c, const std::vector<Collider>& all);
  FrictionSolve friction_solve_ = FrictionSolve::Linearized;
  double max_penetration_ = 0.0;
  std::string failure_;
};

}  // namespace cloth_sim
