// Which nodes the self-collision filter may move, and how: the link between
// the filter and the colliders (self_collision.hpp, SelfCollisionMasses).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "cloth_sim/collider.hpp"
#include "cloth_sim/contact.hpp"
#include "cloth_sim/self_collision.hpp"

namespace cloth_sim {

void selfCollisionMasses(const std::vector<int>& pinned, const ContactSet& contacts,
                         const CollidersOverStep& colliders, const VecX& x0, const VecX& x1,
                         double reach, SelfCollisionMasses* out) {
  out->fixed = pinned;
  out->heavy.clear();
  out->heavy_normal.clear();
  out->heavy_room.clear();
  out->guarded.clear();
  out->guarded_normal.clear();
  out->guarded_room.clear();
  if (colliders.empty()) return;
  const int n = static_cast<int>(x1.size() / 3);
  // Per node: the normal of the one surface it is near, or zero when near
  // two (wedged: it may not move at all).
  std::vector<int> near(n, 0);
  std::vector<Vec3> normal(n, Vec3::Zero());
  std::vector<double> room(n, 0.0);
  // The nearest collider of every node, for the nodes not held.
  std::vector<double> nearest(n, std::numeric_limits<double>::infinity());
  std::vector<Vec3> nearest_normal(n, Vec3::Zero());
  auto hold = [&](int i, const Vec3& nrm) {
    if (near[i] == 0) {
      normal[i] = nrm;
    } else if ((normal[i] - nrm).norm() > 1e-9) {
      normal[i].setZero();
    }
    ++near[i];
  };
  const std::vector<int> held = contacts.contactNodes();
  const std::vector<Vec3> held_normal = contacts.contactNormals();
  for (size_t k = 0; k < held.size(); ++k) {
    if (held_normal[k].isZero(0.0)) near[held[k]] = 2;  // wedged already
    else hold(held[k], held_normal[k]);
  }
  // Not only the nodes the contact solve holds: a node just above a surface
  // is as easily pushed through it by an impulse.
  for (size_t c = 0; c < colliders.colliders->size(); ++c) {
    const Collider& collider = (*colliders.colliders)[c];
    for (int i = 0; i < n; ++i) {
      if (near[i] >= 2) continue;
      const SurfacePoint sp = collider.closest(x1.segment<3>(3 * i), colliders.end[c]);
      if (sp.distance < nearest[i]) nearest[i] = sp.distance, nearest_normal[i] = sp.normal;
      if (!(sp.distance < colliders.thickness + reach)) continue;
      hold(i, sp.normal);
      // Measured against the surface, which may have moved over the step.
      const double d0 = collider.closest(x0.segment<3>(3 * i), colliders.start[c]).distance;
      room[i] = std::max(sp.distance - d0, 0.0);
    }
  }
  for (int i = 0; i < n; ++i) {
    if (near[i] == 0) {
      if (!std::isfinite(nearest[i]) || nearest_normal[i].isZero(0.0)) continue;
      out->guarded.push_back(i);
      out->guarded_normal.push_back(nearest_normal[i]);
      out->guarded_room.push_back(std::max(nearest[i] - colliders.thickness, 0.0));
      continue;
    }
    out->heavy.push_back(i);
    out->heavy_normal.push_back(near[i] >= 2 ? Vec3::Zero() : normal[i]);
    out->heavy_room.push_back(room[i]);
  }
}

int pushedIntoCollider(const CollidersOverStep& colliders, const VecX& x0, const VecX& before,
                       const VecX& after, std::string* which) {
  if (colliders.empty()) return -1;
  const int n = static_cast<int>(after.size() / 3);
  for (int i = 0; i < n; ++i) {
    if (after.segment<3>(3 * i) == before.segment<3>(3 * i)) continue;
    for (size_t c = 0; c < colliders.colliders->size(); ++c) {
      const Collider& collider = (*colliders.colliders)[c];
      const double d1 = collider.closest(after.segment<3>(3 * i), colliders.end[c]).distance;
      if (d1 >= colliders.thickness) continue;
      // Deeper than the solve left it (round-off aside), and than the step
      // started: the filter may push a node back towards the surface by
      // what it moved away in the step (SelfCollision::room), which for a
      // node that started on the band ends it there.
      const double d0 = std::min(
          collider.closest(before.segment<3>(3 * i), colliders.end[c]).distance,
          collider.closest(x0.segment<3>(3 * i), colliders.start[c]).distance);
      if (d1 < d0 - 1e-9 * (1.0 + colliders.thickness)) {
        *which = "self-collision pushed node " + std::to_string(i) + " into collider '" +
                 collider.name() + "'";
        return i;
      }
    }
  }
  return -1;
}

}  // namespace cloth_sim
