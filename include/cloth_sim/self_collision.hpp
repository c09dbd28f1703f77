// The cloth against itself: a filter applied to each solved step, from the
// step's start x0 to its end x1, after Bridson, Fedkiw & Anderson 2002 with
// Harmon et al. 2008's fail-safe:
//  1. proximity: pairs closer than the thickness at x1 get an inelastic
//     normal impulse (the approach is stopped, up to the thickness) and
//     Coulomb friction (tangential impulse at most mu times the normal one),
//     found together by projected Gauss-Seidel sweeps (pairs share nodes);
//  2. a few rounds of CCD: each pair that would come closer than a minimum
//     separation along the linear motion gets an inelastic impulse at its
//     time of impact;
//  3. impact zones: the nodes of pairs that still collide are merged into
//     zones, each moved as one rigid body (linear and angular momentum kept;
//     in a collider's plane, or not at all, when it holds nodes on a collider),
//     until CCD finds nothing outside a zone. A rigid motion keeps distances,
//     so, from an intersection-free x0, the end state is intersection-free.
// Impulses act on positions (x1 moves by w_i / m_i J n) and change each
// moved node's velocity by its displacement over h: inelastic, no bounce.
// Pinned nodes have infinite mass (their work through the filter is
// reported), nodes on a collider infinite mass against moves into it only,
// once back where they started the step along its normal.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "cloth_sim/model.hpp"
#include "cloth_sim/pair_constraints.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/self_repulsion.hpp"
#include "cloth_sim/spatial_hash.hpp"

namespace cloth_sim {

/// What the filter did to one step.
struct SelfCollisionResult {
  bool ok = true;
  std::string failure;  ///< when !ok: why (the caller rejects the step)
  /// pairs closer than the thickness at the end, counting those resting on
  /// it (within kRestingSlack of it: where the response leaves them)
  int contacts = 0;
  /// smallest distance between non-adjacent primitives at the end; exact
  /// when below the thickness, else a lower bound >= the thickness of the
  /// near pairs' distances (DistanceCull; pairs farther apart are not looked
  /// at), infinity when none is near
  double min_distance = std::numeric_limits<double>::infinity();
  int proximity_impulses = 0;
  /// Gauss-Seidel sweeps the proximity impulses took to settle (the limit,
  /// 30, when they did not)
  int proximity_sweeps = 0;
  int ccd_impulses = 0;
  int zone_rounds = 0;  ///< rounds of impact zones (0: impulses sufficed)
  int zone_nodes = 0;   ///< nodes moved rigidly
  int candidates = 0;   ///< broad-phase pairs of the first query
  /// work the pins did on the cloth through the filter (J): the impulses
  /// they held against and the zones they dragged, times their velocity
  double pin_work = 0.0;
  /// the zones' part of pin_work (J)
  double zone_pin_work = 0.0;
};

/// Which nodes the filter may not move, and which it may move only along a
/// collider's surface.
struct SelfCollisionMasses {
  std::vector<int> fixed;  ///< pinned: infinite mass, their x1 is prescribed
  std::vector<int> heavy;  ///< held by a collider contact
  /// per `heavy` entry: its surface normal (a node then has infinite mass
  /// against impulses into the surface and its own mass otherwise), or
  /// zero (infinite mass: wedged)
  std::vector<Vec3> heavy_normal;
  /// per `heavy` entry with a normal: how far it moved away from that
  /// surface over the step (its distance to it at x1 less at x0, >= 0):
  /// what the filter may push it back before it is a wall (SelfCollision::room)
  std::vector<double> heavy_room;
  /// Every other node, against the nearest collider: its surface normal and
  /// its distance beyond the thickness band at x1, how far the filter may
  /// push it towards that surface before it is a wall there. An impulse
  /// through a layer above can push a free node further than the gap it
  /// has: the fold laid at dt 1/120 had a CCD impulse move a node 2.3 mm
  /// down, 1.5 mm above the band. Not for the impact zones' rigid motions
  /// (a free node far above a table would bar a zone's rotation), which
  /// are taken back to x0 instead where they would take one of these
  /// nodes into the band.
  std::vector<int> guarded;
  std::vector<Vec3> guarded_normal;
  std::vector<double> guarded_room;
};

class ContactSet;
struct CollidersOverStep;

/// The masses for a step from x0 to x1: the pinned nodes fixed; the nodes
/// the contact solve holds, and every node within `reach` of the thickness
/// band of a collider at x1, held against moves into that surface (wedged
/// if two) beyond what they moved away from it in the step; every other
/// node guarded against moves into its nearest collider beyond the band.
/// Sliding across the normal or moving away from the surface cannot take a
/// node into a convex collider, nor can a move back to where it was at x0.
void selfCollisionMasses(const std::vector<int>& pinned, const ContactSet& contacts,
                         const CollidersOverStep& colliders, const VecX& x0, const VecX& x1,
                         double reach, SelfCollisionMasses* out);

/// The first node the filter moved (before -> after) that ends deeper
/// inside a collider's thickness band than both where it started the step
/// (x0) and where the solve left it (before) (-1: none, else `which` says
/// which node and collider).
int pushedIntoCollider(const CollidersOverStep& colliders, const VecX& x0, const VecX& before,
                       const VecX& after, std::string* which);

class SelfCollision {
 public:
  /// A pair this fraction of the thickness beyond it still counts as a
  /// contact (SelfCollisionResult::contacts).
  static constexpr double kRestingSlack = 1e-3;
  SelfCollision() = default;
  SelfCollision(const Model& model, const Scene::SelfCollision& params);
  bool enabled() const { return enabled_; }
  /// The filter's proximity stage acts on pairs closer than this fraction of
  /// the thickness (1 by default). With self-repulsion inside the solve
  /// (self_repulsion.hpp) keeping resting layers at the thickness, the
  /// simulation sets it below 1: the filter is then the fail-safe for what
  /// the solve let through, not a second push on every resting pair.
  void setProximity(double fraction) { proximity_ = fraction; }

