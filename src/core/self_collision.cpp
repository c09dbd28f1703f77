// Self-collision response: proximity impulses with friction, CCD impulses,
// impact zones. See self_collision.hpp for the scheme and docs/design.md for
// why this and not a barrier.
#include "cloth_sim/self_collision.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "cloth_sim/collision_geometry.hpp"

namespace cloth_sim {
namespace {

constexpr int kCcdRounds = 4;     // impulse rounds before zones (Bridson et al. use a few)
constexpr int kZoneRounds = 100;  // zone merges before the step is given up
// Largest displacement of a node per unit of gap an impulse may cause: 1 to 2
// when all four nodes move (weights >= 1/3 of the pair's), 1/w for a lone
// movable node of weight w.
constexpr double kMaxReach = 4.0;
// Proximity sweeps end when no node moved by more than this many thicknesses
// over a sweep (what is left over is ~ its square in energy), or after
// kProximitySweeps. Nodes, not pairs: nearly parallel pairs on one node (a
// point over a triangle, a triangle's node over that point) hand their
// impulse to each other at a fraction of a percent a sweep, each pair's gap
// changing by as much while the node stays put: the folded towel at rest
// stopped at the sweep limit at every step (30 sweeps, 4.2 of the filter's
// 5.4 ms a step), its nodes still after 5. Not 1e-3: at that much node
// motion the twist at stretch 1e7, dt 0.01, failed on energy.
constexpr double kProximitySettled = 1e-4;
constexpr int kProximitySweeps = 30;
// A node's room towards its collider below this many thicknesses is none.
constexpr double kRoomRoundOff = 1e-9;
// The CCD (collision_geometry.hpp) reports a pair once within 1.1 times the
// separation, or when its advances did not get it past the step. A pair
// whose distance bound (DistanceCull) stays above 1.1 separations with this
// much of the nodes' displacement to spare does neither: each advance is at
// least 0.9 (bound - separation) / (8 displacement), 500 of them cover the
// step once the spare 0.02 exceeds 8 / (0.9 * 500) = 0.018.
constexpr double kCcdReported = 1.0 + kCcdReportSlack;
constexpr double kCcdCullFactor = 1.02;
static_assert(kCcdCullFactor - 1.0 >
                  8.0 / ((1.0 - kCcdReportSlack) * (kCcdMaxIterations - 2)),
              "the cull's spare displacement must let the CCD's advances cover the step");
// repulsionTerms keeps a pair whose gap along its x0 normal is below the
// reach at x1, which moves from x0's distance by the relative displacement
// of the closest points: at most 2 (da + db) beyond the bound's own.
constexpr double kRepulsionCullFactor = 3.0;

}  // namespace

SelfCollision::SelfCollision(const Model& model, const Scene::SelfCollision& params)
    : enabled_(params.enabled),
      thickness_(params.thickness),
      friction_(params.friction),
      // The CCD only has to keep layers apart; the thickness is the
      // proximity stage's business. A tenth leaves room for round-off
      // without flagging layers that rest at the thickness.
      separation_(0.1 * params.thickness) {
  if (enabled_) mesh_ = buildCollisionMesh(model.numNodes(), model.triangles);
  // A step queries 6-7 times (filters, CCD rounds, re-solves, the measure)
  // with nodes moved by about the thickness between: a thickness of margin
  // answers ~90 % of them from kept pairs (fold demo: the filter 5.4 -> 2.5
  // ms a step; 4 thicknesses: fewer hashings, more pairs to filter, no gain).
  hash_.setReuseMargin(params.thickness);
}

std::array<int, 4> SelfCollision::nodesOf(int kind, int a, int b) const {
  if (kind == 0) {
    const Eigen::Vector3i& t = mesh_.triangles[b];
    return {a, t[0], t[1], t[2]};
  }
  return {mesh_.edges[a][0], mesh_.edges[a][1], mesh_.edges[b][0], mesh_.edges[b][1]};
}

void SelfCollision::gather(const std::array<int, 4>& nodes, const VecX& x,
                           std::array<Vec3, 4>* out) const {
  for (int k = 0; k < 4; ++k) (*out)[k] = x.segment<3>(3 * nodes[k]);
}

void SelfCollision::makePair(int kind, int a, int b, const std::array<Vec3, 4>& at,
                             Pair* pair) const {
  const std::array<int, 4> nodes = nodesOf(kind, a, b);
  std::copy(nodes.begin(), nodes.end(), pair->node);
  Vec3 geometric;
  if (kind == 0) {
    Vec3 bary;
    pointTriangleDistance(at[0], at[1], at[2], at[3], &bary);
    pair->w[0] = 1.0, pair->w[1] = -bary[0], pair->w[2] = -bary[1], pair->w[3] = -bary[2];
    geometric = (at[2] - at[1]).cross(at[3] - at[1]);
  } else {
    double s, t;
    edgeEdgeDistance(at[0], at[1], at[2], at[3], &s, &t);
    pair->w[0] = 1 - s, pair->w[1] = s, pair->w[2] = -(1 - t), pair->w[3] = -t;
    geometric = (at[1] - at[0]).cross(at[3] - at[2]);
  }
  Vec3 rel = Vec3::Zero();
  for (int k = 0; k < 4; ++k) rel += pair->w[k] * at[k];
  pair->distance = rel.norm();
  // Touching (or nearly): the closest points give no direction; the
  // primitives' own normal does, on the side the pair is on.
  if (pair->distance > 1e-12 * (1.0 + at[0].norm())) {
    pair->n = rel / pair->distance;
  } else if (geometric.squaredNorm() > 0.0) {
    pair->n = geometric.normalized();
    if (pair->n.dot(rel) < 0) pair->n = -pair->n;
  } else {
    pair->n = Vec3::UnitZ();
  }
  pair->target = pair->distance;
}

double SelfCollision::room(int i, const VecX& x1) const {
  const double left = away(i, x1.segment<3>(3 * i));
  // Round-off left by a push that took all of it is none (else the next
  // sweep would still count the node free, and converge slowly).
  return left > kRoomRoundOff * thickness_ ? left : 0.0;
}

Vec3 SelfCollision::nodeShare(int i, double w, const Vec3& dx, double room, bool wall) const {
  Vec3 d = (w * inv_mass_[i]) * dx;
  const double along = normal_[i].dot(d);
  if (wall) {
    d -= along * normal_[i];
  } else if (along < -room) {
    d -= (along + room) * normal_[i];
  }
  return d;
}

double SelfCollision::impulse(Pair& pair, const VecX& x0, VecX& x1, double* pin_work) const {
  Vec3 rel1 = Vec3::Zero();
  for (int k = 0; k < 4; ++k) rel1 += pair.w[k] * x1.segment<3>(3 * pair.node[k]);
  const double gap = pair.n.dot(rel1);
  // Nothing applied yet and nothing to restore: the common case, decided
  // before the rest is built (the folded towel at rest: most pairs a sweep).
  if (!(gap < pair.target) && pair.normal_impulse == 0.0) return 0.0;
  Vec3 rel0 = Vec3::Zero();
  // K: the relative position's displacement per impulse, sum w_k^2 / m_k
  // P_k, P_k the projector off node k's collider normal where the impulse
  // pushes the node into that surface and it has no room left there
  // (nodeShare), else the identity.
  Mat3 K = Mat3::Zero();
  double reach = 0.0;
  double rooms[4];
  bool walls[4];
  for (int k = 0; k < 4; ++k) {
    const int i = pair.node[k];
    rel0 += pair.w[k] * x0.segment<3>(3 * i);
    rooms[k] = room(i, x1);
    walls[k] = pair.w[k] * pair.n.dot(normal_[i]) < 0.0 && rooms[k] == 0.0;
    Mat3 P = Mat3::Identity();
    if (walls[k]) P -= normal_[i] * normal_[i].transpose();
    K += (pair.w[k] * pair.w[k] * inv_mass_[i]) * P;
    reach = std::max(reach, (std::abs(pair.w[k]) * inv_mass_[i] * P * pair.n).norm());
  }
  const double denom = pair.n.dot(K * pair.n);
  if (!(denom > 0.0)) return 0.0;
  // Where the movable nodes carry little of the closest points (the rest
  // pinned or held by a collider), closing the gap would throw them far
  // (the gap over their small weight): the impact zones handle that pair.
  if (reach > kMaxReach * denom) return 0.0;
  // Inelastic: the normal impulse brings the end gap up to the target and no
  // further (no bounce). Accumulated over the sweeps, it shrinks where other
  // pairs' impulses have since lifted this pair's nodes beyond the target
  // (else a resting layer was pushed above where it rested: a folded towel
  // gained 7e-5 J of potential energy a step, and every step was halved),
  // never below zero: it only pushes. Impulses are in displacement units:
  // node k moves by w_k / m_k P_k J, the relative position by K J.
  const double normal = std::max(pair.normal_impulse + (pair.target - gap) / denom, 0.0);
  Vec3 dx = (normal - pair.normal_impulse) * pair.n;
  pair.normal_impulse = normal;
  // Coulomb: a tangential impulse at most mu times the normal one, and no
  // larger than what stops the tangential relative displacement of the step
  // (never reversed).
  const Vec3 slip = rel1 - rel0 - pair.n * pair.n.dot(rel1 - rel0);
  const double slip_norm = slip.norm();
  if (friction_ > 0.0 && (slip_norm > 0.0 || !pair.friction_impulse.isZero(0.0))) {
    Vec3 stop = Vec3::Zero();
    if (slip_norm > 0.0) {
      const Vec3 dir = slip / slip_norm;
      const double stiff = dir.dot(K * dir);
      if (stiff > 0.0) stop = -(slip_norm / stiff) * dir;
    }
    Vec3 total = pair.friction_impulse + stop;
    const double cone = friction_ * normal;
    if (total.norm() > cone) total *= cone / total.norm();
    dx += total - pair.friction_impulse;
    pair.friction_impulse = total;
  }
  if (dx.isZero(0.0)) return 0.0;
  for (int k = 0; k < 4; ++k) {
    const int i = pair.node[k];
    x1.segment<3>(3 * i) += nodeShare(i, pair.w[k], dx, rooms[k], walls[k]);
    // A pin holds its node against the impulse's share w_k dx / h (momentum)
    // while moving at (x1 - x0) / h: it does work -w_k dx . (x1 - x0) / h^2.
    if (fixed_[i]) *pin_work -= pair.w[k] * dx.dot(x1.segment<3>(3 * i) - x0.segment<3>(3 * i));
  }
  return std::abs(pair.n.dot(K * dx));
}

void SelfCollision::notePushed(const Pair& pair) {
  PairConstraint c;
  for (int k = 0; k < 4; ++k) c.node[k] = pair.node[k], c.w[k] = pair.w[k];
  c.n = pair.n;
  pushed_.push_back(c);
}

int SelfCollision::find(int i) {
  while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
  return i;
}

void SelfCollision::detect(const VecX& x0, const VecX& x1, bool skip_zones) {
  hits_.clear();
  hash_.findPairs(mesh_, x0, x1, separation_, &pairs_,
                  DistanceCull{kCcdReported * separation_, kCcdCullFactor, false});
  std::array<Vec3, 4> a0, a1;
  auto test = [&](int kind, int a, int b) {
    const std::array<int, 4> nodes = nodesOf(kind, a, b);
    if (skip_zones) {
      // A pair inside one zone moves rigidly: its distance cannot change.
      const int root = find(nodes[0]);
      if (find(nodes[1]) == root && find(nodes[2]) == root && find(nodes[3]) == root) return;
    }
    gather(nodes, x0, &a0);
    gather(nodes, x1, &a1);
    // A pair that starts closer than the separation must keep half its start
    // distance: it may not close in, yet is not flagged for being close.
    const double d0 = kind == 0 ? pointTriangleDistance(a0[0], a0[1], a0[2], a0[3])
                                : edgeEdgeDistance(a0[0], a0[1], a0[2], a0[3]);
    const double sep = std::min(separation_, 0.5 * d0);
    const Impact hit = kind == 0 ? pointTriangleCcd(a0, a1, sep) : edgeEdgeCcd(a0, a1, sep);
    if (hit.hit) hits_.push_back(Hit{kind, a, b, hit.toi});
  };
  for (const auto& [node, tri] : pairs_.point_triangle) test(0, node, tri);
  for (const auto& [ea, eb] : pairs_.edge_edge) test(1, ea, eb);
}

bool SelfCollision::moveZones(const VecX& x0, VecX& x1, std::string* failure, int* moved,
                              double* pin_work) {
  const int n = mesh_.num_nodes;
  std::vector<std::vector<int>> zones;
  std::vector<int> zone_of(n, -1);
  for (int i = 0; i < n; ++i) {
    if (!in_zone_[i]) continue;
    const int root = find(i);
    if (zone_of[root] < 0) {
      zone_of[root] = static_cast<int>(zones.size());
      zones.emplace_back();
    }
    zones[zone_of[root]].push_back(i);
  }
  *moved = 0;
  for (const std::vector<int>& zone : zones) {
    *moved += static_cast<int>(zone.size());
    // Fixed (pinned) nodes have infinite mass: the zone can only follow them,
    // which is a rigid motion only if they all move by one translation.
    int first_fixed = -1;
    for (int i : zone) {
      if (!fixed_[i]) continue;
      if (first_fixed < 0) {
        first_fixed = i;
        continue;
      }
      const Vec3 d0 = x1.segment<3>(3 * first_fixed) - x0.segment<3>(3 * first_fixed);
      const Vec3 d = x1.segment<3>(3 * i) - x0.segment<3>(3 * i);
      if ((d - d0).norm() > 1e-12 * (1.0 + d0.norm())) {
        *failure = "self-collision: an impact zone of " + std::to_string(zone.size()) +
                   " nodes holds pinned nodes " + std::to_string(first_fixed) + " and " +
                   std::to_string(i) + " moving differently: it cannot move rigidly";
        return false;
      }
    }
    if (first_fixed >= 0) {
      // The pins drag the zone along: their impulse (the zone's momentum
      // change) times their velocity d / h is their work.
      const Vec3 d = x1.segment<3>(3 * first_fixed) - x0.segment<3>(3 * first_fixed);
      for (int i : zone) {
        const Vec3 to = x0.segment<3>(3 * i) + d;
        *pin_work += mass_[i] * (to - x1.segment<3>(3 * i)).dot(d);
        x1.segment<3>(3 * i) = to;
      }
      continue;
    }
    // Nodes held by a collider may not move along its normal: with one
    // normal shared by all of them (a table), the zone moves in the plane
    // (a translation across the normal, a rotation about it), which keeps
    // every node's height; with several, or a wedged node, it stays at x0
    // (a rigid motion too, and x0 was clear of the colliders).
    Vec3 axis = Vec3::Zero();
    bool frozen = false;
    for (int i : zone) {
      if (inv_mass_[i] == 0.0) frozen = true;  // wedged between two surfaces
      if (normal_[i].isZero(0.0) || guarded_[i]) continue;
      if (axis.isZero(0.0)) axis = normal_[i];
      else if ((normal_[i] - axis).norm() > 1e-9) frozen = true;
    }
    if (frozen) {
      for (int i : zone) x1.segment<3>(3 * i) = x0.segment<3>(3 * i);
      continue;
    }
    // Rigid motion with the zone's momentum (displacements stand for
    // velocities times h): centre of mass, then the angular velocity
    // I^-1 L about it, applied as an exact rotation so distances are kept.
    // With the true masses this is the mass-orthogonal projection of the
    // zone's motion on rigid motions: its kinetic energy does not grow.
    double mass = 0.0;
    Vec3 c0 = Vec3::Zero(), dc = Vec3::Zero();
    for (int i : zone) {
      const double m = mass_[i];
      mass += m;
      c0 += m * x0.segment<3>(3 * i);
      dc += m * (x1.segment<3>(3 * i) - x0.segment<3>(3 * i));
    }
    c0 /= mass;
    dc /= mass;
    Vec3 L = Vec3::Zero();
    Mat3 inertia = Mat3::Zero();
    for (int i : zone) {
      const double m = mass_[i];
      const Vec3 r = x0.segment<3>(3 * i) - c0;
      L += m * r.cross(x1.segment<3>(3 * i) - x0.segment<3>(3 * i) - dc);
      inertia += m * (r.squaredNorm() * Mat3::Identity() - r * r.transpose());
    }
    // A zone on a line (or one node) has a singular inertia: the
    // pseudo-inverse leaves the rotation about that line out.
    Vec3 omega;
    if (axis.isZero(0.0)) {
      omega = inertia.completeOrthogonalDecomposition().solve(L);
    } else {
      dc -= axis * axis.dot(dc);
      const double about = axis.dot(inertia * axis);
      omega = about > 0.0 ? Vec3(axis * (axis.dot(L) / about)) : Vec3::Zero();
    }
    const double angle = omega.norm();
    const Mat3 R = angle > 0.0 ? Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix()
                               : Mat3::Identity();
    bool into = false;  // a guarded node taken into its collider's band
    for (int i : zone) {
      const Vec3 to = c0 + dc + R * (x0.segment<3>(3 * i) - c0);
      into = into || (guarded_[i] && away(i, to) < 0.0);
    }
    for (int i : zone) {
      x1.segment<3>(3 * i) =
          into ? Vec3(x0.segment<3>(3 * i)) : Vec3(c0 + dc + R * (x0.segment<3>(3 * i) - c0));
    }
  }
  return true;
}

SelfCollisionResult SelfCollision::apply(const Model& model, double h, const VecX& x0,
                                         const SelfCollisionMasses& masses, VecX& x1, VecX& v) {
  SelfCollisionResult result;
  const int n = model.numNodes();

  inv_mass_.resize(n);
  mass_ = model.mass;
  normal_.assign(n, Vec3::Zero());
  room_.assign(n, 0.0);
  fixed_.assign(n, 0);
  for (int i = 0; i < n; ++i) inv_mass_[i] = model.mass[i] > 0.0 ? 1.0 / model.mass[i] : 0.0;
  for (size_t k = 0; k < masses.heavy.size(); ++k) {
    const int i = masses.heavy[k];
    const Vec3 normal = k < masses.heavy_normal.size() ? masses.heavy_normal[k] : Vec3::Zero();
    if (normal.isZero(0.0)) {
      inv_mass_[i] = 0.0;
    } else {
      normal_[i] = normal.normalized();
      if (k < masses.heavy_room.size()) room_[i] = masses.heavy_room[k];
    }
  }
  guarded_.assign(n, 0);
  for (size_t k = 0; k < masses.guarded.size(); ++k) {
    const int i = masses.guarded[k];
    normal_[i] = masses.guarded_normal[k].normalized();
    room_[i] = masses.guarded_room[k];
    guarded_[i] = 1;
  }
  for (int i : masses.fixed) inv_mass_[i] = 0.0, fixed_[i] = 1, normal_[i].setZero();
  x1_in_ = x1;
  pushed_.clear();
  in_zone_.assign(n, 0);

  // 1. Proximity at the end of the step.
  const double proximity = proximity_ * thickness_;
  hash_.findPairs(mesh_, x0, x1, proximity, &pairs_, DistanceCull{proximity, 1.0, false});
  result.candidates = static_cast<int>(pairs_.point_triangle.size() + pairs_.edge_edge.size());
  close_.clear();
  std::array<Vec3, 4> at, start;
  auto consider = [&](int kind, int a, int b) {
    Pair pair;
    gather(nodesOf(kind, a, b), x1, &at);
    makePair(kind, a, b, at, &pair);
    if (!(pair.distance < proximity)) return;
    gather(nodesOf(kind, a, b), x0, &start);
    Vec3 rel0 = Vec3::Zero();
    for (int k = 0; k < 4; ++k) rel0 += pair.w[k] * start[k];
    // Crossed during the step (x0 on the other side): CCD's business.
    const double g0 = pair.n.dot(rel0);
    if (!(g0 > 0.0)) return;
    // Stop the approach; restore up to the thickness, never push beyond
    // where the pair started (no energy put in).
    pair.target = std::min(proximity, g0);
    close_.push_back(pair);
  };
  for (const auto& [node, tri] : pairs_.point_triangle) consider(0, node, tri);
  for (const auto& [ea, eb] : pairs_.edge_edge) consider(1, ea, eb);
  double pin_work = 0.0;  // times h^2 until the end
  double zone_pin_work = 0.0;  // its zones' part
  // Projected Gauss-Seidel: pairs share nodes, so one pass over them
  // overshoots where a later pair lifts a node an earlier one already set
  // (by up to half its correction); the sweeps take that back.
  // Only the nodes of close pairs move: the sweeps' stop looks at those.
  sweep_nodes_.clear();
  for (const Pair& pair : close_) sweep_nodes_.insert(sweep_nodes_.end(), pair.node, pair.node + 4);
  std::sort(sweep_nodes_.begin(), sweep_nodes_.end());
  sweep_nodes_.erase(std::unique(sweep_nodes_.begin(), sweep_nodes_.end()), sweep_nodes_.end());
  sweep_start_.resize(sweep_nodes_.size());
  for (int sweep = 0; sweep < kProximitySweeps && !close_.empty(); ++sweep) {
    for (size_t k = 0; k < sweep_nodes_.size(); ++k) sweep_start_[k] = x1.segment<3>(3 * sweep_nodes_[k]);
    ++result.proximity_sweeps;
    for (Pair& pair : close_) {
      const double change = impulse(pair, x0, x1, &pin_work);
      if (sweep == 0) result.proximity_impulses += change > 0.0;
    }
    double largest = 0.0;
    for (size_t k = 0; k < sweep_nodes_.size(); ++k) {
      largest = std::max(largest, (x1.segment<3>(3 * sweep_nodes_[k]) - sweep_start_[k]).squaredNorm());
    }
    if (largest <= std::pow(kProximitySettled * thickness_, 2)) break;
  }
  for (const Pair& pair : close_) {
    if (pair.normal_impulse > 0.0) notePushed(pair);
  }

  // 2. CCD impulses: stop each colliding pair's normal approach at its time
  // of impact, with friction.
  bool clear = false;
  for (int round = 0; round < kCcdRounds && !clear; ++round) {
    detect(x0, x1, false);
    clear = hits_.empty();
    for (const Hit& hit : hits_) {
      const std::array<int, 4> nodes = nodesOf(hit.kind, hit.a, hit.b);
      gather(nodes, x0, &start);
      gather(nodes, x1, &at);
      for (int k = 0; k < 4; ++k) at[k] = start[k] + hit.toi * (at[k] - start[k]);
      Pair pair;
      makePair(hit.kind, hit.a, hit.b, at, &pair);
      // Stop the approach, no bounce: never beyond the start gap along n.
      Vec3 rel0 = Vec3::Zero();
      for (int k = 0; k < 4; ++k) rel0 += pair.w[k] * start[k];
      pair.target = std::min(pair.target, std::max(pair.n.dot(rel0), 0.0));
      const bool pushed = impulse(pair, x0, x1, &pin_work) > 0.0;
      result.ccd_impulses += pushed;
      if (pushed && pair.normal_impulse > 0.0) notePushed(pair);
    }
  }

  // 3. The fail-safe: impact zones until CCD finds nothing between zones.
  if (!clear) {
    parent_.resize(n);
    std::iota(parent_.begin(), parent_.end(), 0);
    in_zone_.assign(n, 0);
    for (int round = 0; round < kZoneRounds && !clear; ++round) {
      detect(x0, x1, true);
      clear = hits_.empty();
      if (clear) break;
      ++result.zone_rounds;
      for (const Hit& hit : hits_) {
        const std::array<int, 4> nodes = nodesOf(hit.kind, hit.a, hit.b);
        for (int k = 0; k < 4; ++k) {
          in_zone_[nodes[k]] = 1;
          parent_[find(nodes[k])] = find(nodes[0]);
        }
      }
      if (!moveZones(x0, x1, &result.failure, &result.zone_nodes, &zone_pin_work)) {
        result.ok = false;
        return result;
      }
    }
    if (!clear) {
      result.ok = false;
      result.failure = "self-collision: impact zones did not settle in " +
                       std::to_string(kZoneRounds) + " rounds";
      return result;
    }
  }

  for (int i = 0; i < n; ++i) {
    if (x1.segment<3>(3 * i) != x1_in_.segment<3>(3 * i)) {
      v.segment<3>(3 * i) += (x1.segment<3>(3 * i) - x1_in_.segment<3>(3 * i)) / h;
    }
  }
  result.pin_work = (pin_work + zone_pin_work) / (h * h);
  result.zone_pin_work = zone_pin_work / (h * h);
  return result;
}

void SelfCollision::repulsionTerms(const Model& model, const VecX& x0, const VecX& x1,
                                   double reach, double scale, SelfRepulsion* out) {
  out->clear();
  hash_.findPairs(mesh_, x0, x1, reach, &pairs_, DistanceCull{reach, kRepulsionCullFactor, false});
  // Every candidate first, then per node the nearest and one on its other
  // side (below): a choice that does not depend on the order the hash lists
  // pairs in. Chosen as they came (a side judged against whichever term held
  // a node's first slot then), a pair entering or leaving the list swapped
  // terms: the measured energy jumped by 5.6e-4 J between positions 1e-5 s
  // apart, and a pin driven through a folded cloth failed after 8 halvings.
  candidates_.clear();
  std::array<Vec3, 4> at;
  Pair pair;
  RepulsionTerm term;
  for (const auto& [node, tri] : pairs_.point_triangle) {
    gather(nodesOf(0, node, tri), x0, &at);
    makePair(0, node, tri, at, &pair);
    // Touching pairs have no closest-point direction to push along (the
    // filter's business).
    if (pair.distance <= 1e-6 * thickness_) continue;
    term.active = pair.distance < reach;
    double inverse_mass = 0.0;
    for (int k = 0; k < 4; ++k) {
      term.node[k] = pair.node[k];
      term.w[k] = pair.w[k];
      inverse_mass += pair.w[k] * pair.w[k] / model.mass[pair.node[k]];
    }
    term.n = pair.n;
    if (!term.active && !(term.gap(x1) < reach)) continue;
    term.stiffness = scale / inverse_mass;
    term.reach = reach;
    term.friction = friction_ * term.stiffness * std::max(reach - pair.distance, 0.0);
    candidates_.push_back({term, pair.distance, node});
  }
  // Nearest first (ties: the earlier in the hash's sorted list).
  node_terms_.assign(model.numNodes(), {-1, -1});
  for (int c = 0; c < static_cast<int>(candidates_.size()); ++c) {
    int& first = node_terms_[candidates_[c].node][0];
    if (first < 0 || candidates_[c].distance < candidates_[first].distance) first = c;
  }
  // Then, on the node's other side (a node between two layers), the term
  // holding the most energy, weighted by how clearly its normal opposes the
  // first's: a sign test flipped near 90 degrees (a node over a crumpled
  // vertex, two normals at 89.8 degrees) and switched a 4.8e-4 J term on
  // and off between positions 1e-5 s apart. With the weight a term fades
  // in as its normal turns; terms not yet within the reach (predicted
  // ones, no energy at x0): the nearest.
  auto side = [](double cosine) {  // 0 at cos >= -0.25, 1 at cos <= -0.75, C1 between
    const double t = std::clamp((-cosine - 0.25) / 0.5, 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
  };
  auto held = [&](const Candidate& c, double weight) {
    const double d = std::max(c.term.reach - c.distance, 0.0);
    return weight * c.term.stiffness * d * d;
  };
  side_weight_.assign(candidates_.size(), 0.0);
  for (int c = 0; c < static_cast<int>(candidates_.size()); ++c) {
    std::array<int, 2>& slots = node_terms_[candidates_[c].node];
    if (c == slots[0]) continue;
    const double w = side(candidates_[c].term.n.dot(candidates_[slots[0]].term.n));
    if (!(w > 0.0)) continue;
    side_weight_[c] = w;
    const int best = slots[1];
    if (best < 0) {
      slots[1] = c;
      continue;
    }
    const double mine = held(candidates_[c], w), theirs = held(candidates_[best], side_weight_[best]);
    if (mine > theirs || (mine == theirs && candidates_[c].distance < candidates_[best].distance)) slots[1] = c;
  }
  for (const std::array<int, 2>& slots : node_terms_) {
    if (slots[1] < 0) continue;
    Candidate& c = candidates_[slots[1]];
    c.term.stiffness *= side_weight_[slots[1]];
    c.term.friction *= side_weight_[slots[1]];
  }
  for (const std::array<int, 2>& slots : node_terms_) {
    for (int c : slots) {
      if (c >= 0) out->add(candidates_[c].term);
    }
  }
}

void SelfCollision::measure(const VecX& x, SelfCollisionResult* result) {
  // Wide enough for the pairs resting just beyond the thickness.
  const double wide = (1.0 + kRestingSlack) * thickness_;
  hash_.findPairs(mesh_, x, x, wide, &pairs_, DistanceCull{wide, 1.0});
  result->contacts = 0;
  // The pairs left out are farther than `wide`: their bound is "some
  // distance >= the thickness" as the pairs beyond it the hash gave were.
  result->min_distance = pairs_.culled_bound;
  std::array<Vec3, 4> at;
  auto visit = [&](int kind, int a, int b) {
    gather(nodesOf(kind, a, b), x, &at);
    const double d = kind == 0 ? pointTriangleDistance(at[0], at[1], at[2], at[3])
                               : edgeEdgeDistance(at[0], at[1], at[2], at[3]);
    result->min_distance = std::min(result->min_distance, d);
    result->contacts += d < (1.0 + kRestingSlack) * thickness_;
  };
  for (const auto& [node, tri] : pairs_.point_triangle) visit(0, node, tri);
  for (const auto& [ea, eb] : pairs_.edge_edge) visit(1, ea, eb);
}

}  // namespace cloth_sim
