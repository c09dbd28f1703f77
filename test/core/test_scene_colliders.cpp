// The contact section of a scene: every bad value is refused with its field.
#include <gtest/gtest.h>

#include "cloth_sim/scene.hpp"

namespace cloth_sim {
namespace {

const char* kBase = "cloth: {rows: 3, cols: 3}\n";

std::string errorOf(const std::string& extra) {
  try {
    parseScene(std::string(kBase) + extra);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

void expectRejected(const std::string& extra, const std::string& field) {
  const std::string error = errorOf(extra);
  EXPECT_EQ(error.rfind(field + ":", 0), 0u) << "scene:\n" << extra << "\nerror: " << error;
}

TEST(SceneColliders, ReadsEveryShapeWithDefaults) {
  const Scene s = parseScene(std::string(kBase) + R"(
contact: {thickness: 0.003, friction: 0.25}
colliders:
  - {name: floor,  type: plane,   point: [0, 0, 0], normal: [0, 0, 2], friction: 0.5}
  - {name: ball,   type: sphere,  center: [0, 0, 0.5], radius: 0.3}
  - {name: table,  type: box,     center: [0, 0, 0.4], half_extents: [0.5, 0.3, 0.4], rpy: [0, 0, 0.3]}
  - {name: finger, type: capsule, a: [0, 0, 1], b: [0.2, 0, 1], radius: 0.02, frame: gripper}
initial: {velocity: [0.1, 0, -1]}
events:
  - {time: 0.5, move_collider: {name: ball, velocity: [0, 0, 1], duration: 0.2}}
)");
  EXPECT_EQ(s.contact.thickness, 0.003);
  EXPECT_EQ(s.contact.friction, 0.25);
  ASSERT_EQ(s.colliders.size(), 4u);
  EXPECT_EQ(s.colliders[0].type, ColliderParams::Type::Plane);
  EXPECT_EQ(*s.colliders[0].friction, 0.5);
  EXPECT_FALSE(s.colliders[1].friction.has_value());
  EXPECT_EQ(s.colliders[2].rpy, Vec3(0, 0, 0.3));
  EXPECT_EQ(s.colliders[3].frame, "gripper");
  EXPECT_EQ(s.initial.velocity, Vec3(0.1, 0, -1));
  ASSERT_EQ(s.events.size(), 1u);
  EXPECT_EQ(s.events[0].kind, SceneEvent::Kind::MoveCollider);
  EXPECT_EQ(s.events[0].collider, "ball");
}

TEST(SceneColliders, RefusesBadValuesNamingTheField) {
  expectRejected("colliders:\n  - {type: sphere, center: [0, 0, 0], radius: -1}", "colliders[0].radius");
  expectRejected("colliders:\n  - {type: sphere, center: [0, 0, 0], radius: 0}", "colliders[0].radius");
  expectRejected("colliders:\n  - {type: plane, normal: [0, 0, 0]}", "colliders[0].normal");
  expectRejected("colliders:\n  - {type: plane, normal: [0, .nan, 1]}", "colliders[0].normal[1]");
  expectRejected("colliders:\n  - {type: box, center: [0, 0, 0], half_extents: [1, 0, 1]}",
                 "colliders[0].half_extents[1]");
  expectRejected("colliders:\n  - {type: box, center: [0, 0, 0]}", "colliders[0].half_extents");
  expectRejected("colliders:\n  - {type: box, center: [0, 0, 0], half_extents: [1, 1, 1], radius: 2}",
                 "colliders[0].radius");
  expectRejected("colliders:\n  - {type: capsule, a: [0, 0, 0], b: [1, 0, 0], radius: 0.1, friction: -0.1}",
                 "colliders[0].friction");
  expectRejected("colliders:\n  - {type: cone, center: [0, 0, 0]}", "colliders[0].type");
  expectRejected("colliders:\n  - {center: [0, 0, 0]}", "colliders[0].type");
  expectRejected("colliders:\n  - {name: a, type: plane, normal: [0, 0, 1]}\n"
                 "  - {name: a, type: plane, normal: [0, 1, 0]}",
                 "colliders[1].name");
  expectRejected("colliders: {type: plane}", "colliders");
  expectRejected("contact: {thickness: -0.001}", "contact.thickness");
  expectRejected("contact: {friction: -1}", "contact.friction");
  expectRejected("contact: {stiffness: 3}", "contact.stiffness");
  expectRejected("initial: {velocity: [0, 1]}", "initial.velocity");
  expectRejected("colliders:\n  - {name: a, type: plane, normal: [0, 0, 1]}\n"
                 "events:\n  - {time: 0, move_collider: {name: b, position: [0, 0, 1]}}",
                 "events[0].move_collider.name");
  expectRejected("colliders:\n  - {name: a, type: plane, normal: [0, 0, 1]}\n"
                 "events:\n  - {time: 0, move_collider: {name: a, velocity: [0, 0, 1]}}",
                 "events[0].move_collider.duration");
  expectRejected("colliders:\n  - {name: a, type: plane, normal: [0, 0, 1]}\n"
                 "solver: {method: symplectic_euler}",
                 "solver.method");
}

TEST(SceneColliders, OverridesReachColliders) {
  const Scene s = parseScene(std::string(kBase) +
                                 "colliders:\n  - {name: ball, type: sphere, center: [0, 0, 0], radius: 0.3}",
                             {"colliders[0].radius=0.5"});
  EXPECT_EQ(s.colliders[0].radius, 0.5);
  EXPECT_THROW(parseScene(std::string(kBase) +
                              "colliders:\n  - {name: ball, type: sphere, center: [0, 0, 0], radius: 0.3}",
                          {"colliders[0].radius=-2"}),
               SceneError);
}

}  // namespace
}  // namespace cloth_sim
