// Rigid colliders: a convex shape in its own frame, placed in the world by a
// pose. Pure geometry: signed distance, closest surface point and outward
// normal, and the first contact of a point moving along a segment while the
// collider moves between two poses (continuous detection, so nothing tunnels).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cloth_sim/scene.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// world = rotation * local + translation.
struct Pose {
  Mat3 rotation = Mat3::Identity();
  Vec3 translation = Vec3::Zero();
  Vec3 toWorld(const Vec3& local) const { return rotation * local + translation; }
  Vec3 toLocal(const Vec3& world) const { return rotation.transpose() * (world - translation); }
  Pose operator*(const Pose& o) const {
    return {rotation * o.rotation, rotation * o.translation + translation};
  }
};
/// Roll, pitch, yaw (REP 103: R = Rz(yaw) Ry(pitch) Rx(roll)).
Mat3 rotationFromRpy(const Vec3& rpy);

/// The closest point of a surface to a query point.
struct SurfacePoint {
  double distance = 0.0;         ///< signed: < 0 inside the shape
  Vec3 point = Vec3::Zero();     ///< on the surface
  Vec3 normal = Vec3::UnitZ();   ///< outward unit normal there
};

class Collider {
 public:
  using Type = ColliderParams::Type;
  /// The shape of `params` in its own frame, and its pose in the scene:
  /// plane through the origin with its normal (pose at `point`); sphere at the
  /// origin (pose at `center`); box centred, axis-aligned (pose `center`,
  /// `rpy`); capsule from the origin to b - a (pose at `a`).
  static Collider fromParams(const ColliderParams& params, double default_friction);

  Type type() const { return type_; }
  const std::string& name() const { return name_; }
  const std::string& frame() const { return frame_; }
  double friction() const { return friction_; }
  double radius() const { return radius_; }
  const Vec3& halfExtents() const { return half_extents_; }
  const Vec3& planeNormal() const { return normal_; }  ///< local
  const Vec3& segment() const { return segment_; }     ///< capsule: local b - a
  /// Where the scene put it (reset, and the offset from a tf frame).
  const Pose& scenePose() const { return scene_pose_; }

  /// Signed distance etc. of a point given in the collider's own frame.
  SurfacePoint closestLocal(const Vec3& p) const;
  /// The same in the world, with the collider at `pose`.
  SurfacePoint closest(const Vec3& p, const Pose& pose) const;

 private:
  Type type_ = Type::Plane;
  std::string name_, frame_;
  double friction_ = 0.0;
  double radius_ = 0.0;
  Vec3 half_extents_ = Vec3::Zero();
  Vec3 normal_ = Vec3::UnitZ();
  Vec3 segment_ = Vec3::Zero();
  Pose scene_pose_;
};

/// The colliders over one step: their shapes, poses at its start and end.
struct CollidersOverStep {
  const std::vector<Collider>* colliders = nullptr;
  std::vector<Pose> start, end;
  double thickness = 0.0;
  double friction_smoothing = 0.0;  ///< m/s; 0: exact stick/slip (Scene::Contact)
  bool exact_sticking = true;       ///< Scene::Contact::exact_sticking
  bool empty() const { return !colliders || colliders->empty(); }
};

/// The first contact of a point that moves from p0 to p1 (world) while the
/// collider moves from pose0 to pose1 (straight in its own frame).
struct SweptHit {
  double t = 0.0;       ///< fraction of the step at first contact (0: already within)
  SurfacePoint local;   ///< closest surface point there, collider frame
};
/// Returns the first time the point comes within `thickness` of the surface
/// (distance to a convex shape is convex along a segment: a bracketed
/// minimum, then bisection), or nothing if it stays at least `thickness`
/// minus `tolerance` away.
std::optional<SweptHit> firstContact(const Collider& collider, const Pose& pose0,
                                     const Pose& pose1, const Vec3& p0, const Vec3& p1,
                                     double thickness, double tolerance);

}  // namespace cloth_sim