  /// Inputs: the step's length h, its start x0 (3n) and solved end x1 (3n),
  /// v the solved end velocity, `masses`. Output: x1 and v filtered as above
  /// (v += (x1 out - x1 in) / h: untouched where the filter moved nothing).
  /// Fails (ok = false, x1 and v then partly filtered: the caller rolls the
  /// step back) when a zone holds fixed nodes that do not move as one
  /// translation, or the zones do not settle within their round limit.
  /// `contacts` and `min_distance` are left to measure(): a step filters up
  /// to 4 times and reports only the last.
  SelfCollisionResult apply(const Model& model, double h, const VecX& x0,
                            const SelfCollisionMasses& masses, VecX& x1, VecX& v);
  /// The last apply's pairs that a proximity or CCD impulse pushed apart:
  /// nodes, weights and normal where it acted (`gap` left 0 for the caller).
  const std::vector<PairConstraint>& pushedPairs() const { return pushed_; }
  /// Whether the last apply moved node i with an impact zone.
  bool movedInZone(int i) const { return in_zone_[i] != 0; }

  /// Distance and closeness of every candidate pair at positions x (for the
  /// final report; also the tests' proximity measure).
  void measure(const VecX& x, SelfCollisionResult* result);

  /// The repulsion terms of a step from x0 (self_repulsion.hpp), x1 a
  /// prediction of its end (x0 + h v0): per node, the nearest triangle (not
  /// its own) whose gap is below `reach` at x0 or, along the normal at x0,
  /// at x1, and one on the node's other side (a node between two layers):
  /// the most energy at x0 among the triangles whose normal opposes the
  /// first's, its stiffness weighted from 0 (normals 104 degrees apart)
  /// to 1 (139 degrees and beyond), so that the energy the terms measure at
  /// x0 = x1 changes continuously with the positions and not with the order
  /// of the hash's pairs. Weights and normal are the closest points' at x0; the
  /// stiffness is `scale` times the pair's effective mass 1 / sum_k w_k^2 / m_k
  /// (scale c / h^2: c times as stiff as its nodes' inertia over the step);
  /// active where the gap at x0 is below the reach. Point-triangle pairs only:
  /// edge-edge pairs add little between layers (every node is a point over
  /// the other layer) and cost several terms a node in every product.
  /// Replaces out's terms.
  void repulsionTerms(const Model& model, const VecX& x0, const VecX& x1, double reach,
                      double scale, SelfRepulsion* out);

  const CollisionMesh& mesh() const { return mesh_; }

