// Scene files: YAML -> Scene, with overrides, and the checks every Scene must
// pass. Every error message starts with the dotted path of the bad field, so a
// user can find it in the file (or in the --set that produced it).
#include "cloth_sim/scene.hpp"
#include "scene_yaml.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace cloth_sim {

namespace {
std::string printable(const std::string& text) {
  std::string out;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof(escaped), "\\x%02x", byte);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out;
}
}  // namespace

SceneError::SceneError(const std::string& message) : std::runtime_error(printable(message)) {}

// Shared with scene_colliders.cpp through scene_yaml.hpp.
namespace scene_yaml {

constexpr long long kMaxNodes = 4000000;  // a typo like rows: 200000 fails here, not in malloc

// ------------------------------------------------------------ messages ----

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw SceneError(path + ": " + what);
}

/// Shortest text that reads back as the same double ("-3", "1e-06", "nan").
std::string formatNumber(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

std::string child(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

std::string element(const std::string& path, size_t index) {
  return path + "[" + std::to_string(index) + "]";
}

/// How a YAML value looks to the user, for "expected X, got Y".
std::string describe(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Scalar:
      return node.Tag() == "!" ? "the quoted string '" + node.Scalar() + "'"
                               : "'" + node.Scalar() + "'";
    case YAML::NodeType::Sequence: return "a sequence";
    case YAML::NodeType::Map: return "a map";
    default: return "nothing (null)";
  }
}

std::string joinNames(const std::vector<std::string>& names) {
  std::string text;
  for (size_t i = 0; i < names.size(); ++i) text += (i ? ", " : "") + names[i];
  return text;
}

// -------------------------------------------------------- YAML readers ----

bool isYamlInfOrNan(const std::string& text) {
  static const std::set<std::string> kSpecial = {
      ".inf", ".Inf", ".INF", "+.inf", "+.Inf", "+.INF", "-.inf", "-.Inf", "-.INF",
      ".nan", ".NaN", ".NAN"};
  return kSpecial.count(text) != 0;
}

/// Parses the whole text as a decimal number (locale-independent). Non-finite
/// spellings ("nan", ".inf", ...) and numbers beyond the range of a double
/// come back as NaN so the caller rejects them as not finite.
bool textToDouble(const std::string& text, double* value) {
  if (isYamlInfOrNan(text)) {
    *value = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  const char* begin = text.data();
  const char* end = begin + text.size();
  if (begin != end && *begin == '+') ++begin;
  if (begin == end) return false;
  const auto result = std::from_chars(begin, end, *value);
  if (result.ptr != end) return false;
  if (result.ec == std::errc::result_out_of_range) {
    *value = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  return result.ec == std::errc();
}

/// The scalar text of a plain (unquoted) YAML scalar, or an error saying what
/// was expected instead.
const std::string& plainScalar(const YAML::Node& node, const std::string& path,
                               const std::string& expected) {
  if (!node.IsScalar() || node.Tag() == "!") {
    fail(path, "expected " + expected + ", got " + describe(node));
  }
  return node.Scalar();
}

double readNumber(const YAML::Node& node, const std::string& path) {
  const std::string& text = plainScalar(node, path, "a number");
  double value = 0.0;
  if (!textToDouble(text, &value)) fail(path, "expected a number, got '" + text + "'");
  if (!std::isfinite(value)) fail(path, "must be a finite number, got '" + text + "'");
  return value;
}

/// An integer in [lo, hi]. "24.0" and "1e3" are accepted: they are integers.
long long readInteger(const YAML::Node& node, const std::string& path, long long lo,
                      long long hi) {
  const std::string& text = plainScalar(node, path, "an integer");
  long long value = 0;
  const char* begin = text.data();
  const char* end = begin + text.size();
  if (begin != end && *begin == '+') ++begin;
  const auto result = std::from_chars(begin, end, value);
  if (result.ec != std::errc() || result.ptr != end) {
    double number = 0.0;
    if (!textToDouble(text, &number) || !std::isfinite(number) ||
        number != std::floor(number)) {
      fail(path, "expected an integer, got '" + text + "'");
    }
    if (number < static_cast<double>(lo) || number > static_cast<double>(hi)) {
      fail(path, "integer out of range [" + std::to_string(lo) + ", " + std::to_string(hi) +
                     "], got '" + text + "'");
    }
    value = static_cast<long long>(number);
  }
  if (value < lo || value > hi) {
    fail(path, "integer out of range [" + std::to_string(lo) + ", " + std::to_string(hi) +
                   "], got '" + text + "'");
  }
  return value;
}

int readInt(const YAML::Node& node, const std::string& path) {
  return static_cast<int>(readInteger(node, path, std::numeric_limits<int>::min(),
                                      std::numeric_limits<int>::max()));
}

bool readBool(const YAML::Node& node, const std::string& path) {
  const std::string& text = plainScalar(node, path, "true or false");
  if (text == "true" || text == "True" || text == "TRUE") return true;
  if (text == "false" || text == "False" || text == "FALSE") return false;
  fail(path, "expected true or false, got '" + text + "'");
}

std::string readName(const YAML::Node& node, const std::string& path) {
  if (!node.IsScalar()) fail(path, "expected a name, got " + describe(node));
  return node.Scalar();
}

Vec3 readVec3(const YAML::Node& node, const std::string& path) {
  if (!node.IsSequence()) fail(path, "expected 3 numbers [x, y, z], got " + describe(node));
  if (node.size() != 3) {
    fail(path, "expected 3 numbers [x, y, z], got " + std::to_string(node.size()));
  }
  Vec3 value;
  for (size_t k = 0; k < 3; ++k) value[k] = readNumber(node[k], element(path, k));
  return value;
}

/// A list of node indices (range checks come later, in validateScene).
std::vector<int> readIndices(const YAML::Node& node, const std::string& path) {
  if (!node.IsDefined() || node.IsNull()) return {};
  if (!node.IsSequence()) fail(path, "expected a list of node indices, got " + describe(node));
  std::vector<int> indices;
  for (size_t k = 0; k < node.size(); ++k) indices.push_back(readInt(node[k], element(path, k)));
  return indices;
}

// ------------------------------------------------------ scene sections ----

void readCloth(const YAML::Node& node, Scene::Cloth* cloth) {
  const Fields f(node, "cloth",
                 {"rows", "cols", "width", "length", "plane", "origin", "mass", "node_mass"});
  if (!f.has("rows")) fail(f.path("rows"), "required (number of node rows, >= 2)");
  if (!f.has("cols")) fail(f.path("cols"), "required (number of node columns, >= 1)");
  cloth->rows = readInt(f.get("rows"), f.path("rows"));
  cloth->cols = readInt(f.get("cols"), f.path("cols"));
  if (f.has("width")) cloth->width = readNumber(f.get("width"), f.path("width"));
  if (f.has("length")) cloth->length = readNumber(f.get("length"), f.path("length"));
  if (f.has("plane")) {
    const std::string name = readName(f.get("plane"), f.path("plane"));
    if (name == "horizontal") {
      cloth->plane = Plane::Horizontal;
    } else if (name == "vertical") {
      cloth->plane = Plane::Vertical;
    } else {
      fail(f.path("plane"), "unknown plane '" + name + "' (expected horizontal, vertical)");
    }
  }
  if (f.has("origin")) cloth->origin = readVec3(f.get("origin"), f.path("origin"));
  if (f.has("mass")) cloth->mass = readNumber(f.get("mass"), f.path("mass"));

  const YAML::Node masses = f.get("node_mass");
  const std::string masses_path = f.path("node_mass");
  if (masses.IsDefined() && !masses.IsNull()) {
    if (!masses.IsMap()) {
      fail(masses_path, "expected a map {node index: mass}, got " + describe(masses));
    }
    for (auto it = masses.begin(); it != masses.end(); ++it) {
      const std::string key_text = it->first.IsScalar() ? it->first.Scalar() : "?";
      const std::string path = child(masses_path, key_text);
      const int index = readInt(it->first, path);
      if (cloth->node_mass.count(index)) fail(path, "duplicate node " + std::to_string(index));
      cloth->node_mass[index] = readNumber(it->second, path);
    }
  }
}

void readSprings(const YAML::Node& node, Scene* scene) {
  const Fields f(node, "springs", {"stretch", "shear", "bend", "damping_model"});
  // Defaults of a group named without values: the demo cloth's.
  const double kDefaultStiffness[kNumSpringTypes] = {5000.0, 500.0, 5.0};
  const double kDefaultDamping[kNumSpringTypes] = {2.0, 0.5, 0.0};
  for (int t = 0; t < kNumSpringTypes; ++t) {
    const std::string name = toString(static_cast<SpringType>(t));
    SpringGroupParams& group = scene->springs[t];
    group = SpringGroupParams{};
    if (!f.has(name)) continue;  // absent: no springs of this type
    const Fields g(f.get(name), f.path(name), {"stiffness", "damping"});
    group.stiffness = g.has("stiffness") ? readNumber(g.get("stiffness"), g.path("stiffness"))
                                         : kDefaultStiffness[t];
    group.damping = g.has("damping") ? readNumber(g.get("damping"), g.path("damping"))
                                     : kDefaultDamping[t];
    // Stiffness 0 turns the group off (absent from the model, costs nothing);
    // a negative one stays enabled so validateScene rejects it.
    group.enabled = group.stiffness != 0.0;
  }
  if (f.has("damping_model")) {
    const std::string name = readName(f.get("damping_model"), f.path("damping_model"));
    if (name == "along_spring") {
      scene->damping_model = DampingModel::AlongSpring;
    } else if (name == "relative_velocity") {
      scene->damping_model = DampingModel::RelativeVelocity;
    } else {
      fail(f.path("damping_model"),
           "unknown damping model '" + name + "' (expected along_spring, relative_velocity)");
    }
  }
}

void readInitial(const YAML::Node& node, Scene::Initial* initial) {
  const Fields f(node, "initial", {"velocity", "stretch", "scatter", "seed", "collapse"});
  if (f.has("velocity")) initial->velocity = readVec3(f.get("velocity"), f.path("velocity"));
  if (f.has("stretch")) initial->stretch = readNumber(f.get("stretch"), f.path("stretch"));
  if (f.has("scatter")) initial->scatter = readNumber(f.get("scatter"), f.path("scatter"));
  if (f.has("seed")) {
    initial->seed = static_cast<unsigned>(
        readInteger(f.get("seed"), f.path("seed"), 0, std::numeric_limits<unsigned>::max()));
  }
  if (f.has("collapse")) initial->collapse = readBool(f.get("collapse"), f.path("collapse"));
}

Scene sceneFromYaml(const YAML::Node& root) {
  const Fields top(root, "",
                   {"cloth", "springs", "gravity", "air_drag", "pins", "solver", "initial",
                    "contact", "colliders", "self_collision", "events"});
  Scene scene;
  readCloth(top.get("cloth"), &scene.cloth);
  readSprings(top.get("springs"), &scene);
  if (top.has("gravity")) scene.gravity = readVec3(top.get("gravity"), "gravity");
  if (top.has("air_drag")) scene.air_drag = readNumber(top.get("air_drag"), "air_drag");
  scene.pins = readIndices(top.get("pins"), "pins");
  readSolver(top.get("solver"), &scene.solver);
  readInitial(top.get("initial"), &scene.initial);
  readContact(top.get("contact"), top.get("colliders"), &scene);
  readSelfCollision(top.get("self_collision"), &scene);

  const YAML::Node events = top.get("events");
  if (events.IsDefined() && !events.IsNull()) {
    if (!events.IsSequence()) fail("events", "expected a list of events, got " + describe(events));
    for (size_t k = 0; k < events.size(); ++k) {
      scene.events.push_back(readEvent(events[k], element("events", k)));
    }
  }
  validateScene(scene);
  return scene;
}

/// Records where each document starts (the parser's events are not needed).
class DocumentStarts : public YAML::EventHandler {
 public:
  YAML::Mark start;
  void OnDocumentStart(const YAML::Mark& mark) override { start = mark; }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

/// The number of YAML documents in the text, without YAML::LoadAll: on text
/// that yaml-cpp 0.7 cannot read past (",", ",a", ", x: 1", "[1],") its parser
/// reports an empty document without consuming anything, again and again, and
/// LoadAll loops forever allocating. A document that starts where the one
/// before it started is that case: a syntax error at that place.
int countDocuments(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  YAML::Parser parser(in);
  int count = 0;
  int last_start = -1;
  DocumentStarts starts;
  while (parser.HandleNextDocument(starts)) {
    if (starts.start.pos <= last_start) {
      const size_t pos = static_cast<size_t>(starts.start.pos);
      const std::string found =
          pos < text.size() ? "'" + text.substr(pos, 1) + "'" : "the end of the text";
      throw SceneError(prefix + "YAML syntax error at line " +
                       std::to_string(starts.start.line + 1) + ", column " +
                       std::to_string(starts.start.column + 1) + ": unexpected " + found +
                       " (not the start of a YAML value)");
    }
    last_start = starts.start.pos;
    ++count;
  }
  return count;
}

// ----------------------------------------------------------- overrides ----

/// One step of an override's key path: a map key or a sequence index.
struct PathStep {
  std::string key;
  long index = -1;  ///< >= 0: a sequence element
};

/// Splits "events[0].time" into {events, [0], time}; false if malformed.
bool splitKeyPath(const std::string& text, std::vector<PathStep>* steps) {
  size_t pos = 0;
  while (true) {
    const size_t stop = text.find_first_of(".[", pos);
    const std::string key = text.substr(pos, stop == std::string::npos ? std::string::npos
                                                                          : stop - pos);
    if (key.empty()) return false;
    steps->push_back({key, -1});
    pos = stop;
    while (pos != std::string::npos && text[pos] == '[') {
      const size_t close = text.find(']', pos);
      if (close == std::string::npos || close == pos + 1) return false;
      const std::string digits = text.substr(pos + 1, close - pos - 1);
      if (digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 9) {
        return false;
      }
      steps->push_back({"", std::stol(digits)});
      pos = close + 1;
      if (pos == text.size()) return true;
      if (text[pos] != '.' && text[pos] != '[') return false;
    }
    if (pos == std::string::npos) return true;
    ++pos;  // skip '.'
  }
}

std::string trim(const std::string& text) {
  const size_t first = text.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  const size_t last = text.find_last_not_of(" \t");
  return text.substr(first, last - first + 1);
}

/// Sets one `key.path=value` in the YAML tree, creating intermediate maps.
void applyOverride(YAML::Node root, const std::string& override_text) {
  const std::string name = "override '" + override_text + "'";
  const size_t eq = override_text.find('=');
  if (eq == std::string::npos) {
    throw SceneError(name + ": expected key.path=value, e.g. solver.dt=0.001");
  }
  const std::string key_path = trim(override_text.substr(0, eq));
  std::vector<PathStep> steps;
  if (!splitKeyPath(key_path, &steps)) {
    throw SceneError(name + ": malformed key path '" + key_path +
                     "' (expected names separated by '.', e.g. springs.bend.stiffness)");
  }
  YAML::Node value;
  try {
    const std::string value_text = override_text.substr(eq + 1);
    if (countDocuments(value_text, name + ": value: ") > 1) {
      throw SceneError(name + ": the value holds more than one YAML document");
    }
    value = YAML::Load(value_text);
  } catch (const YAML::Exception& e) {
    throw SceneError(name + ": cannot parse the value as YAML: " + e.msg);
  }

  YAML::Node node = root;  // shares the tree: assignments below edit root
  std::string walked;
  for (size_t k = 0; k < steps.size(); ++k) {
    const PathStep& step = steps[k];
    const bool last = k + 1 == steps.size();
    if (step.index < 0) {
      if (node.IsNull()) node = YAML::Node(YAML::NodeType::Map);
      if (!node.IsMap()) {
        throw SceneError(name + ": " + walked + " is not a map, cannot set '" + step.key + "'");
      }
      walked = child(walked, step.key);
      if (last) {
        node[step.key] = value;
      } else {
        const YAML::Node next = node[step.key];
        if (!next.IsDefined() || next.IsNull()) node[step.key] = YAML::Node(YAML::NodeType::Map);
        node.reset(node[step.key]);
      }
    } else {
      if (!node.IsSequence() || static_cast<size_t>(step.index) >= node.size()) {
        throw SceneError(name + ": " + walked + " has no element [" +
                         std::to_string(step.index) + "]");
      }
      walked = element(walked, static_cast<size_t>(step.index));
      if (last) {
        node[static_cast<size_t>(step.index)] = value;
      } else {
        node.reset(node[static_cast<size_t>(step.index)]);
      }
    }
  }
}

Scene parseWithSource(const std::string& yaml_text, const std::vector<std::string>& overrides,
                      const std::string& source) {
  const std::string prefix = source.empty() ? "" : source + ": ";
  YAML::Node root;
  try {
    const int documents = countDocuments(yaml_text, prefix);
    if (documents > 1) {
      throw SceneError(prefix + "expected one YAML document, got " + std::to_string(documents));
    }
    root = documents == 0 ? YAML::Node(YAML::NodeType::Map) : YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw SceneError(prefix + "YAML syntax error at line " + std::to_string(e.mark.line + 1) +
                     ", column " + std::to_string(e.mark.column + 1) + ": " + e.msg);
  }
  if (root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  if (!root.IsMap()) fail("scene", "expected a map at the top level, got " + describe(root));
  for (const std::string& text : overrides) applyOverride(root, text);
  try {
    return sceneFromYaml(root);
  } catch (const YAML::Exception& e) {  // not expected: the readers check types first
    throw SceneError(prefix + "cannot read the scene: " + e.msg);
  }
}

// ---------------------------------------------------------- validation ----

void requireFinite(double value, const std::string& path) {
  if (!std::isfinite(value)) fail(path, "must be a finite number, got " + formatNumber(value));
}

void requirePositive(double value, const std::string& path) {
  requireFinite(value, path);
  if (!(value > 0.0)) fail(path, "must be > 0, got " + formatNumber(value));
}

void requireNonNegative(double value, const std::string& path) {
  requireFinite(value, path);
  if (value < 0.0) fail(path, "must be >= 0, got " + formatNumber(value));
}

void requireFraction(double value, const std::string& path) {
  requirePositive(value, path);
  if (!(value < 1.0)) fail(path, "must be < 1 (a relative tolerance), got " + formatNumber(value));
}

void requireAtLeast(long long value, long long minimum, const std::string& path) {
  if (value < minimum) {
    fail(path, "must be >= " + std::to_string(minimum) + ", got " + std::to_string(value));
  }
}

void requireFiniteVec(const Vec3& value, const std::string& path) {
  for (int k = 0; k < 3; ++k) requireFinite(value[k], element(path, static_cast<size_t>(k)));
}

void requireNode(int index, int num_nodes, const std::string& path) {
  if (index < 0 || index >= num_nodes) {
    fail(path, "index " + std::to_string(index) + " out of range [0, " +
                   std::to_string(num_nodes - 1) + "]");
  }
}

/// Node indices of a pin list: in range, each once, at least one if required.
void requireNodeList(const std::vector<int>& indices, int num_nodes, const std::string& path,
                     bool non_empty) {
  if (non_empty && indices.empty()) fail(path, "must list at least one node");
  std::map<int, size_t> seen;
  for (size_t k = 0; k < indices.size(); ++k) {
    const std::string item = element(path, k);
    requireNode(indices[k], num_nodes, item);
    const auto found = seen.find(indices[k]);
    if (found != seen.end()) {
      fail(item, "duplicate node " + std::to_string(indices[k]) + " (already " +
                     element(path, found->second) + ")");
    }
    seen[indices[k]] = k;
  }
}

void validateCloth(const Scene::Cloth& cloth) {
  requireAtLeast(cloth.rows, 2, "cloth.rows");
  requireAtLeast(cloth.cols, 1, "cloth.cols");
  const long long nodes = static_cast<long long>(cloth.rows) * cloth.cols;
  if (nodes > kMaxNodes) {
    fail("cloth", "rows * cols = " + std::to_string(cloth.rows) + " * " +
                      std::to_string(cloth.cols) + " = " + std::to_string(nodes) +
                      " nodes exceeds the limit of " + std::to_string(kMaxNodes));
  }
  requirePositive(cloth.width, "cloth.width");
  requirePositive(cloth.length, "cloth.length");
  requireFiniteVec(cloth.origin, "cloth.origin");
  requirePositive(cloth.mass, "cloth.mass");
  for (const auto& [index, mass] : cloth.node_mass) {
    const std::string path = "cloth.node_mass." + std::to_string(index);
    requireNode(index, static_cast<int>(nodes), path);
    requirePositive(mass, path);
  }
}

void validateSprings(const Scene& scene) {
  for (int t = 0; t < kNumSpringTypes; ++t) {
    const SpringGroupParams& group = scene.springs[t];
    const std::string path = std::string("springs.") + toString(static_cast<SpringType>(t));
    const std::string stiffness_path = path + ".stiffness";
    requireFinite(group.stiffness, stiffness_path);
    if (group.stiffness < 0.0) {
      fail(stiffness_path, "must be > 0, got " + formatNumber(group.stiffness) +
                               " (0 turns the group off)");
    }
    if (group.enabled && group.stiffness == 0.0) {
      fail(stiffness_path, "must be > 0 for an enabled group, got 0");
    }
    requireNonNegative(group.damping, path + ".damping");
  }
}

void validateInitial(const Scene::Initial& initial) {
  requireFiniteVec(initial.velocity, "initial.velocity");
  requirePositive(initial.stretch, "initial.stretch");
  requireNonNegative(initial.scatter, "initial.scatter");
}

}  // namespace scene_yaml

using namespace scene_yaml;

Scene parseScene(const std::string& yaml_text, const std::vector<std::string>& overrides) {
  return parseWithSource(yaml_text, overrides, "");
}

Scene loadScene(const std::string& path, const std::vector<std::string>& overrides) {
  std::ifstream file(path, std::ios::binary);
  std::error_code error;
  if (!file || std::filesystem::is_directory(path, error)) {
    throw SceneError(path + ": cannot read file");
  }
  std::ostringstream text;
  text << file.rdbuf();
  if (file.bad()) throw SceneError(path + ": cannot read file");
  return parseWithSource(text.str(), overrides, path);
}

void validateScene(const Scene& scene) {
  validateCloth(scene.cloth);
  validateSprings(scene);
  requireFiniteVec(scene.gravity, "gravity");
  requireNonNegative(scene.air_drag, "air_drag");
  requireNodeList(scene.pins, scene.numNodes(), "pins", false);
  validateSolver(scene.solver);
  validateInitial(scene.initial);
  validateContact(scene);
  validateSelfCollision(scene);
  validateEvents(scene);
}

}  // namespace cloth_sim
