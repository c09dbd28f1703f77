// The YAML readers and value checks of scene.cpp, shared with the files that
// read other scene sections (scene_colliders.cpp). Internal to the core.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <utility>
#include <vector>

#include "cloth_sim/scene.hpp"

namespace cloth_sim {
namespace scene_yaml {

/// Throws SceneError("<path>: <what>").
[[noreturn]] void fail(const std::string& path, const std::string& what);
/// Shortest text that reads back as the same double ("-3", "1e-06", "nan").
std::string formatNumber(double value);
std::string child(const std::string& path, const std::string& key);    ///< "a.b"
std::string element(const std::string& path, size_t index);            ///< "a[3]"
/// How a YAML value looks to the user, for "expected X, got Y".
std::string describe(const YAML::Node& node);
std::string joinNames(const std::vector<std::string>& names);

double readNumber(const YAML::Node& node, const std::string& path);
int readInt(const YAML::Node& node, const std::string& path);
bool readBool(const YAML::Node& node, const std::string& path);
std::string readName(const YAML::Node& node, const std::string& path);
Vec3 readVec3(const YAML::Node& node, const std::string& path);

void requireFinite(double value, const std::string& path);
void requirePositive(double value, const std::string& path);
void requireNonNegative(double value, const std::string& path);
void requireFiniteVec(const Vec3& value, const std::string& path);
void requireFraction(double value, const std::string& path);  ///< in (0, 1)
void requireAtLeast(long long value, long long minimum, const std::string& path);

std::vector<int> readIndices(const YAML::Node& node, const std::string& path);
/// index in [0, num_nodes)
void requireNode(int index, int num_nodes, const std::string& path);
/// Node indices of a pin list: in range, each once, at least one if non_empty.
void requireNodeList(const std::vector<int>& indices, int num_nodes, const std::string& path,
                     bool non_empty);

// scene_events.cpp
/// One entry of `events` (its time and exactly one action).
SceneEvent readEvent(const YAML::Node& node, const std::string& path);
/// Every event: times in order, each action's fields valid for the scene.
void validateEvents(const Scene& scene);

// scene_solver.cpp
/// Reads `solver` (absent: the defaults).
void readSolver(const YAML::Node& node, Scene::Solver* solver);
/// Checks every solver field (the method's own limits included).
void validateSolver(const Scene::Solver& solver);

// scene_colliders.cpp
/// Reads `contact` and `colliders` (either may be absent).
void readContact(const YAML::Node& contact, const YAML::Node& colliders, Scene* scene);
/// The move_collider event body (`action_path` names it).
void readMoveCollider(const YAML::Node& body, const std::string& action_path, SceneEvent* event);
/// Checks contact, colliders (and that no symplectic_euler scene has them).
void validateContact(const Scene& scene);
/// Reads `self_collision` (absent or null: disabled).
void readSelfCollision(const YAML::Node& node, Scene* scene);
/// thickness > 0 and finite when enabled, friction >= 0, an implicit method.
void validateSelfCollision(const Scene& scene);
/// A move_collider event names an existing collider, with finite values.
void validateMoveCollider(const SceneEvent& event, const Scene& scene, const std::string& path);

/// A YAML map checked against the keys it may hold. Null or absent reads as
/// an empty map; anything else that is not a map, an unknown key or a
/// repeated key is an error naming it.
class Fields {
 public:
  Fields(const YAML::Node& node, std::string path, std::vector<std::string> allowed)
      : path_(std::move(path)) {
    if (!node.IsDefined() || node.IsNull()) return;
    if (!node.IsMap()) {
      fail(path_.empty() ? "scene" : path_, "expected a map, got " + describe(node));
    }
    for (auto it = node.begin(); it != node.end(); ++it) {
      if (!it->first.IsScalar()) {
        fail(path_.empty() ? "scene" : path_, "keys must be names, got " + describe(it->first));
      }
      const std::string key = it->first.Scalar();
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        fail(child(path_, key), "unknown key (expected one of " + joinNames(allowed) + ")");
      }
      if (has(key)) fail(child(path_, key), "duplicate key");
      entries_.emplace_back(key, it->second);
    }
  }

  bool has(const std::string& key) const {
    for (const auto& entry : entries_) {
      if (entry.first == key) return true;
    }
    return false;
  }
  YAML::Node get(const std::string& key) const {
    for (const auto& entry : entries_) {
      if (entry.first == key) return entry.second;
    }
    return YAML::Node();
  }
  std::string path(const std::string& key) const { return child(path_, key); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::vector<std::pair<std::string, YAML::Node>> entries_;
};

}  // namespace scene_yaml
}  // namespace cloth_sim
