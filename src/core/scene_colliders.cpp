// The scene's `contact` defaults, its `colliders` and the move_collider event:
// read and checked like every other section (messages name the field).
#include <cmath>
#include <set>

#include "scene_yaml.hpp"

namespace cloth_sim {

const char* toString(ColliderParams::Type type) {
  switch (type) {
    case ColliderParams::Type::Plane: return "plane";
    case ColliderParams::Type::Sphere: return "sphere";
    case ColliderParams::Type::Box: return "box";
    case ColliderParams::Type::Capsule: return "capsule";
  }
  return "?";
}

namespace scene_yaml {
namespace {

/// The keys each collider type takes besides name, type, friction and frame,
/// and which of them are required.
struct ShapeKeys {
  ColliderParams::Type type;
  std::vector<std::string> keys;
  std::vector<std::string> required;
};

const std::vector<ShapeKeys>& shapeKeys() {
  static const std::vector<ShapeKeys> kShapes = {
      {ColliderParams::Type::Plane, {"point", "normal"}, {"normal"}},
      {ColliderParams::Type::Sphere, {"center", "radius"}, {"center", "radius"}},
      {ColliderParams::Type::Box, {"center", "half_extents", "rpy"}, {"center", "half_extents"}},
      {ColliderParams::Type::Capsule, {"a", "b", "radius"}, {"a", "b", "radius"}},
  };
  return kShapes;
}

ColliderParams readCollider(const YAML::Node& node, const std::string& path) {
  if (!node.IsMap()) fail(path, "expected a map {type: ..., ...}, got " + describe(node));
  const YAML::Node type_node = node["type"];
  if (!type_node.IsDefined()) fail(child(path, "type"), "required (plane, sphere, box or capsule)");
  const std::string type = readName(type_node, child(path, "type"));
  const ShapeKeys* shape = nullptr;
  for (const ShapeKeys& s : shapeKeys()) {
    if (type == toString(s.type)) shape = &s;
  }
  if (!shape) {
    fail(child(path, "type"), "unknown collider type '" + type +
                                  "' (expected plane, sphere, box or capsule)");
  }
  std::vector<std::string> allowed = {"name", "type", "friction", "frame"};
  allowed.insert(allowed.end(), shape->keys.begin(), shape->keys.end());
  const Fields f(node, path, allowed);
  for (const std::string& key : shape->required) {
    if (!f.has(key)) fail(f.path(key), std::string("required for a ") + toString(shape->type));
  }
  ColliderParams c;
  c.type = shape->type;
  if (f.has("name")) c.name = readName(f.get("name"), f.path("name"));
  if (f.has("frame")) c.frame = readName(f.get("frame"), f.path("frame"));
  if (f.has("friction")) c.friction = readNumber(f.get("friction"), f.path("friction"));
  if (f.has("point")) c.point = readVec3(f.get("point"), f.path("point"));
  if (f.has("normal")) c.normal = readVec3(f.get("normal"), f.path("normal"));
  if (f.has("center")) c.center = readVec3(f.get("center"), f.path("center"));
  if (f.has("radius")) c.radius = readNumber(f.get("radius"), f.path("radius"));
  if (f.has("half_extents")) {
    c.half_extents = readVec3(f.get("half_extents"), f.path("half_extents"));
  }
  if (f.has("rpy")) c.rpy = readVec3(f.get("rpy"), f.path("rpy"));
  if (f.has("a")) c.a = readVec3(f.get("a"), f.path("a"));
  if (f.has("b")) c.b = readVec3(f.get("b"), f.path("b"));
  return c;
}

void validateCollider(const ColliderParams& c, const std::string& path) {
  if (c.friction) requireNonNegative(*c.friction, child(path, "friction"));
  switch (c.type) {
    case ColliderParams::Type::Plane:
      requireFiniteVec(c.point, child(path, "point"));
      requireFiniteVec(c.normal, child(path, "normal"));
      if (!(c.normal.norm() > 1e-12)) fail(child(path, "normal"), "must not be zero");
      break;
    case ColliderParams::Type::Sphere:
      requireFiniteVec(c.center, child(path, "center"));
      requirePositive(c.radius, child(path, "radius"));
      break;
    case ColliderParams::Type::Box:
      requireFiniteVec(c.center, child(path, "center"));
      for (int k = 0; k < 3; ++k) {
        requirePositive(c.half_extents[k], element(child(path, "half_extents"), k));
      }
      requireFiniteVec(c.rpy, child(path, "rpy"));
      break;
    case ColliderParams::Type::Capsule:
      requireFiniteVec(c.a, child(path, "a"));
      requireFiniteVec(c.b, child(path, "b"));
      requirePositive(c.radius, child(path, "radius"));
      break;
  }
}

}  // namespace

void readContact(const YAML::Node& contact, const YAML::Node& colliders, Scene* scene) {
  const Fields f(contact, "contact",
                 {"thickness", "friction", "friction_smoothing", "exact_sticking"});
  if (f.has("thickness")) scene->contact.thickness = readNumber(f.get("thickness"), f.path("thickness"));
  if (f.has("friction")) scene->contact.friction = readNumber(f.get("friction"), f.path("friction"));
  if (f.has("friction_smoothing")) {
    scene->contact.friction_smoothing =
        readNumber(f.get("friction_smoothing"), f.path("friction_smoothing"));
  }
  if (f.has("exact_sticking")) {
    scene->contact.exact_sticking = readBool(f.get("exact_sticking"), f.path("exact_sticking"));
  }
  if (!colliders.IsDefined() || colliders.IsNull()) return;
  if (!colliders.IsSequence()) {
    fail("colliders", "expected a list of colliders, got " + describe(colliders));
  }
  for (size_t k = 0; k < colliders.size(); ++k) {
    scene->colliders.push_back(readCollider(colliders[k], element("colliders", k)));
  }
}

void readMoveCollider(const YAML::Node& body, const std::string& action_path, SceneEvent* event) {
  event->kind = SceneEvent::Kind::MoveCollider;
  const Fields g(body, action_path, {"name", "position", "velocity", "duration"});
  if (!g.has("name")) fail(g.path("name"), "required (the collider to move)");
  event->collider = readName(g.get("name"), g.path("name"));
  if (g.has("position")) event->position = readVec3(g.get("position"), g.path("position"));
  if (g.has("velocity")) event->velocity = readVec3(g.get("velocity"), g.path("velocity"));
  if (!event->position && !event->velocity) {
    fail(action_path, "expected position, velocity (with duration) or both");
  }
  if (g.has("duration")) {
    if (!event->velocity) fail(g.path("duration"), "only applies with velocity");
    event->duration = readNumber(g.get("duration"), g.path("duration"));
  } else if (event->velocity) {
    fail(g.path("duration"), "required with velocity (s, > 0)");
  }
}

void validateContact(const Scene& scene) {
  requireNonNegative(scene.contact.thickness, "contact.thickness");
  requireNonNegative(scene.contact.friction, "contact.friction");
  requireNonNegative(scene.contact.friction_smoothing, "contact.friction_smoothing");
  std::set<std::string> names;
  for (size_t k = 0; k < scene.colliders.size(); ++k) {
    const ColliderParams& c = scene.colliders[k];
    const std::string path = element("colliders", k);
    validateCollider(c, path);
    if (!c.name.empty() && !names.insert(c.name).second) {
      fail(child(path, "name"), "duplicate collider name '" + c.name + "'");
    }
  }
  if (!scene.colliders.empty() && scene.solver.method == Method::SymplecticEuler) {
    fail("solver.method", "symplectic_euler has no contact: colliders need implicit_euler, "
                          "newton or bdf2");
  }
}

void readSelfCollision(const YAML::Node& node, Scene* scene) {
  const Fields f(node, "self_collision", {"enabled", "thickness", "friction"});
  Scene::SelfCollision& sc = scene->self_collision;
  if (f.has("enabled")) sc.enabled = readBool(f.get("enabled"), f.path("enabled"));
  if (f.has("thickness")) sc.thickness = readNumber(f.get("thickness"), f.path("thickness"));
  if (f.has("friction")) sc.friction = readNumber(f.get("friction"), f.path("friction"));
}

void validateSelfCollision(const Scene& scene) {
  const Scene::SelfCollision& sc = scene.self_collision;
  // Checked even when disabled: a bad value is a mistake either way.
  requireNonNegative(sc.thickness, "self_collision.thickness");
  requireNonNegative(sc.friction, "self_collision.friction");
  if (!sc.enabled) return;
  // The proximity response and the CCD's separation both scale with it: at 0
  // two layers could rest exactly on each other, where "intersecting" and
  // "touching" cannot be told apart.
  if (!(sc.thickness > 0.0)) {
    fail("self_collision.thickness", "must be > 0 when self_collision is enabled, got " +
                                         formatNumber(sc.thickness));
  }
  if (scene.solver.method == Method::SymplecticEuler) {
    fail("solver.method", "symplectic_euler has no self-collision: self_collision needs "
                          "implicit_euler, newton or bdf2");
  }
}

void validateMoveCollider(const SceneEvent& event, const Scene& scene, const std::string& path) {
  bool found = false;
  for (const ColliderParams& c : scene.colliders) found = found || c.name == event.collider;
  if (!found) fail(child(path, "name"), "no collider named '" + event.collider + "'");
  if (event.position) requireFiniteVec(*event.position, child(path, "position"));
  requireNonNegative(event.duration, child(path, "duration"));
  if (event.velocity) {
    requireFiniteVec(*event.velocity, child(path, "velocity"));
    requirePositive(event.duration, child(path, "duration"));
  }
}

}  // namespace scene_yaml
}  // namespace cloth_sim