 private:
  /// One point–triangle (kind 0) or edge–edge (kind 1) pair as four nodes
  /// with the weights of the relative position w . x (closest points' difference).
  struct Pair {
    int node[4];
    double w[4];
    Vec3 n;           ///< unit normal: the closest points' direction where measured
    double distance;  ///< where measured
    double target;    ///< end gap along n the impulse restores (if larger)
    /// impulses applied so far (displacement units times mass): normal,
    /// >= 0, and friction, across n, at most `friction_` times the normal
    double normal_impulse = 0.0;
    Vec3 friction_impulse = Vec3::Zero();
  };
  /// The pair's nodes, closest-point weights, normal and distance at the
  /// four positions `at` (ordered as nodesOf).
  void makePair(int kind, int a, int b, const std::array<Vec3, 4>& at, Pair* pair) const;
  void gather(const std::array<int, 4>& nodes, const VecX& x, std::array<Vec3, 4>* out) const;
  std::array<int, 4> nodesOf(int kind, int a, int b) const;
  /// Brings pair's accumulated impulses to what x1 now needs (one projected
  /// Gauss-Seidel update: the normal one restores the gap to the target and
  /// may shrink, never below zero; friction stops the slip within the cone)
  /// and applies the change to x1. Returns the change of the pair's gap
  /// (0: nothing to do). Adds the work of pinned nodes of the pair, times
  /// h^2, to pin_work.
  double impulse(Pair& pair, const VecX& x0, VecX& x1, double* pin_work) const;
  /// CCD of every candidate pair not inside one zone; fills hits_.
  void detect(const VecX& x0, const VecX& x1, bool skip_zones);
  /// Moves each zone rigidly; false (with `failure`) if a zone cannot move.
  /// Adds the work of pins dragging a zone, times h^2, to pin_work.
  bool moveZones(const VecX& x0, VecX& x1, std::string* failure, int* moved, double* pin_work);
  int find(int i);

  bool enabled_ = false;
  double thickness_ = 0.0;
  double friction_ = 0.0;
  double separation_ = 0.0;  ///< CCD's minimum separation
  double proximity_ = 1.0;   ///< setProximity's
  CollisionMesh mesh_;
  SpatialHash hash_;
  CandidatePairs pairs_;
  std::vector<double> mass_, inv_mass_;  ///< inv_mass_ 0: pinned or wedged
  std::vector<Vec3> normal_;      ///< a contact's surface normal, else zero
  std::vector<double> room_;      ///< SelfCollisionMasses::heavy_room per node, else 0
  std::vector<char> guarded_;     ///< normal_ and room_ from SelfCollisionMasses::guarded
  /// Displacement of node i when an impulse of dx (displacement units times
  /// mass) acts on it with weight w: w / m dx, less any part into the
  /// surface of normal_ beyond `room` (room(i, x1)). One-sided: a node
  /// near a collider is a wall only against impulses that push it in;
  /// pushed away it moves with its own mass (held both ways, a layer
  /// falling onto one on a table threw its other nodes by the whole gap:
  /// fold.yaml, energy jump, issue 14). Where the pair's push (along +n)
  /// meets the wall (`wall`: into the surface, no room), none of the node's
  /// share along the normal, whichever the sign of dx: an accumulated
  /// impulse eased off in a later sweep must not lift a node its push never
  /// moved (offset layers on a table: 0.23 mm; with the towel's table nodes
  /// held along their normal, its top layer crept up 0.3 um a step).
  Vec3 nodeShare(int i, double w, const Vec3& dx, double room, bool wall) const;
  /// How far node i, at x1, may still be pushed into its collider's surface
  /// before it is a wall: its travel away from the surface in the step
  /// (SelfCollisionMasses::heavy_room, plus the filter's own moves along the
  /// normal since; 0 when none). A static surface stops a node, it does not
  /// push one that is moving away from it: a wall at once, a node lifting
  /// off the table at 0.31 m/s pushed the layer above it up to its own
  /// speed, and the heap at stretch 100, dt 1e-4, gained 7e-6 J of kinetic
  /// energy at every halving down to 4e-7 s (at stretch 1e6, dt 0.01: 0.19
  /// m/s, 1e-6 J at dt/256).
  double room(int i, const VecX& x1) const;
  /// Node i's distance left towards its surface were it at `at` (< 0: past
  /// its room), before room()'s round-off.
  double away(int i, const Vec3& at) const {
    return room_[i] + normal_[i].dot(at - x1_in_.segment<3>(3 * i));
  }
  std::vector<int> parent_;  ///< zone union-find (a node alone is its own root)
  std::vector<char> in_zone_;
  std::vector<PairConstraint> pushed_;  ///< pushedPairs()
  void notePushed(const Pair& pair);
  std::vector<char> fixed_;
  struct Hit {
    int kind, a, b;
    double toi;
  };
  std::vector<Hit> hits_;
  VecX x1_in_;
  std::vector<Pair> close_;         ///< apply's close pairs (kept for its capacity)
  std::vector<int> sweep_nodes_;    ///< the nodes of the close pairs (sorted, unique)
  std::vector<Vec3> sweep_start_;   ///< their x1 at the start of a proximity sweep
  /// repulsionTerms': every candidate term, and per node the candidates
  /// chosen on either side (-1: none)
  struct Candidate {
    RepulsionTerm term;
    double distance;
    int node;
  };
  std::vector<Candidate> candidates_;
  std::vector<double> side_weight_;
  std::vector<std::array<int, 2>> node_terms_;
};

}  // namespace cloth_sim
