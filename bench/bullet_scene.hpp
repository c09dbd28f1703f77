// A scene's colliders, self-collision and scripted pins in the Bullet peer's
// terms, for the self-collision benchmark and bullet_check.
#pragma once

#include <map>
#include <string>

#include "bullet_peer.hpp"
#include "cloth_sim/collider.hpp"
#include "cloth_sim/scene.hpp"
#include "command_line.hpp"

namespace cloth_sim::bench {

/// The scene's colliders as the peer's boxes (a plane: a 2 m thick, 20 m wide box under it).
inline BulletContact bulletContact(const Scene& scene, bool self) {
  BulletContact c;
  for (const ColliderParams& p : scene.colliders) {
    BulletBox box;
    box.friction = p.friction.value_or(scene.contact.friction);
    if (p.type == ColliderParams::Type::Box) {
      box.center = p.center;
      box.half_extents = p.half_extents;
      box.rotation = rotationFromRpy(p.rpy);
    } else if (p.type == ColliderParams::Type::Plane) {
      const Vec3 n = p.normal.normalized();
      box.half_extents = Vec3(10.0, 10.0, 1.0);
      box.center = p.point - n;
      box.rotation = Eigen::Quaterniond::FromTwoVectors(Vec3::UnitZ(), n).toRotationMatrix();
    } else {
      throw UsageError{"colliders: the Bullet peer takes boxes and planes only, got " +
                       std::string(toString(p.type))};
    }
    c.boxes.push_back(box);
  }
  c.margin = scene.contact.thickness;
  c.self_collision = self && scene.self_collision.enabled;
  c.self_thickness = scene.self_collision.thickness;
  c.self_friction = scene.self_collision.friction;
  return c;
}

/// The scene's pin events as (step, node, held?, velocity) changes on the peer.
struct PinChange {
  long step;
  int node;
  bool hold;
  Vec3 velocity;
};

inline std::multimap<long, PinChange> pinScript(const Scene& scene, double dt) {
  std::multimap<long, PinChange> script;
  auto add = [&](long k, int node, bool hold, const Vec3& v) {
    script.emplace(k, PinChange{k, node, hold, v});
  };
  for (const SceneEvent& e : scene.events) {
    const long k = stepsTo(e.time, dt, "event");
    if (e.kind == SceneEvent::Kind::MovePin && !e.position) {
      const Vec3 v = e.velocity.value_or(Vec3::Zero());
      add(k, e.index, true, v);
      if (e.duration > 0) add(stepsTo(e.time + e.duration, dt, "move_pin end"), e.index, true,
                              Vec3::Zero());
    } else if (e.kind == SceneEvent::Kind::Pin) {
      for (int i : e.indices) add(k, i, true, Vec3::Zero());
    } else if (e.kind == SceneEvent::Kind::Release) {
      std::vector<int> nodes = e.indices;
      if (e.release_all) {
        for (int i = 0; i < scene.numNodes(); ++i) nodes.push_back(i);  // held or not
      }
      for (int i : nodes) add(k, i, false, Vec3::Zero());
    } else {
      throw UsageError{"events: the peer replays move_pin (velocity only), pin and release"};
    }
  }
  return script;
}

}  // namespace cloth_sim::bench
