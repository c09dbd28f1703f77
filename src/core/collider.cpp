#include "cloth_sim/collider.hpp"

#include <algorithm>
#include <cmath>

namespace cloth_sim {

Mat3 rotationFromRpy(const Vec3& rpy) {
  return (Eigen::AngleAxisd(rpy[2], Vec3::UnitZ()) * Eigen::AngleAxisd(rpy[1], Vec3::UnitY()) *
          Eigen::AngleAxisd(rpy[0], Vec3::UnitX()))
      .toRotationMatrix();
}

Collider Collider::fromParams(const ColliderParams& p, double default_friction) {
  Collider c;
  c.type_ = p.type;
  c.name_ = p.name;
  c.frame_ = p.frame;
  c.friction_ = p.friction.value_or(default_friction);
  switch (p.type) {
    case Type::Plane:
      c.normal_ = p.normal.normalized();
      c.scene_pose_.translation = p.point;
      break;
    case Type::Sphere:
      c.radius_ = p.radius;
      c.scene_pose_.translation = p.center;
      break;
    case Type::Box:
      c.half_extents_ = p.half_extents;
      c.scene_pose_ = Pose{rotationFromRpy(p.rpy), p.center};
      break;
    case Type::Capsule:
      c.radius_ = p.radius;
      c.segment_ = p.b - p.a;
      c.scene_pose_.translation = p.a;
      break;
  }
  return c;
}

namespace {

/// A unit vector perpendicular to a (or +z if a is zero).
Vec3 anyPerpendicular(const Vec3& a) {
  if (a.squaredNorm() == 0.0) return Vec3::UnitZ();
  const Vec3 axis = std::abs(a[0]) < 0.9 * a.norm() ? Vec3::UnitX() : Vec3::UnitY();
  return a.cross(axis).normalized();
}

SurfacePoint aroundPoint(const Vec3& p, const Vec3& center, double radius, const Vec3& axis) {
  const Vec3 d = p - center;
  const double len = d.norm();
  SurfacePoint s;
  s.normal = len > 0.0 ? Vec3(d / len) : anyPerpendicular(axis);
  s.distance = len - radius;
  s.point = center + radius * s.normal;
  return s;
}

}  // namespace

SurfacePoint Collider::closestLocal(const Vec3& p) const {
  switch (type_) {
    case Type::Plane: {
      SurfacePoint s;
      s.distance = normal_.dot(p);
      s.point = p - s.distance * normal_;
      s.normal = normal_;
      return s;
    }
    case Type::Sphere:
      return aroundPoint(p, Vec3::Zero(), radius_, Vec3::Zero());
    case Type::Capsule: {
      const double len_sq = segment_.squaredNorm();
      const double t = len_sq > 0.0 ? std::clamp(p.dot(segment_) / len_sq, 0.0, 1.0) : 0.0;
      return aroundPoint(p, t * segment_, radius_, segment_);
    }
    case Type::Box: {
      const Vec3 q = p.cwiseAbs() - half_extents_;
      SurfacePoint s;
      if (q.maxCoeff() > 0.0) {  // outside: the clamped point is the closest
        s.point = p.cwiseMax(-half_extents_).cwiseMin(half_extents_);
        const Vec3 d = p - s.point;
        s.distance = d.norm();
        s.normal = d / s.distance;
        return s;
      }
      int k = 0;  // inside or on it: the nearest face
      q.maxCoeff(&k);
      const double side = p[k] < 0.0 ? -1.0 : 1.0;
      s.distance = q[k];
      s.point = p;
      s.point[k] = side * half_extents_[k];
      s.normal = Vec3::Zero();
      s.normal[k] = side;
      return s;
    }
  }
  return {};
}

SurfacePoint Collider::closest(const Vec3& p, const Pose& pose) const {
  SurfacePoint s = closestLocal(pose.toLocal(p));
  s.point = pose.toWorld(s.point);
  s.normal = pose.rotation * s.normal;
  return s;
}

std::optional<SweptHit> firstContact(const Collider& collider, const Pose& pose0,
                                     const Pose& pose1, const Vec3& p0, const Vec3& p1,
                                     double thickness, double tolerance) {
  const Vec3 a = pose0.toLocal(p0), b = pose1.toLocal(p1);
  const double d0 = collider.closestLocal(a).distance;
  if (d0 < thickness - tolerance) return SweptHit{0.0, collider.closestLocal(a)};
  const double d1 = collider.closestLocal(b).distance;
  const double length = (b - a).norm();
  // Distance is 1-Lipschitz along the path: nowhere below (d0 + d1 - L) / 2.
  if (d1 >= thickness - tolerance && 0.5 * (d0 + d1 - length) >= thickness - tolerance) {
    return std::nullopt;
  }
  auto dist = [&](double t) { return collider.closestLocal(a + t * (b - a)).distance; };
  double hi = 1.0;  // a time known to be within thickness, if any
  if (d1 >= thickness - tolerance) {
    // Golden-section search for the convex distance's minimum on [0, 1].
    const double g = 0.5 * (std::sqrt(5.0) - 1.0);
    double lo = 0.0, up = 1.0;
    double x1 = up - g * (up - lo), x2 = lo + g * (up - lo);
    double f1 = dist(x1), f2 = dist(x2);
    while (up - lo > 1e-12 && std::min(f1, f2) >= thickness - tolerance) {
      if (f1 < f2) {
        up = x2;
        x2 = x1;
        f2 = f1;
        x1 = up - g * (up - lo);
        f1 = dist(x1);
      } else {
        lo = x1;
        x1 = x2;
        f1 = f2;
        x2 = lo + g * (up - lo);
        f2 = dist(x2);
      }
    }
    if (std::min(f1, f2) >= thickness - tolerance) return std::nullopt;
    hi = f1 < f2 ? x1 : x2;
  }
  // Bisection for the first time within thickness on [0, hi] (the distance
  // falls monotonically there: convex, above at 0, below at hi).
  double lo = 0.0;
  for (int it = 0; it < 60 && hi - lo > 1e-14; ++it) {
    const double mid = 0.5 * (lo + hi);
    (dist(mid) < thickness ? hi : lo) = mid;
  }
  return SweptHit{lo, collider.closestLocal(a + lo * (b - a))};
}

}  // namespace cloth_sim
