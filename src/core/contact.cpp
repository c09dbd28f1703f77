#include "cloth_sim/contact.hpp"

#include <algorithm>
#include <cmath>

namespace cloth_sim {

namespace {

/// Cosine beyond which two contact normals count as the same direction (or
/// opposite): their planes then cannot both be kept as equalities.
constexpr double kParallel = 1.0 - 1e-6;

}  // namespace

void ContactSet::reindex(int num_nodes) {
  slot_.assign(num_nodes, -1);
  for (size_t k = 0; k < nodes_.size(); ++k) slot_[nodes_[k].node] = static_cast<int>(k);
}

int ContactSet::addNode(int node, bool sticking) {
  NodeContact c;
  c.node = node;
  c.sticking = sticking;
  nodes_.push_back(c);
  slot_[node] = static_cast<int>(nodes_.size()) - 1;
  return slot_[node];
}

bool ContactSet::touches(int slot, int collider) const {
  if (slot < 0) return false;
  const NodeContact& c = nodes_[slot];
  for (int q = 0; q < c.num_planes; ++q) {
    if (c.plane[q].collider == collider) return true;
  }
  return false;
}

std::vector<int> ContactSet::contactNodes() const {
  std::vector<int> out;
  out.reserve(nodes_.size());
  for (const NodeContact& c : nodes_) out.push_back(c.node);
  return out;
}

std::vector<Vec3> ContactSet::contactNormals() const {
  std::vector<Vec3> out;
  out.reserve(nodes_.size());
  for (const NodeContact& c : nodes_) {
    out.push_back(c.num_planes == 1 ? c.plane[0].normal : Vec3::Zero());
  }
  return out;
}

void ContactSet::setPlane(Plane& p, int collider, const SurfacePoint& local,
                          const CollidersOverStep& colliders, double h) const {
  const Pose& start = colliders.start[collider];
  const Pose& end = colliders.end[collider];
  p.collider = collider;
  p.local_point = local.point;
  p.local_normal = local.normal;
  p.normal = end.rotation * local.normal;
  const Vec3 point_end = end.toWorld(local.point);
  p.offset = p.normal.dot(point_end) + colliders.thickness;
  p.surface_velocity = (point_end - start.toWorld(local.point)) / h;
}

bool ContactSet::refresh(NodeContact& c, const CollidersOverStep& colliders) {
  const Plane& a = c.plane[0];
  Mat3 normal_part = a.normal * a.normal.transpose();
  c.surface_velocity = a.surface_velocity;
  c.mu = (*colliders.colliders)[a.collider].friction();
  if (c.num_planes == 2) {
    const Plane& b = c.plane[1];
    // Projector on span(n1, n2): N G^-1 N^T with G the Gram matrix.
    const double g = a.normal.dot(b.normal);
    const double det = 1.0 - g * g;
    if (!(det > 1.0 - kParallel * kParallel)) return false;
    normal_part = (a.normal * a.normal.transpose() + b.normal * b.normal.transpose() -
                   g * (a.normal * b.normal.transpose() + b.normal * a.normal.transpose())) /
                  det;
    c.surface_velocity = 0.5 * (a.surface_velocity + b.surface_velocity);
    c.mu = std::max(c.mu, (*colliders.colliders)[b.collider].friction());
  }
  c.tangent = Mat3::Identity() - normal_part;
  return true;
}

bool ContactSet::addPlane(NodeContact& c, int collider, const SurfacePoint& local,
                          const CollidersOverStep& colliders) {
  Plane p;
  setPlane(p, collider, local, colliders, h_);
  for (int k = 0; k < c.num_planes; ++k) {
    Plane& e = c.plane[k];
    const double cosine = e.normal.dot(p.normal);
    if (cosine > kParallel) {  // the same direction: the tighter plane
      if (p.offset > e.offset) e = p;
      return refresh(c, colliders);
    }
    if (cosine < -kParallel) {
      // Opposite planes n.x = d1 and -n.x = d2 leave room only if d1 + d2 <= 0.
      if (e.offset + p.offset > kPenetrationTolerance) {
        const auto& all = *colliders.colliders;
        failure_ = "node " + std::to_string(c.node) + " is squeezed between colliders '" +
                   all[e.collider].name() + "' and '" + all[p.collider].name() +
                   "' with no room for it (gap " + std::to_string(-(e.offset + p.offset) +
                   2.0 * colliders.thickness) + " m, thickness " +
                   std::to_string(colliders.thickness) + " m on each side)";
        return false;
      }
      e = p;  // pressed against the other one now
      return refresh(c, colliders);
    }
  }
  if (c.num_planes < kMaxPlanes) {
    c.plane[c.num_planes++] = p;
  } else {
    // A third surface: it replaces the plane that pushes least.
    const int weakest = c.plane[0].normal_force <= c.plane[1].normal_force ? 0 : 1;
    c.plane[weakest] = p;
  }
  return refresh(c, colliders);
}

double ContactSet::frictionCap(const NodeContact& c, const std::vector<Collider>& all) {
  double cap = 0.0;
  for (int q = 0; q < c.num_planes; ++q) {
    cap += all[c.plane[q].collider].friction() * std::max(c.plane[q].normal_force, 0.0);
  }
  return cap;
}

/// The step from here on under smoothed friction: every sticking node
/// slides with its cap from the last normal force (its slip not known yet:
/// the drag 2 / eps holds it until the solve moves it).
void ContactSet::smoothAll(const CollidersOverStep& colliders) {
  smoothing_ = motion_smoothing_;
  const auto& all = *colliders.colliders;
  for (NodeContact& c : nodes_) {
    if (!c.sticking) continue;
    c.sticking = false;
    c.slip.setZero();
    c.slip_speed = 0.0;
    c.friction = frictionCap(c, all);
  }
}

void ContactSet::begin(const CollidersOverStep& colliders, const ConstraintFilter& pins,
                       const VecX& x0, const VecX& v0, const Vec3& gravity, double h) {
  h_ = h;
  // Exact sticking with smoothing: the step starts exact (0) and is smoothed
  // below if a contact slides (smoothAll).
  motion_smoothing_ = colliders.exact_sticking ? colliders.friction_smoothing : 0.0;
  smoothing_ = colliders.exact_sticking ? 0.0 : colliders.friction_smoothing;
  passes_ = 0;
  // A node let go for pulling is predicted onto a surface again (below) by
  // its own velocity only, not by a step's fall h^2 g, until it touches one:
  // resting in a wrinkle just above a table, within that fall, it was
  // predicted at every step, pulled down onto the surface against its
  // springs and let go, a contact pass more a step (drop64: 85 nodes a step).
  if (pulled_.size() != static_cast<size_t>(pins.numNodes())) {
    pulled_.assign(static_cast<size_t>(pins.numNodes()), 0);
  }
  for (const int i : released_) pulled_[static_cast<size_t>(i)] = 1;
  released_.clear();
  failure_.clear();
  const auto& all = *colliders.colliders;
  const double thickness = colliders.thickness;
  // Last step's contacts, re-linearised at x0 while they still touch.
  std::vector<NodeContact> kept;
  kept.reserve(nodes_.size());
  for (NodeContact c : nodes_) {
    if (pins.isEliminated(c.node)) continue;
    const Vec3 x = x0.segment<3>(3 * c.node);
    const double reach = 1e-6 + h * v0.segment<3>(3 * c.node).norm() + h * h * gravity.norm();
    int planes = 0;
    for (int k = 0; k < c.num_planes; ++k) {
      const int id = c.plane[k].collider;
      const SurfacePoint s = all[id].closestLocal(colliders.start[id].toLocal(x));
      if (s.distance - thickness > reach) continue;
      const double force = c.plane[k].normal_force;
      setPlane(c.plane[planes], id, s, colliders, h);
      c.plane[planes++].normal_force = force;
    }
    c.num_planes = planes;
    c.held = false;
    c.fresh = false;
    c.flips = 0;
    if (planes == 0) continue;
    if (!refresh(c, colliders)) {
      c.num_planes = 1;
      refresh(c, colliders);
    }
    kept.push_back(c);
  }
  nodes_.swap(kept);
  reindex(pins.numNodes());
  if (motion_smoothing_ > 0.0) {
    // Exact at rest, smoothed in motion: a node that ended the last step
    // slipping slower than the smoothing speed sticks again; one still
    // sliding smooths the whole step.
    bool moving = false;
    for (NodeContact& c : nodes_) {
      if (c.sticking || c.mu <= 0.0) continue;
      if (c.slip_speed < motion_smoothing_) {
        c.sticking = true;
      } else {
        moving = true;
      }
    }
    if (moving) smoothAll(colliders);
  }
  // New contacts on the predicted path, of the nodes the broad phase keeps.
  broad_.buildPredicted(colliders, x0, v0, gravity, h);
  queries_ = 0;
  for (const int i : broad_.candidates()) {
    if (pins.isEliminated(i)) continue;
    const Vec3 p0 = x0.segment<3>(3 * i);
    const bool pulled = pulled_[static_cast<size_t>(i)];
    const Vec3 p1 = p0 + h * v0.segment<3>(3 * i) + (pulled ? 0.0 : h * h) * gravity;
    for (size_t k = 0; k < all.size(); ++k) {
      const int id = static_cast<int>(k);
      if (!broad_.mayTouch(i, id) || touches(slot_[i], id)) continue;
      ++queries_;
      const auto hit = firstContact(all[k], colliders.start[k], colliders.end[k], p0, p1,
                                    thickness, kPenetrationTolerance);
      if (!hit) continue;
      pulled_[static_cast<size_t>(i)] = 0;
      const int slot = slot_[i] >= 0 ? slot_[i] : addNode(i, sticksOnArrival(all[k].friction()));
      if (!addPlane(nodes_[slot], id, hit->local, colliders)) {
        // No room on the prediction: keep the first plane, update() decides.
        failure_.clear();
      }
    }
  }
}

void ContactSet::constrain(ConstraintFilter& filter) const {
  for (const NodeContact& c : nodes_) {
    filter.project(c.node, c.sticking ? Mat3::Zero() : c.tangent);
  }
}

void ContactSet::constrainNormals(ConstraintFilter& filter) const {
  for (const NodeContact& c : nodes_) filter.project(c.node, c.tangent);
}

Vec3 ContactSet::normalVelocity(const NodeContact& c, double t0, double t1) {
  const Plane& p = c.plane[0];
  if (c.num_planes == 1) return t0 * p.normal;
  const Plane& q = c.plane[1];
  const double g = p.normal.dot(q.normal);
  const double det = 1.0 - g * g;
  return ((t0 - g * t1) / det) * p.normal + ((t1 - g * t0) / det) * q.normal;
}

Vec3 ContactSet::prescribed(size_t k, const VecX& ax, double bh) const {
  const NodeContact& c = nodes_[k];
  const Vec3 a = ax.segment<3>(3 * c.node);
  // Normal speeds that reach each plane.
  const double t0 = (c.plane[0].offset - c.plane[0].normal.dot(a)) / bh;
  const double t1 = c.num_planes > 1 ? (c.plane[1].offset - c.plane[1].normal.dot(a)) / bh : 0.0;
  Vec3 w = normalVelocity(c, t0, t1);
  if (c.sticking) w += c.tangent * c.surface_velocity;
  return w;
}

void ContactSet::prescribe(const VecX& ax, double bh, VecX& v1) const {
  for (size_t k = 0; k < nodes_.size(); ++k) {
    const NodeContact& c = nodes_[k];
    const Vec3 w = prescribed(k, ax, bh);
    Vec3 v = v1.segment<3>(3 * c.node);
    v1.segment<3>(3 * c.node) = (c.sticking ? Vec3::Zero() : Vec3(c.tangent * v)) + w;
  }
}

bool ContactSet::alignWithSurfaces(double h, const VecX& x1, VecX& v1, VecX& x_prev,
                                   VecX& v_prev) const {
  bool landed = false;
  for (const NodeContact& c : nodes_) {
    if (!c.fresh) continue;  // aligned when it landed; its history is smooth since
    landed = true;
    // The surfaces' own normal speeds.
    const Plane& p = c.plane[0];
    const Plane& q = c.plane[1];
    Vec3 u = normalVelocity(c, p.normal.dot(p.surface_velocity),
                            c.num_planes > 1 ? q.normal.dot(q.surface_velocity) : 0.0);
    if (c.sticking) u += c.tangent * c.surface_velocity;
    const Mat3 held = c.sticking ? Mat3::Identity() : Mat3(Mat3::Identity() - c.tangent);
    const int i = 3 * c.node;
    const Vec3 x = x1.segment<3>(i);
    v1.segment<3>(i) += held * (u - v1.segment<3>(i));
    v_prev.segment<3>(i) += held * (u - v_prev.segment<3>(i));
    x_prev.segment<3>(i) += held * (x - h * u - x_prev.segment<3>(i));
  }
  return landed;
}

bool ContactSet::prescribeChange(const VecX& ax, double bh, const VecX& v0, VecX& c) const {
  bool any = false;
  for (size_t k = 0; k < nodes_.size(); ++k) {
    const NodeContact& n = nodes_[k];
    const Vec3 v = v0.segment<3>(3 * n.node);
    const Vec3 change = prescribed(k, ax, bh) - (n.sticking ? v : Vec3(v - n.tangent * v));
    c.segment<3>(3 * n.node) = change;
    any = any || change.squaredNorm() > 0.0;
  }
  return any;
}

namespace {

/// Slip velocity of a node in the tangent space.
Vec3 slipOf(const Mat3& tangent, const Vec3& v, const Vec3& surface) {
  return tangent * (v - surface);
}

}  // namespace

double ContactSet::smoothedSign(double s, double eps) {
  if (s >= eps) return 1.0;
  const double y = s / eps;
  return y * (2.0 - y);
}

ContactSet::FrictionLaw ContactSet::law(const NodeContact& c, const Vec3& s) const {
  FrictionLaw l;
  const bool here = smoothedAtIterate();
  l.speed = here ? s.norm() : c.slip_speed;
  l.dir = here ? (l.speed > 0.0 ? Vec3(s / l.speed) : Vec3::Zero()) : c.slip;
  if (smoothing_ > 0.0) {
    // f1 and its slope at |s0|; at 0 both ways are the drag 2 / eps.
    l.base = smoothedSign(l.speed, smoothing_);
    const double drag = l.speed > 0.0 ? l.base / l.speed : 2.0 / smoothing_;
    l.turn = c.friction * drag;
    // Along the slip f1' (the exact Hessian), or in a descent the drag
    // (FrictionSolve).
    if (friction_solve_ == FrictionSolve::Descent) {
      l.along = drag;
    } else {
      l.along = l.speed < smoothing_ ? 2.0 * (1.0 - l.speed / smoothing_) / smoothing_ : 0.0;
    }
  } else if (l.speed > 0.0) {
    l.turn = c.friction / std::max(l.speed, kStopSpeed);
  }
  return l;
}

Vec3 ContactSet::linearFriction(const NodeContact& c, const FrictionLaw& l, const Vec3& s) {
  const double along = l.dir.dot(s);
  // (Exact Coulomb's terms as they always were: base 1 and along 0 add zeros.)
  Vec3 force = -c.friction * ((l.base + l.along * (along - l.speed)) * l.dir);
  if (l.turn > 0.0) force -= l.turn * (s - l.dir * along);
  return force;
}

void ContactSet::addFriction(VecX& f, double scale, const VecX& v) const {
  for (const NodeContact& c : nodes_) {
    if (c.sticking || c.friction <= 0.0) continue;
    const Vec3 s = slipOf(c.tangent, v.segment<3>(3 * c.node), c.surface_velocity);
    f.segment<3>(3 * c.node) += scale * linearFriction(c, law(c, s), s);
  }
}

void ContactSet::addFrictionJacobian(SystemMatrix& A, double scale, const VecX& v) const {
  for (const NodeContact& c : nodes_) {
    if (c.sticking || c.friction <= 0.0) continue;
    const FrictionLaw l =
        law(c, slipOf(c.tangent, v.segment<3>(3 * c.node), c.surface_velocity));
    if (l.along == 0.0 && l.turn == 0.0) continue;
    const Mat3 along = l.dir * l.dir.transpose();
    A.addNodeBlock(c.node, (scale * c.friction * l.along) * along +
                               (scale * l.turn) * (c.tangent - along));
  }
}

double ContactSet::frictionPotential(const VecX& v) const {
  double sum = 0.0;
  for (const NodeContact& c : nodes_) {
    if (c.sticking || c.friction <= 0.0) continue;
    const Vec3 s = slipOf(c.tangent, v.segment<3>(3 * c.node), c.surface_velocity);
    if (smoothedAtIterate()) {  // f0, f0' = f1
      const double y = s.norm(), eps = smoothing_;
      sum += c.friction * (y >= eps ? y - eps / 3.0 : y * y / eps - y * y * y / (3.0 * eps * eps));
      continue;
    }
    const FrictionLaw l = law(c, s);
    const double along = l.dir.dot(s);
    const Vec3 turn = s - l.dir * along;
    sum += c.friction * ((l.base - l.along * l.speed) * along + 0.5 * l.along * along * along) +
           0.5 * l.turn * turn.squaredNorm();
  }
  return sum;
}

ContactCheck ContactSet::update(const CollidersOverStep& colliders, const ConstraintFilter& pins,
                                const std::vector<double>& mass, const VecX& x0,
                                const VecX& x1, const VecX& v1, const VecX& reaction,
                                double bh, const Vec3& gravity, double solve_tolerance) {
  failure_.clear();
  bool changed = false;
  const bool refine_friction = ++passes_ <= kFrictionPasses;
  bool smooth_now = false;
  changes_ = ContactChanges();
  held_pulls_ = 0;
  const auto& all = *colliders.colliders;
  const double thickness = colliders.thickness;

  // Coulomb's law on every contact: push only, stick inside the cone.
  for (size_t k = 0; k < nodes_.size();) {
    NodeContact& c = nodes_[k];
    const Vec3 force = reaction.segment<3>(3 * c.node) / bh;
    double lambda[kMaxPlanes] = {0.0, 0.0};
    if (c.num_planes == 1) {
      lambda[0] = c.plane[0].normal.dot(force);
    } else {
      const Vec3& n0 = c.plane[0].normal;
      const Vec3& n1 = c.plane[1].normal;
      const double g = n0.dot(n1), det = 1.0 - g * g;
      const double f0 = n0.dot(force), f1 = n1.dot(force);
      lambda[0] = (f0 - g * f1) / det;
      lambda[1] = (f1 - g * f0) / det;
    }
    int weakest = 0;
    for (int q = 0; q < c.num_planes; ++q) {
      c.plane[q].normal_force = lambda[q];
      if (lambda[q] < lambda[weakest]) weakest = q;
    }
    const double pull_tolerance =
        std::max(1e-9, solve_tolerance) * (force.norm() + mass[c.node] * gravity.norm());
    const double cap = frictionCap(c, all);
    const Vec3 tangential = c.tangent * force;
    const double needed = tangential.norm();
    // A sticking node outside the friction cone slides first: its normal
    // force while held in place says little about the sliding one (a node
    // pulled sideways off a curved surface pulls on a sticking contact, not
    // on a sliding one). Only a sliding node that pulls lets go.
    // A node on the cone's boundary can flip between stick and slip at every
    // pass (sliding, friction stops it; sticking, it needs a hair more than
    // mu f_n): after two flips in a step it stays stuck for the step.
    // (Beyond the cone by more than the solve's own noise: a loose solve's
    // tangential forces are only known to its tolerance.)
    const bool outside = c.sticking && needed > cap * (1.0 + std::max(1e-9, solve_tolerance));
    // Exact at rest, smoothed in motion: a sticking node outside its cone
    // smooths the whole step (after this loop), so the next solve finds
    // every node that slides. Switched node by node, each pass freed only
    // the ring of sticking nodes the last one loaded, and the refining
    // passes ran out: a cloth dragged across a table by a corner (contact
    // hard case c3) strained to 0.52-0.92 against held neighbours, where
    // the smoothed step strains 0.03-0.05.
    if (motion_smoothing_ > 0.0 && smoothing_ <= 0.0 && outside) {
      smooth_now = true;
    } else if (refine_friction && outside && c.flips < 2) {
      c.sticking = false;
      ++c.flips;
      ++changes_.slid;
      c.slip = -tangential / needed;
      c.slip_speed = 0.0;
      c.friction = cap;
      changed = true;
      ++k;
      continue;
    }
    // A node back after its release this step is kept (no cycling), and
    // may then pull. On the last retry of a step that gained energy (at the
    // deepest halving) such a node slides: where it pulls its friction cone
    // is empty. Kept sticking, it pulled a stiffened cloth's node onto a
    // table's edge against its springs (contact hard case c4 at newton, dt
    // 0.1: 483 N, 1.5e-3 J gained at every halving). Only then: sliding in
    // every step, the fold, the heap and a drop onto a rod rested less well
    // (Simulation::stepWithRecovery).
    if (c.held && c.sticking && lambda[weakest] < -pull_tolerance) {
      ++held_pulls_;
      if (slide_held_pulls_) {
        c.sticking = false;
        ++changes_.slid;
        c.slip = needed > 0.0 ? Vec3(-tangential / needed) : Vec3::Zero();
        c.slip_speed = 0.0;
        c.friction = 0.0;
        changed = true;
        ++k;
        continue;
      }
    }
    if (!c.held && lambda[weakest] < -pull_tolerance) {  // adhesion: let go
      changed = true;
      ++changes_.released;
      released_.push_back(c.node);
      if (c.num_planes == 1) {
        nodes_.erase(nodes_.begin() + static_cast<long>(k));
        reindex(static_cast<int>(slot_.size()));
        continue;
      }
      c.plane[weakest] = c.plane[1 - weakest];
      c.num_planes = 1;
      refresh(c, colliders);
      ++k;
      continue;
    }
    if (smoothing_ > 0.0 && (cap > 0.0 || c.friction > 0.0)) {
      // Smoothed: no state to switch. Solved again (in the refining passes)
      // while the linearised law at the answer's slip is off f1's by more
      // than the lag; the law is re-linearised at every pass, and the next
      // step starts from the last one (IPC's lagged friction).
      const Vec3 slip = slipOf(c.tangent, v1.segment<3>(3 * c.node), c.surface_velocity);
      const double speed = slip.norm();
      const Vec3 exact = speed > 0.0 ? Vec3(-cap * smoothedSign(speed, smoothing_) / speed * slip)
                                     : Vec3::Zero();
      const bool lagging = (exact - linearFriction(c, law(c, slip), slip)).norm() >
                           kFrictionLag * std::max(cap, c.friction);
      if (refine_friction && lagging) {
        changed = true;
        ++changes_.friction;
      }
      c.friction = lagging && c.friction > 0.0 && cap > 0.0 ? 0.5 * (cap + c.friction) : cap;
      if (speed > 0.0) c.slip = slip / speed;
      c.slip_speed = speed;
    } else if (refine_friction && !c.sticking && (cap > 0.0 || c.friction > 0.0)) {
      const Vec3 slip = slipOf(c.tangent, v1.segment<3>(3 * c.node), c.surface_velocity);
      const double speed = slip.norm();
      // Friction would reverse the slip: stick. (A slow slip the same way is
      // a slide: sticking it would need more than the cone allows.) The
      // first slide after sticking has no slip to reverse yet: its direction
      // was only guessed from the sticking force.
      if (cap > 0.0 && c.slip_speed > 0.0 && !(slip.dot(c.slip) > 0.0)) {
        c.sticking = true;
        ++c.flips;
        ++changes_.stuck;
        changed = true;
      } else {
        const Vec3 direction = speed > 0.0 ? Vec3(slip / speed) : c.slip;
        // (A turn that moves the node by under kSlipTolerance over the step
        // does not count: a slow node's direction converges slowly.)
        const double turn = (direction - c.slip).norm();
        const bool turned = turn > kDirectionLag &&
                            turn * speed * h_ > kSlipTolerance;
        const bool lagging = std::abs(cap - c.friction) > kFrictionLag * std::max(cap, c.friction);
        if (refine_friction && (lagging || turned)) {
          changed = true;
          ++changes_.friction;
        }
        // Averaged after the first update: the normal force of the whole
        // cloth can swing between passes when every friction follows it.
        c.friction = lagging && c.friction > 0.0 && cap > 0.0 ? 0.5 * (cap + c.friction) : cap;
        c.slip = direction;
        c.slip_speed = speed;
      }
    }
    ++k;
  }

  if (smooth_now) {
    smoothAll(colliders);
    changes_.smoothed = true;
    ++changes_.slid;
    changed = true;
  }

  // Every node the broad phase keeps against its colliders: the swept path
  // for new contacts, the end position for the penetration measure (a node
  // it drops ends beyond the thickness: no penetration, no contact).
  max_penetration_ = 0.0;
  broad_.build(colliders, x0, x1);
  queries_ = 0;
  for (const int i : broad_.candidates()) {
    const Vec3 p0 = x0.segment<3>(3 * i), p1 = x1.segment<3>(3 * i);
    for (size_t k = 0; k < all.size(); ++k) {
      if (!broad_.mayTouch(i, static_cast<int>(k))) continue;
      ++queries_;
      const double depth = thickness - all[k].closest(p1, colliders.end[k]).distance;
      max_penetration_ = std::max(max_penetration_, depth);
      if (pins.isEliminated(i)) continue;
      const bool own = touches(slot_[i], static_cast<int>(k));
      // A node on a contact plane is outside that (convex) collider.
      if (own && depth <= kPenetrationTolerance) continue;
      std::optional<SweptHit> hit;
      if (own) {
        hit = SweptHit{1.0, all[k].closestLocal(colliders.end[k].toLocal(p1))};
      } else {
        hit = firstContact(all[k], colliders.start[k], colliders.end[k], p0, p1, thickness,
                           kPenetrationTolerance);
      }
      if (!hit) continue;
      ++changes_.added;
      pulled_[static_cast<size_t>(i)] = 0;
      const int s = slot_[i] >= 0 ? slot_[i] : addNode(i, sticksOnArrival(all[k].friction()));
      NodeContact& c = nodes_[s];
      if (std::find(released_.begin(), released_.end(), i) != released_.end()) c.held = true;
      if (own) {  // re-linearise its own plane where it ended
        for (int q = 0; q < c.num_planes; ++q) {
          if (c.plane[q].collider == static_cast<int>(k)) {
            setPlane(c.plane[q], static_cast<int>(k), hit->local, colliders, h_);
          }
        }
        refresh(c, colliders);
      } else if (!addPlane(c, static_cast<int>(k), hit->local, colliders)) {
        return ContactCheck::Failed;
      }
      changed = true;
    }
  }
  return changed ? ContactCheck::Changed : ContactCheck::Consistent;
}

double ContactSet::normalForce() const {
  double sum = 0.0;
  for (const NodeContact& c : nodes_) {
    for (int q = 0; q < c.num_planes; ++q) sum += std::max(c.plane[q].normal_force, 0.0);
  }
  return sum;
}

double ContactSet::work(const VecX& x0, const VecX& x1, const VecX& reaction, double bh) const {
  double w = 0.0;
  for (const NodeContact& c : nodes_) {
    const int i = c.node;
    w += reaction.segment<3>(3 * i).dot(x1.segment<3>(3 * i) - x0.segment<3>(3 * i)) / bh;
  }
  return w;
}

}  // namespace cloth_sim
