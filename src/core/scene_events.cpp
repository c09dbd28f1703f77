// The scene's `events` list: reading each event and checking it against the
// scene (scene.cpp reads and checks the rest; docs/scene.md, "Events").
#include <string>
#include <vector>

#include "scene_yaml.hpp"

namespace cloth_sim {
namespace scene_yaml {

SceneEvent readEvent(const YAML::Node& node, const std::string& path) {
  static const std::vector<std::string> kActions = {"set_stiffness", "move_pin", "pin",
                                                    "release", "move_collider"};
  std::vector<std::string> keys = {"time"};
  keys.insert(keys.end(), kActions.begin(), kActions.end());
  if (!node.IsDefined() || node.IsNull()) fail(path, "expected a map {time: ..., <action>: ...}");
  const Fields f(node, path, keys);

  SceneEvent event;
  if (!f.has("time")) fail(f.path("time"), "required (simulated time in s, >= 0)");
  event.time = readNumber(f.get("time"), f.path("time"));

  std::vector<std::string> actions;
  for (const auto& action : kActions) {
    if (f.has(action)) actions.push_back(action);
  }
  if (actions.size() != 1) {
    fail(path, "expected exactly one action (" + joinNames(kActions) + "), got " +
                   (actions.empty() ? std::string("none")
                                    : std::to_string(actions.size()) + ": " + joinNames(actions)));
  }
  const std::string& action = actions.front();
  const std::string action_path = f.path(action);
  const YAML::Node body = f.get(action);

  if (action == "set_stiffness") {
    event.kind = SceneEvent::Kind::SetStiffness;
    const Fields g(body, action_path, {"spring_type", "stiffness", "damping"});
    if (!g.has("spring_type")) {
      fail(g.path("spring_type"), "required (stretch, shear, bend or all)");
    }
    const std::string type = readName(g.get("spring_type"), g.path("spring_type"));
    if (type == "all") {
      event.all_types = true;
    } else if (!parseSpringType(type, &event.spring_type)) {
      fail(g.path("spring_type"),
           "unknown spring type '" + type + "' (expected stretch, shear, bend, all)");
    }
    if (!g.has("stiffness")) fail(g.path("stiffness"), "required (N/m, > 0)");
    event.stiffness = readNumber(g.get("stiffness"), g.path("stiffness"));
    if (g.has("damping")) {
      // In SceneEvent a negative damping means "keep"; in a file it is a mistake.
      event.damping = readNumber(g.get("damping"), g.path("damping"));
      if (event.damping < 0.0) {
        fail(g.path("damping"), "must be >= 0, got " + formatNumber(event.damping));
      }
    }
  } else if (action == "move_pin") {
    event.kind = SceneEvent::Kind::MovePin;
    const Fields g(body, action_path, {"index", "position", "velocity", "duration"});
    if (!g.has("index")) fail(g.path("index"), "required (the pinned node to move)");
    event.index = readInt(g.get("index"), g.path("index"));
    if (g.has("position")) event.position = readVec3(g.get("position"), g.path("position"));
    if (g.has("velocity")) event.velocity = readVec3(g.get("velocity"), g.path("velocity"));
    if (!event.position && !event.velocity) {
      fail(action_path, "expected position, velocity (with duration) or both");
    }
    if (g.has("duration")) {
      if (!event.velocity) fail(g.path("duration"), "only applies with velocity");
      event.duration = readNumber(g.get("duration"), g.path("duration"));
    } else if (event.velocity) {
      fail(g.path("duration"), "required with velocity (s, > 0)");
    }
  } else if (action == "move_collider") {
    readMoveCollider(body, action_path, &event);
  } else if (action == "pin") {
    event.kind = SceneEvent::Kind::Pin;
    if (!body.IsSequence()) {
      fail(action_path, "expected a list of node indices, got " + describe(body));
    }
    event.indices = readIndices(body, action_path);
  } else {
    event.kind = SceneEvent::Kind::Release;
    if (body.IsScalar() && body.Scalar() == "all") {
      event.release_all = true;
    } else if (body.IsSequence()) {
      event.indices = readIndices(body, action_path);
    } else {
      fail(action_path, "expected 'all' or a list of node indices, got " + describe(body));
    }
  }
  return event;
}

void validateEvent(const SceneEvent& event, const Scene& scene, const std::string& path) {
  const int num_nodes = scene.numNodes();
  switch (event.kind) {
    case SceneEvent::Kind::SetStiffness: {
      const std::string action = path + ".set_stiffness";
      requirePositive(event.stiffness, action + ".stiffness");
      requireFinite(event.damping, action + ".damping");
      if (event.damping < 0.0 && event.damping != -1.0) {
        fail(action + ".damping", "must be >= 0 (or -1 to keep the current damping), got " +
                                      formatNumber(event.damping));
      }
      if (!event.all_types && !scene.springs[static_cast<int>(event.spring_type)].enabled) {
        fail(action + ".spring_type", std::string("the scene has no ") +
                                          toString(event.spring_type) +
                                          " springs (group absent or stiffness 0)");
      }
      break;
    }
    case SceneEvent::Kind::MovePin: {
      const std::string action = path + ".move_pin";
      // A node not pinned when the event runs is pinned by it (docs/scene.md).
      requireNode(event.index, num_nodes, action + ".index");
      if (!event.position && !event.velocity) {
        fail(action, "expected position, velocity (with duration) or both");
      }
      if (event.position) requireFiniteVec(*event.position, action + ".position");
      requireNonNegative(event.duration, action + ".duration");
      if (event.velocity) {
        requireFiniteVec(*event.velocity, action + ".velocity");
        requirePositive(event.duration, action + ".duration");
      }
      break;
    }
    case SceneEvent::Kind::Pin:
      requireNodeList(event.indices, num_nodes, path + ".pin", true);
      break;
    case SceneEvent::Kind::Release:
      if (!event.release_all) requireNodeList(event.indices, num_nodes, path + ".release", true);
      break;
    case SceneEvent::Kind::MoveCollider:
      validateMoveCollider(event, scene, path + ".move_collider");
      break;
  }
}

void validateEvents(const Scene& scene) {
  for (size_t k = 0; k < scene.events.size(); ++k) {
    const std::string path = element("events", k);
    const SceneEvent& event = scene.events[k];
    requireNonNegative(event.time, path + ".time");
    if (k > 0 && event.time < scene.events[k - 1].time) {
      fail(path + ".time", "events must be in time order, got " + formatNumber(event.time) +
                               " after " + formatNumber(scene.events[k - 1].time));
    }
    validateEvent(event, scene, path);
  }
}

}  // namespace scene_yaml
}  // namespace cloth_sim
