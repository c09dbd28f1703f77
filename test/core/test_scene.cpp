// Scene files: the shipped scenes load with the values they state, absent
// fields take their documented defaults, overrides edit the tree, and every
// bad value is rejected with a message that starts with the field's path.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "cloth_sim/scene.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {
namespace {

const std::string kSourceDir = CLOTH_SIM_SOURCE_DIR;

// A small valid scene every rejection test edits one field of.
const char* kBase = R"(
cloth: {rows: 24, cols: 24}
springs:
  stretch: {stiffness: 5000.0, damping: 2.0}
  shear: {stiffness: 500.0, damping: 0.5}
  bend: {stiffness: 5.0, damping: 0.0}
pins: [0, 23]
)";

// A scene with one event of each kind, so overrides can reach every event field.
const char* kWithEvents = R"(
cloth: {rows: 24, cols: 24, origin: [0, 0, 1.5], node_mass: {575: 3.0}}
gravity: [0, 0, -9.81]
springs:
  stretch: {stiffness: 5000.0}
pins: [0, 23]
initial: {scatter: 0.01, seed: 7}
events:
  - {time: 0.5, set_stiffness: {spring_type: stretch, stiffness: 1.0e6, damping: 3.0}}
  - {time: 1.0, move_pin: {index: 0, position: [1, 0, 1.5]}}
  - {time: 1.0, move_pin: {index: 0, velocity: [10, 0, 0], duration: 0.2}}
  - {time: 1.5, pin: [5, 6]}
  - {time: 2.0, release: all}
)";

std::string errorOf(const std::string& yaml, const std::vector<std::string>& overrides = {}) {
  try {
    parseScene(yaml, overrides);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(accepted)";
}

std::string validationErrorOf(const Scene& scene) {
  try {
    validateScene(scene);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(accepted)";
}

/// The message starts with `prefix` (the field path, usually with the
/// complaint) and contains `fragment` (usually the bad value).
::testing::AssertionResult messageIs(const std::string& message, const std::string& prefix,
                                     const std::string& fragment) {
  if (message.rfind(prefix, 0) != 0) {
    return ::testing::AssertionFailure()
           << "message '" << message << "' does not start with '" << prefix << "'";
  }
  if (message.find(fragment) == std::string::npos) {
    return ::testing::AssertionFailure()
           << "message '" << message << "' does not contain '" << fragment << "'";
  }
  return ::testing::AssertionSuccess();
}

::testing::AssertionResult rejects(const std::string& yaml, const std::string& prefix,
                                   const std::string& fragment = "") {
  return messageIs(errorOf(yaml), prefix, fragment);
}

::testing::AssertionResult overrideRejects(const std::string& yaml, const std::string& override_text,
                                           const std::string& prefix,
                                           const std::string& fragment = "") {
  return messageIs(errorOf(yaml, {override_text}), prefix, fragment);
}

Scene validScene() { return parseScene(kBase); }

// ------------------------------------------------------------ enum names ----

TEST(SceneTypes, SpringTypeNamesRoundTrip) {
  for (SpringType type : {SpringType::Stretch, SpringType::Shear, SpringType::Bend}) {
    SpringType parsed = SpringType::Stretch;
    ASSERT_TRUE(parseSpringType(toString(type), &parsed)) << toString(type);
    EXPECT_EQ(parsed, type);
  }
  EXPECT_STREQ(toString(SpringType::Bend), "bend");
  SpringType untouched = SpringType::Shear;
  EXPECT_FALSE(parseSpringType("Stretch", &untouched));
  EXPECT_FALSE(parseSpringType("all", &untouched));
  EXPECT_EQ(untouched, SpringType::Shear);
}

TEST(SceneTypes, MethodNamesRoundTrip) {
  const std::vector<std::pair<Method, std::string>> names = {
      {Method::ImplicitEuler, "implicit_euler"},
      {Method::Newton, "newton"},
      {Method::Bdf2, "bdf2"},
      {Method::SymplecticEuler, "symplectic_euler"}};
  for (const auto& [method, name] : names) {
    EXPECT_EQ(std::string(toString(method)), name);
    Method parsed = Method::Newton;
    ASSERT_TRUE(parseMethod(name, &parsed)) << name;
    EXPECT_EQ(parsed, method);
  }
  Method untouched = Method::Bdf2;
  EXPECT_FALSE(parseMethod("rk4", &untouched));
  EXPECT_FALSE(parseMethod("", &untouched));
  EXPECT_EQ(untouched, Method::Bdf2);
}

// ------------------------------------------------------- shipped scenes ----

TEST(SceneFiles, DemoLoadsWithItsValues) {
  const Scene scene = loadScene(kSourceDir + "/config/demo.yaml");
  EXPECT_EQ(scene.cloth.rows, 24);
  EXPECT_EQ(scene.cloth.cols, 24);
  EXPECT_EQ(scene.numNodes(), 576);
  EXPECT_EQ(scene.cloth.width, 1.0);
  EXPECT_EQ(scene.cloth.length, 1.0);
  EXPECT_EQ(scene.cloth.plane, Plane::Horizontal);
  EXPECT_EQ(scene.cloth.origin, Vec3(0, 0, 1.5));
  EXPECT_EQ(scene.cloth.mass, 0.3);
  EXPECT_TRUE(scene.cloth.node_mass.empty());

  const auto& stretch = scene.springs[static_cast<int>(SpringType::Stretch)];
  const auto& shear = scene.springs[static_cast<int>(SpringType::Shear)];
  const auto& bend = scene.springs[static_cast<int>(SpringType::Bend)];
  EXPECT_TRUE(stretch.enabled);
  EXPECT_EQ(stretch.stiffness, 5000.0);
  EXPECT_EQ(stretch.damping, 2.0);
  EXPECT_TRUE(shear.enabled);
  EXPECT_EQ(shear.stiffness, 500.0);
  EXPECT_EQ(shear.damping, 0.5);
  EXPECT_TRUE(bend.enabled);
  EXPECT_EQ(bend.stiffness, 5.0);
  EXPECT_EQ(bend.damping, 0.0);
  EXPECT_EQ(scene.damping_model, DampingModel::AlongSpring);

  EXPECT_EQ(scene.gravity, Vec3(0, 0, -9.81));
  EXPECT_EQ(scene.air_drag, 0.0);
  EXPECT_EQ(scene.pins, (std::vector<int>{0, 23}));
  EXPECT_EQ(scene.solver.method, Method::ImplicitEuler);
  EXPECT_EQ(scene.solver.dt, 1.0 / 120.0);
  EXPECT_EQ(scene.solver.tolerance, 1e-4);
  EXPECT_EQ(scene.solver.max_iterations, 500);
  EXPECT_EQ(scene.solver.preconditioner, Preconditioner::Auto);
  EXPECT_TRUE(scene.solver.project_compression);
  EXPECT_TRUE(scene.events.empty());
}

TEST(SceneFiles, SeedLoadsInTheOriginalProjectsUnits) {
  const Scene scene = loadScene(kSourceDir + "/config/scenes/seed.yaml");
  EXPECT_EQ(scene.cloth.rows, 16);
  EXPECT_EQ(scene.cloth.cols, 16);
  EXPECT_EQ(scene.cloth.width, 96.0);
  EXPECT_EQ(scene.cloth.length, 96.0);
  EXPECT_EQ(scene.cloth.plane, Plane::Horizontal);
  EXPECT_DOUBLE_EQ(scene.cloth.mass / scene.numNodes(), 6.0);  // 6 per node

  const auto& stretch = scene.springs[static_cast<int>(SpringType::Stretch)];
  const auto& shear = scene.springs[static_cast<int>(SpringType::Shear)];
  EXPECT_TRUE(stretch.enabled);
  EXPECT_EQ(stretch.stiffness, 100.0);
  EXPECT_EQ(stretch.damping, 0.8);
  EXPECT_TRUE(shear.enabled);
  EXPECT_EQ(shear.stiffness, 100.0);
  EXPECT_EQ(shear.damping, 0.8);
  EXPECT_FALSE(scene.springs[static_cast<int>(SpringType::Bend)].enabled);
  EXPECT_EQ(scene.damping_model, DampingModel::RelativeVelocity);

  EXPECT_EQ(scene.gravity.x(), 0.0);
  EXPECT_EQ(scene.gravity.y(), 0.0);
  EXPECT_DOUBLE_EQ(scene.gravity.z(), -9.8 / 6.0);
  // The two corners of one edge.
  EXPECT_EQ(scene.pins, (std::vector<int>{0, 15}));
  EXPECT_EQ(scene.solver.method, Method::ImplicitEuler);
  EXPECT_EQ(scene.solver.dt, 1.0 / 23.0);
  EXPECT_EQ(scene.solver.preconditioner, Preconditioner::None);
  EXPECT_EQ(scene.solver.tolerance, 1e-2);
}

// ------------------------------------------------------------- defaults ----

TEST(SceneDefaults, OnlyRowsAndColsAreNeeded) {
  const Scene scene = parseScene("cloth: {rows: 3, cols: 1}");
  const Scene defaults;
  EXPECT_EQ(scene.cloth.rows, 3);
  EXPECT_EQ(scene.cloth.cols, 1);
  EXPECT_EQ(scene.cloth.width, 1.0);
  EXPECT_EQ(scene.cloth.length, 1.0);
  EXPECT_EQ(scene.cloth.plane, Plane::Horizontal);
  EXPECT_EQ(scene.cloth.origin, Vec3(0, 0, 1.5));
  EXPECT_EQ(scene.cloth.mass, 0.3);
  EXPECT_TRUE(scene.cloth.node_mass.empty());
  for (int t = 0; t < kNumSpringTypes; ++t) {
    EXPECT_FALSE(scene.springs[t].enabled) << "springs absent => no springs at all";
  }
  EXPECT_EQ(scene.damping_model, DampingModel::AlongSpring);
  EXPECT_EQ(scene.gravity, Vec3(0, 0, -9.81));
  EXPECT_EQ(scene.air_drag, 0.0);
  EXPECT_TRUE(scene.pins.empty());
  // No method named: the automatic solver (SceneSolver.* pins its values).
  EXPECT_EQ(scene.solver.method, automaticSolver().method);
  EXPECT_EQ(scene.solver.dt, automaticSolver().dt);
  EXPECT_EQ(scene.solver.tolerance, automaticSolver().tolerance);
  EXPECT_EQ(scene.solver.error_tolerance, automaticSolver().error_tolerance);
  EXPECT_EQ(scene.solver.newton_max_iterations, automaticSolver().newton_max_iterations);
  EXPECT_EQ(scene.solver.max_iterations, 500);
  EXPECT_EQ(scene.solver.preconditioner, Preconditioner::Auto);
  EXPECT_TRUE(scene.solver.project_compression);
  EXPECT_EQ(scene.solver.newton_tolerance, 1e-8);
  EXPECT_EQ(scene.solver.max_halvings, 8);
  EXPECT_TRUE(scene.solver.recovery);
  EXPECT_EQ(scene.initial.stretch, 1.0);
  EXPECT_EQ(scene.initial.scatter, 0.0);
  EXPECT_EQ(scene.initial.seed, 0u);
  EXPECT_FALSE(scene.initial.collapse);
  EXPECT_TRUE(scene.events.empty());
  // The documented defaults are the struct's defaults; with a method named,
  // the solver's too.
  EXPECT_EQ(scene.cloth.mass, defaults.cloth.mass);
  const Scene named = parseScene("cloth: {rows: 3, cols: 1}\nsolver: {method: implicit_euler}");
  EXPECT_EQ(named.solver.method, Method::ImplicitEuler);
  EXPECT_EQ(named.solver.dt, 0.004);
  EXPECT_EQ(named.solver.dt, defaults.solver.dt);
  EXPECT_EQ(named.solver.tolerance, 1e-6);
  EXPECT_EQ(named.solver.newton_max_iterations, 20);
  EXPECT_FALSE(named.solver.error_tolerance.has_value());
}

TEST(SceneDefaults, NamedGroupWithoutValuesGetsGroupDefaults) {
  const Scene scene = parseScene("cloth: {rows: 4, cols: 4}\n"
                                 "springs: {stretch: {}, shear: ~, bend: {damping: 0.1}}\n");
  const auto& stretch = scene.springs[static_cast<int>(SpringType::Stretch)];
  const auto& shear = scene.springs[static_cast<int>(SpringType::Shear)];
  const auto& bend = scene.springs[static_cast<int>(SpringType::Bend)];
  EXPECT_TRUE(stretch.enabled);
  EXPECT_EQ(stretch.stiffness, 5000.0);
  EXPECT_EQ(stretch.damping, 2.0);
  EXPECT_TRUE(shear.enabled);
  EXPECT_EQ(shear.stiffness, 500.0);
  EXPECT_EQ(shear.damping, 0.5);
  EXPECT_TRUE(bend.enabled);
  EXPECT_EQ(bend.stiffness, 5.0);
  EXPECT_EQ(bend.damping, 0.1);
}

TEST(SceneDefaults, OnlyNamedGroupsArePresent) {
  const Scene scene = parseScene("cloth: {rows: 4, cols: 4}\n"
                                 "springs: {shear: {stiffness: 7}, damping_model: relative_velocity}\n");
  EXPECT_FALSE(scene.springs[static_cast<int>(SpringType::Stretch)].enabled);
  EXPECT_TRUE(scene.springs[static_cast<int>(SpringType::Shear)].enabled);
  EXPECT_EQ(scene.springs[static_cast<int>(SpringType::Shear)].stiffness, 7.0);
  EXPECT_FALSE(scene.springs[static_cast<int>(SpringType::Bend)].enabled);
  EXPECT_EQ(scene.damping_model, DampingModel::RelativeVelocity);
}

TEST(SceneDefaults, StiffnessZeroTurnsTheGroupOff) {
  const Scene scene = parseScene("cloth: {rows: 4, cols: 4}\n"
                                 "springs: {stretch: {stiffness: 100}, bend: {stiffness: 0}}\n");
  EXPECT_TRUE(scene.springs[static_cast<int>(SpringType::Stretch)].enabled);
  EXPECT_FALSE(scene.springs[static_cast<int>(SpringType::Bend)].enabled);
}

// ----------------------------------------------------- full schema parse ----

TEST(SceneParse, EveryFieldIsRead) {
  const Scene scene = parseScene(R"(
cloth:
  rows: 5
  cols: 3
  width: 2.0
  length: 4.0
  plane: vertical
  origin: [1, 2, 3]
  mass: 1.5
  node_mass: {14: 3.0, 2: 0.25}
springs:
  stretch: {stiffness: 10, damping: 1}
  bend: {stiffness: 2, damping: 0}
  damping_model: relative_velocity
gravity: [0, -1, 0]
air_drag: 0.01
pins: [0, 2]
solver:
  method: bdf2
  dt: 0.01
  tolerance: 1.0e-9
  max_iterations: 50
  preconditioner: none
  project_compression: false
  newton_tolerance: 1.0e-6
  newton_max_iterations: 7
  max_halvings: 0
  recovery: false
initial: {stretch: 3.0, scatter: 0.01, seed: 7, collapse: true}
)");
  EXPECT_EQ(scene.cloth.rows, 5);
  EXPECT_EQ(scene.cloth.cols, 3);
  EXPECT_EQ(scene.cloth.width, 2.0);
  EXPECT_EQ(scene.cloth.length, 4.0);
  EXPECT_EQ(scene.cloth.plane, Plane::Vertical);
  EXPECT_EQ(scene.cloth.origin, Vec3(1, 2, 3));
  EXPECT_EQ(scene.cloth.mass, 1.5);
  EXPECT_EQ(scene.cloth.node_mass, (std::map<int, double>{{14, 3.0}, {2, 0.25}}));
  EXPECT_EQ(scene.springs[0].stiffness, 10.0);
  EXPECT_EQ(scene.springs[0].damping, 1.0);
  EXPECT_FALSE(scene.springs[1].enabled);
  EXPECT_EQ(scene.springs[2].stiffness, 2.0);
  EXPECT_EQ(scene.damping_model, DampingModel::RelativeVelocity);
  EXPECT_EQ(scene.gravity, Vec3(0, -1, 0));
  EXPECT_EQ(scene.air_drag, 0.01);
  EXPECT_EQ(scene.pins, (std::vector<int>{0, 2}));
  EXPECT_EQ(scene.solver.method, Method::Bdf2);
  EXPECT_EQ(scene.solver.dt, 0.01);
  EXPECT_EQ(scene.solver.tolerance, 1e-9);
  EXPECT_EQ(scene.solver.max_iterations, 50);
  EXPECT_EQ(scene.solver.preconditioner, Preconditioner::None);
  EXPECT_FALSE(scene.solver.project_compression);
  EXPECT_EQ(scene.solver.newton_tolerance, 1e-6);
  EXPECT_EQ(scene.solver.newton_max_iterations, 7);
  EXPECT_EQ(scene.solver.max_halvings, 0);
  EXPECT_FALSE(scene.solver.recovery);
  EXPECT_EQ(scene.initial.stretch, 3.0);
  EXPECT_EQ(scene.initial.scatter, 0.01);
  EXPECT_EQ(scene.initial.seed, 7u);
  EXPECT_TRUE(scene.initial.collapse);
}

TEST(SceneParse, EventsOfEveryKind) {
  const Scene scene = parseScene(std::string(kWithEvents) +
                                 "  - {time: 2.5, release: [3, 4]}\n"
                                 "  - {time: 3.0, set_stiffness: {spring_type: all, stiffness: 10}}\n");
  ASSERT_EQ(scene.events.size(), 7u);
  const auto& stiffen = scene.events[0];
  EXPECT_EQ(stiffen.kind, SceneEvent::Kind::SetStiffness);
  EXPECT_EQ(stiffen.time, 0.5);
  EXPECT_FALSE(stiffen.all_types);
  EXPECT_EQ(stiffen.spring_type, SpringType::Stretch);
  EXPECT_EQ(stiffen.stiffness, 1e6);
  EXPECT_EQ(stiffen.damping, 3.0);

  const auto& jump = scene.events[1];
  EXPECT_EQ(jump.kind, SceneEvent::Kind::MovePin);
  EXPECT_EQ(jump.index, 0);
  ASSERT_TRUE(jump.position.has_value());
  EXPECT_EQ(*jump.position, Vec3(1, 0, 1.5));
  EXPECT_FALSE(jump.velocity.has_value());

  const auto& drag = scene.events[2];
  EXPECT_EQ(drag.kind, SceneEvent::Kind::MovePin);
  EXPECT_FALSE(drag.position.has_value());
  ASSERT_TRUE(drag.velocity.has_value());
  EXPECT_EQ(*drag.velocity, Vec3(10, 0, 0));
  EXPECT_EQ(drag.duration, 0.2);

  EXPECT_EQ(scene.events[3].kind, SceneEvent::Kind::Pin);
  EXPECT_EQ(scene.events[3].indices, (std::vector<int>{5, 6}));
  EXPECT_EQ(scene.events[4].kind, SceneEvent::Kind::Release);
  EXPECT_TRUE(scene.events[4].release_all);
  EXPECT_EQ(scene.events[5].kind, SceneEvent::Kind::Release);
  EXPECT_FALSE(scene.events[5].release_all);
  EXPECT_EQ(scene.events[5].indices, (std::vector<int>{3, 4}));
  EXPECT_TRUE(scene.events[6].all_types);
  EXPECT_EQ(scene.events[6].damping, -1.0) << "absent damping keeps the current one";
  EXPECT_EQ(scene.cloth.node_mass.at(575), 3.0);
  EXPECT_EQ(scene.initial.seed, 7u);
}

TEST(SceneParse, MovePinOfANodeNotPinnedIsAcceptedAtParseTime) {
  // Whether node 7 is pinned at t = 1 is the simulation's business.
  const Scene scene = parseScene(std::string(kBase) +
                                 "events: [{time: 1, move_pin: {index: 7, position: [0, 0, 0]}}]\n");
  EXPECT_EQ(scene.events.at(0).index, 7);
}

TEST(SceneParse, IntegersMayBeWrittenAsWholeNumbers) {
  const Scene scene = parseScene("cloth: {rows: 4.0, cols: +3}\nsolver: {max_iterations: 1e3}\n");
  EXPECT_EQ(scene.cloth.rows, 4);
  EXPECT_EQ(scene.cloth.cols, 3);
  EXPECT_EQ(scene.solver.max_iterations, 1000);
}

TEST(SceneParse, EmptyOptionalSectionsMeanDefaults) {
  const Scene scene = parseScene("cloth: {rows: 2, cols: 2}\nsolver:\ninitial:\nevents:\npins:\n");
  EXPECT_TRUE(scene.pins.empty());
  EXPECT_TRUE(scene.events.empty());
  EXPECT_EQ(scene.solver.dt, automaticSolver().dt);
}

// ----------------------------------------------------------- rejections ----

TEST(SceneRejects, MissingOrTooSmallGrid) {
  EXPECT_TRUE(rejects("", "cloth.rows: required"));
  EXPECT_TRUE(rejects("cloth: {cols: 3}", "cloth.rows: required"));
  EXPECT_TRUE(rejects("cloth: {rows: 3}", "cloth.cols: required"));
  EXPECT_TRUE(rejects("cloth: {rows: 1, cols: 3}", "cloth.rows: must be >= 2, got 1"));
  EXPECT_TRUE(rejects("cloth: {rows: -4, cols: 3}", "cloth.rows: must be >= 2", "-4"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 0}", "cloth.cols: must be >= 1, got 0"));
  EXPECT_TRUE(rejects("cloth: {rows: 2001, cols: 2000}", "cloth: rows * cols", "4002000"));
  EXPECT_TRUE(rejects("cloth: {rows: 1e10, cols: 2}", "cloth.rows: integer out of range", "1e10"));
  EXPECT_TRUE(rejects("cloth: {rows: 2.5, cols: 2}", "cloth.rows: expected an integer", "'2.5'"));
  EXPECT_TRUE(rejects("cloth: {rows: many, cols: 2}", "cloth.rows: expected an integer", "'many'"));
  EXPECT_TRUE(rejects("cloth: {rows: .nan, cols: 2}", "cloth.rows: expected an integer", "'.nan'"));
  // The largest grid allowed is accepted.
  EXPECT_EQ(errorOf("cloth: {rows: 2000, cols: 2000}"), "(accepted)");
}

TEST(SceneRejects, UnknownKeysAtEveryLevel) {
  EXPECT_TRUE(rejects(std::string(kBase) + "colour: red\n", "colour: unknown key"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, colour: red}", "cloth.colour: unknown key"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nsprings: {stretch: {stiffness: 1, colour: 2}}",
                      "springs.stretch.colour: unknown key"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nsprings: {twist: {stiffness: 1}}",
                      "springs.twist: unknown key"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nsolver: {dtt: 0.1}", "solver.dtt: unknown key"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\ninitial: {strech: 2}", "initial.strech: unknown key"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nevents: [{time: 1, release: all, when: 2}]",
                      "events[0].when: unknown key"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\npins: [0]\n"
                      "events: [{time: 1, move_pin: {index: 0, position: [0, 0, 0], speed: 1}}]",
                      "events[0].move_pin.speed: unknown key"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nsprings: {stretch: {}}\n"
                      "events: [{time: 1, set_stiffness: {spring_type: stretch, stiffness: 2, k: 1}}]",
                      "events[0].set_stiffness.k: unknown key"));
}

TEST(SceneRejects, DuplicateKeysAndWrongShapes) {
  EXPECT_TRUE(rejects("cloth: {rows: 3, rows: 4, cols: 2}", "cloth.rows: duplicate key"));
  EXPECT_TRUE(rejects("[1, 2]", "scene: expected a map", "a sequence"));
  EXPECT_TRUE(rejects("cloth: 5", "cloth: expected a map", "'5'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nsprings: {stretch: 5000}",
                      "springs.stretch: expected a map", "'5000'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, origin: [0, 0]}", "cloth.origin: expected 3 numbers",
                      "got 2"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, origin: 1}", "cloth.origin: expected 3 numbers",
                      "'1'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\ngravity: [0, 0, down]", "gravity[2]: expected a number",
                      "'down'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\npins: 4", "pins: expected a list of node indices",
                      "'4'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nevents: {time: 1}", "events: expected a list",
                      "a map"));
  EXPECT_TRUE(rejects("a: 1\n---\nb: 2\n", "expected one YAML document", "2"));
}

TEST(SceneRejects, NonNumericValues) {
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, mass: abc}", "cloth.mass: expected a number, got 'abc'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, mass: \"0.3\"}", "cloth.mass: expected a number",
                      "quoted string '0.3'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, mass: [1]}", "cloth.mass: expected a number",
                      "a sequence"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, mass: }", "cloth.mass: expected a number", "null"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, mass: 1.2.3}", "cloth.mass: expected a number",
                      "'1.2.3'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nsolver: {project_compression: maybe}",
                      "solver.project_compression: expected true or false, got 'maybe'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nsolver: {recovery: 1}",
                      "solver.recovery: expected true or false, got '1'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\ninitial: {collapse: yes please}",
                      "initial.collapse: expected true or false", "'yes please'"));
}

TEST(SceneRejects, NonFiniteNumbersEverywhere) {
  // Every floating-point field of the schema, reached through an override.
  const std::vector<std::string> fields = {
      "cloth.width", "cloth.length", "cloth.mass", "cloth.origin[0]", "cloth.origin[2]",
      "cloth.node_mass.575", "springs.stretch.stiffness", "springs.stretch.damping",
      "gravity[1]", "air_drag", "solver.dt", "solver.tolerance", "solver.newton_tolerance",
      "initial.stretch", "initial.scatter", "events[0].time",
      "events[0].set_stiffness.stiffness", "events[0].set_stiffness.damping",
      "events[1].move_pin.position[0]", "events[2].move_pin.velocity[2]",
      "events[2].move_pin.duration"};
  ASSERT_EQ(errorOf(kWithEvents), "(accepted)");
  for (const std::string& field : fields) {
    for (const char* value : {".nan", ".inf", "-.inf", ".NaN", "+.Inf", "nan", "inf"}) {
      EXPECT_TRUE(overrideRejects(kWithEvents, field + "=" + value,
                                  field + ": must be a finite number", std::string("'") + value + "'"))
          << field << "=" << value;
    }
  }
  // Directly in the file too.
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, mass: .nan}",
                      "cloth.mass: must be a finite number, got '.nan'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\ngravity: [0, 0, -.inf]",
                      "gravity[2]: must be a finite number, got '-.inf'"));
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3, mass: 1e400}",
                      "cloth.mass: must be a finite number, got '1e400'"));
  // Integer fields reject them as non-integers.
  for (const std::string field : {"cloth.rows", "cloth.cols", "pins[0]", "solver.max_iterations",
                                   "solver.newton_max_iterations", "solver.max_halvings",
                                   "initial.seed", "events[1].move_pin.index", "events[3].pin[1]"}) {
    EXPECT_TRUE(overrideRejects(kWithEvents, field + "=.inf", field + ": expected an integer",
                                "'.inf'"))
        << field;
  }
}

TEST(SceneRejects, NegativeAndZeroValues) {
  const std::string base = kBase;
  EXPECT_EQ(errorOf(base, {"springs.stretch.stiffness=-3"}),
            "springs.stretch.stiffness: must be > 0, got -3 (0 turns the group off)");
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3}\nsprings: {stretch: {stiffness: -3}}",
                      "springs.stretch.stiffness: must be > 0, got -3"));
  EXPECT_TRUE(overrideRejects(base, "springs.shear.damping=-0.5", "springs.shear.damping: must be >= 0",
                              "got -0.5"));
  EXPECT_TRUE(overrideRejects(base, "cloth.mass=0", "cloth.mass: must be > 0, got 0"));
  EXPECT_TRUE(overrideRejects(base, "cloth.mass=-1", "cloth.mass: must be > 0, got -1"));
  EXPECT_TRUE(overrideRejects(base, "cloth.width=0", "cloth.width: must be > 0, got 0"));
  EXPECT_TRUE(overrideRejects(base, "cloth.length=-2", "cloth.length: must be > 0, got -2"));
  EXPECT_TRUE(overrideRejects(base, "air_drag=-0.1", "air_drag: must be >= 0, got -0.1"));
  EXPECT_TRUE(overrideRejects(base, "solver.dt=0", "solver.dt: must be > 0, got 0"));
  EXPECT_TRUE(overrideRejects(base, "solver.dt=-0.004", "solver.dt: must be > 0, got -0.004"));
  EXPECT_TRUE(overrideRejects(base, "solver.tolerance=0", "solver.tolerance: must be > 0, got 0"));
  EXPECT_TRUE(overrideRejects(base, "solver.tolerance=1", "solver.tolerance: must be < 1", "got 1"));
  EXPECT_TRUE(overrideRejects(base, "solver.tolerance=1.5", "solver.tolerance: must be < 1", "got 1.5"));
  EXPECT_TRUE(overrideRejects(base, "solver.newton_tolerance=2", "solver.newton_tolerance: must be < 1",
                              "got 2"));
  EXPECT_TRUE(overrideRejects(base, "solver.newton_tolerance=-1e-8",
                              "solver.newton_tolerance: must be > 0", "got -1e-08"));
  EXPECT_TRUE(overrideRejects(base, "solver.max_iterations=0",
                              "solver.max_iterations: must be >= 1, got 0"));
  EXPECT_TRUE(overrideRejects(base, "solver.newton_max_iterations=-2",
                              "solver.newton_max_iterations: must be >= 1, got -2"));
  EXPECT_TRUE(overrideRejects(base, "solver.max_halvings=-1", "solver.max_halvings: must be >= 0, got -1"));
  EXPECT_TRUE(overrideRejects(base, "solver.max_halvings=31", "solver.max_halvings: must be <= 30, got 31"));
  EXPECT_TRUE(overrideRejects(base, "initial.stretch=0", "initial.stretch: must be > 0, got 0"));
  EXPECT_TRUE(overrideRejects(base, "initial.stretch=-3", "initial.stretch: must be > 0, got -3"));
  EXPECT_TRUE(overrideRejects(base, "initial.scatter=-0.01", "initial.scatter: must be >= 0, got -0.01"));
  EXPECT_TRUE(overrideRejects(base, "initial.seed=-1", "initial.seed: integer out of range", "'-1'"));
  // Zero is fine where >= 0 is the rule.
  EXPECT_EQ(errorOf(base, {"initial.scatter=0"}), "(accepted)");
  EXPECT_EQ(errorOf(base, {"air_drag=0"}), "(accepted)");
  EXPECT_EQ(errorOf(base, {"solver.max_halvings=0"}), "(accepted)");
}

TEST(SceneRejects, UnknownNames) {
  const std::string base = kBase;
  EXPECT_EQ(errorOf(base, {"solver.method=rk4"}),
            "solver.method: unknown method 'rk4' (expected implicit_euler, newton, bdf2, "
            "symplectic_euler)");
  EXPECT_TRUE(overrideRejects(base, "cloth.plane=diagonal", "cloth.plane: unknown plane 'diagonal'",
                              "horizontal, vertical"));
  EXPECT_TRUE(overrideRejects(base, "springs.damping_model=viscous",
                              "springs.damping_model: unknown damping model 'viscous'",
                              "along_spring, relative_velocity"));
  EXPECT_TRUE(overrideRejects(base, "solver.preconditioner=ilu",
                              "solver.preconditioner: unknown preconditioner 'ilu'",
                              "none, block_jacobi, cholesky"));
  EXPECT_EQ(parseScene(base, {"solver.preconditioner=cholesky"}).solver.preconditioner,
            Preconditioner::Cholesky);
  EXPECT_EQ(parseScene(base, {"solver.preconditioner=none"}).solver.preconditioner,
            Preconditioner::None);
  EXPECT_TRUE(overrideRejects(base, "solver.method=[newton]", "solver.method: expected a name",
                              "a sequence"));
}

TEST(SceneRejects, Pins) {
  const std::string base = "cloth: {rows: 24, cols: 24}\n";
  EXPECT_EQ(errorOf(base + "pins: [0, 23, 600]"), "pins[2]: index 600 out of range [0, 575]");
  EXPECT_TRUE(rejects(base + "pins: [-1]", "pins[0]: index -1 out of range [0, 575]"));
  EXPECT_TRUE(rejects(base + "pins: [576]", "pins[0]: index 576 out of range [0, 575]"));
  EXPECT_TRUE(rejects(base + "pins: [0, 5, 23, 5]", "pins[3]: duplicate node 5", "pins[1]"));
  EXPECT_TRUE(rejects(base + "pins: [0, 1.5]", "pins[1]: expected an integer", "'1.5'"));
  EXPECT_EQ(errorOf(base + "pins: [575]"), "(accepted)");
}

TEST(SceneRejects, NodeMass) {
  const std::string base = "cloth: {rows: 24, cols: 24, node_mass: ";
  EXPECT_TRUE(rejects(base + "{600: 3.0}}", "cloth.node_mass.600: index 600 out of range [0, 575]"));
  EXPECT_TRUE(rejects(base + "{-1: 3.0}}", "cloth.node_mass.-1: index -1 out of range"));
  EXPECT_TRUE(rejects(base + "{5: 0}}", "cloth.node_mass.5: must be > 0, got 0"));
  EXPECT_TRUE(rejects(base + "{5: -2}}", "cloth.node_mass.5: must be > 0, got -2"));
  EXPECT_TRUE(rejects(base + "{five: 1}}", "cloth.node_mass.five: expected an integer", "'five'"));
  EXPECT_TRUE(rejects(base + "{5: 1, 05: 2}}", "cloth.node_mass.05: duplicate node 5"));
  EXPECT_TRUE(rejects(base + "[5, 1]}", "cloth.node_mass: expected a map", "a sequence"));
}

TEST(SceneRejects, Initial) {
  const std::string base = "cloth: {rows: 4, cols: 4}\n";
  EXPECT_TRUE(rejects(base + "initial: {stretch: 0}", "initial.stretch: must be > 0, got 0"));
  EXPECT_TRUE(rejects(base + "initial: {stretch: -1.5}", "initial.stretch: must be > 0, got -1.5"));
  EXPECT_TRUE(rejects(base + "initial: {scatter: -0.01}", "initial.scatter: must be >= 0, got -0.01"));
  EXPECT_TRUE(rejects(base + "initial: {seed: 1.5}", "initial.seed: expected an integer", "'1.5'"));
  EXPECT_TRUE(rejects(base + "initial: {seed: 4294967296}", "initial.seed: integer out of range",
                      "'4294967296'"));
}

TEST(SceneRejects, EventOrderAndTime) {
  const std::string base = "cloth: {rows: 4, cols: 4}\npins: [0]\nevents:\n";
  EXPECT_TRUE(rejects(base + "  - {time: 1.0, release: all}\n  - {time: 0.5, pin: [1]}\n",
                      "events[1].time: events must be in time order", "got 0.5 after 1"));
  EXPECT_TRUE(rejects(base + "  - {time: -0.1, release: all}\n", "events[0].time: must be >= 0, got -0.1"));
  EXPECT_TRUE(rejects(base + "  - {release: all}\n", "events[0].time: required"));
  EXPECT_TRUE(rejects(base + "  - {time: 1}\n", "events[0]: expected exactly one action", "got none"));
  EXPECT_TRUE(rejects(base + "  - {time: 1, pin: [1], release: all}\n",
                      "events[0]: expected exactly one action", "got 2: pin, release"));
  EXPECT_TRUE(rejects(base + "  - 3\n", "events[0]: expected a map", "'3'"));
  EXPECT_TRUE(rejects(base + "  -\n", "events[0]: expected a map"));
  // Equal times are allowed and keep file order.
  const Scene scene = parseScene(base + "  - {time: 1, pin: [1]}\n  - {time: 1, release: [1]}\n");
  EXPECT_EQ(scene.events[0].kind, SceneEvent::Kind::Pin);
  EXPECT_EQ(scene.events[1].kind, SceneEvent::Kind::Release);
}

TEST(SceneRejects, SetStiffnessEvent) {
  const std::string base =
      "cloth: {rows: 4, cols: 4}\nsprings: {stretch: {}}\nevents:\n  - {time: 1, set_stiffness: ";
  EXPECT_TRUE(rejects(base + "{stiffness: 5}}\n", "events[0].set_stiffness.spring_type: required"));
  EXPECT_TRUE(rejects(base + "{spring_type: twist, stiffness: 5}}\n",
                      "events[0].set_stiffness.spring_type: unknown spring type 'twist'",
                      "stretch, shear, bend, all"));
  EXPECT_TRUE(rejects(base + "{spring_type: stretch}}\n", "events[0].set_stiffness.stiffness: required"));
  EXPECT_TRUE(rejects(base + "{spring_type: stretch, stiffness: 0}}\n",
                      "events[0].set_stiffness.stiffness: must be > 0, got 0"));
  EXPECT_TRUE(rejects(base + "{spring_type: stretch, stiffness: -5}}\n",
                      "events[0].set_stiffness.stiffness: must be > 0, got -5"));
  EXPECT_TRUE(rejects(base + "{spring_type: stretch, stiffness: 5, damping: -1}}\n",
                      "events[0].set_stiffness.damping: must be >= 0, got -1"));
  EXPECT_TRUE(rejects(base + "{spring_type: bend, stiffness: 5}}\n",
                      "events[0].set_stiffness.spring_type: the scene has no bend springs"));
  EXPECT_TRUE(rejects(base + "5}\n", "events[0].set_stiffness: expected a map", "'5'"));
  EXPECT_EQ(errorOf(base + "{spring_type: all, stiffness: 5, damping: 0}}\n"), "(accepted)");
}

TEST(SceneRejects, MovePinEvent) {
  const std::string base = "cloth: {rows: 24, cols: 24}\npins: [0]\nevents:\n  - {time: 1, move_pin: ";
  EXPECT_TRUE(rejects(base + "{position: [0, 0, 0]}}\n", "events[0].move_pin.index: required"));
  EXPECT_TRUE(rejects(base + "{index: 600, position: [0, 0, 0]}}\n",
                      "events[0].move_pin.index: index 600 out of range [0, 575]"));
  EXPECT_TRUE(rejects(base + "{index: 0}}\n", "events[0].move_pin: expected position, velocity"));
  EXPECT_TRUE(rejects(base + "{index: 0, velocity: [1, 0, 0]}}\n",
                      "events[0].move_pin.duration: required with velocity"));
  EXPECT_TRUE(rejects(base + "{index: 0, position: [0, 0, 0], duration: 1}}\n",
                      "events[0].move_pin.duration: only applies with velocity"));
  EXPECT_TRUE(rejects(base + "{index: 0, velocity: [1, 0, 0], duration: 0}}\n",
                      "events[0].move_pin.duration: must be > 0, got 0"));
  EXPECT_TRUE(rejects(base + "{index: 0, velocity: [1, 0, 0], duration: -1}}\n",
                      "events[0].move_pin.duration: must be >= 0, got -1"));
  EXPECT_TRUE(rejects(base + "{index: 0, position: [0, 0]}}\n",
                      "events[0].move_pin.position: expected 3 numbers", "got 2"));
  EXPECT_EQ(errorOf(base + "{index: 0, position: [0, 0, 1], velocity: [1, 0, 0], duration: 2}}\n"),
            "(accepted)");
}

TEST(SceneRejects, PinAndReleaseEvents) {
  const std::string base = "cloth: {rows: 24, cols: 24}\npins: [0]\nevents:\n  - {time: 1, ";
  EXPECT_TRUE(rejects(base + "pin: [5, 600]}\n", "events[0].pin[1]: index 600 out of range [0, 575]"));
  EXPECT_TRUE(rejects(base + "pin: [5, 5]}\n", "events[0].pin[1]: duplicate node 5"));
  EXPECT_TRUE(rejects(base + "pin: []}\n", "events[0].pin: must list at least one node"));
  EXPECT_TRUE(rejects(base + "pin: 5}\n", "events[0].pin: expected a list of node indices", "'5'"));
  EXPECT_TRUE(rejects(base + "release: some}\n", "events[0].release: expected 'all' or a list",
                      "'some'"));
  EXPECT_TRUE(rejects(base + "release: [-3]}\n", "events[0].release[0]: index -3 out of range"));
  EXPECT_TRUE(rejects(base + "release: []}\n", "events[0].release: must list at least one node"));
}

// ------------------------------------------------------------ overrides ----

TEST(SceneOverrides, SetScalarsListsAndNewMaps) {
  const Scene scene = parseScene(kBase, {"solver.dt=0.001", "pins=[0, 5]", "solver.method=newton",
                                         "cloth.node_mass.7=2.5", "initial.stretch=3",
                                         " gravity = [0, 0, -1] ", "solver.project_compression=false"});
  EXPECT_EQ(scene.solver.dt, 0.001);
  EXPECT_EQ(scene.pins, (std::vector<int>{0, 5}));
  EXPECT_EQ(scene.solver.method, Method::Newton);
  EXPECT_EQ(scene.cloth.node_mass.at(7), 2.5);
  EXPECT_EQ(scene.initial.stretch, 3.0);
  EXPECT_EQ(scene.gravity, Vec3(0, 0, -1));
  EXPECT_FALSE(scene.solver.project_compression);
}

TEST(SceneOverrides, LaterOverridesWinAndFlowMapsReplace) {
  const Scene scene = parseScene(kBase, {"solver.dt=0.1", "solver.dt=0.2",
                                         "springs.shear={stiffness: 9}"});
  EXPECT_EQ(scene.solver.dt, 0.2);
  EXPECT_EQ(scene.springs[static_cast<int>(SpringType::Shear)].stiffness, 9.0);
  EXPECT_EQ(scene.springs[static_cast<int>(SpringType::Shear)].damping, 0.5) << "group default";
}

TEST(SceneOverrides, CreateAbsentSectionsAndGroups) {
  const Scene scene = parseScene("cloth: {rows: 4, cols: 4}",
                                 {"springs.bend.stiffness=2", "solver.max_halvings=3"});
  const auto& bend = scene.springs[static_cast<int>(SpringType::Bend)];
  EXPECT_TRUE(bend.enabled);
  EXPECT_EQ(bend.stiffness, 2.0);
  EXPECT_EQ(bend.damping, 0.0);
  EXPECT_FALSE(scene.springs[static_cast<int>(SpringType::Stretch)].enabled);
  EXPECT_EQ(scene.solver.max_halvings, 3);
  // Even the required fields can come from overrides alone.
  EXPECT_EQ(parseScene("", {"cloth.rows=2", "cloth.cols=1"}).numNodes(), 2);
}

TEST(SceneOverrides, IndexIntoSequences) {
  const Scene scene = parseScene(kWithEvents, {"events[0].time=0.7", "pins[1]=22",
                                               "events[1].move_pin.position[2]=2"});
  EXPECT_EQ(scene.events[0].time, 0.7);
  EXPECT_EQ(scene.pins, (std::vector<int>{0, 22}));
  EXPECT_EQ(*scene.events[1].position, Vec3(1, 0, 2));
}

TEST(SceneOverrides, StiffnessZeroDisablesAGroup) {
  const Scene scene = loadScene(kSourceDir + "/config/demo.yaml", {"springs.bend.stiffness=0"});
  EXPECT_FALSE(scene.springs[static_cast<int>(SpringType::Bend)].enabled);
  EXPECT_TRUE(scene.springs[static_cast<int>(SpringType::Stretch)].enabled);
  EXPECT_TRUE(scene.springs[static_cast<int>(SpringType::Shear)].enabled);
  // An event that needs the switched-off group is then an error.
  EXPECT_TRUE(overrideRejects(std::string(kBase) +
                                  "events: [{time: 1, set_stiffness: {spring_type: bend, stiffness: 9}}]",
                              "springs.bend.stiffness=0",
                              "events[0].set_stiffness.spring_type: the scene has no bend springs"));
  // Negative stays an error.
  EXPECT_TRUE(overrideRejects(kBase, "springs.bend.stiffness=-1",
                              "springs.bend.stiffness: must be > 0, got -1"));
}

TEST(SceneOverrides, BadOverridesAreRejected) {
  EXPECT_EQ(errorOf(kBase, {"solver.dt"}),
            "override 'solver.dt': expected key.path=value, e.g. solver.dt=0.001");
  EXPECT_TRUE(overrideRejects(kBase, "=3", "override '=3': malformed key path"));
  EXPECT_TRUE(overrideRejects(kBase, "solver..dt=3", "override 'solver..dt=3': malformed key path"));
  EXPECT_TRUE(overrideRejects(kBase, "solver.dt.=3", "override 'solver.dt.=3': malformed key path"));
  EXPECT_TRUE(overrideRejects(kBase, "pins[x]=3", "override 'pins[x]=3': malformed key path"));
  EXPECT_TRUE(overrideRejects(kBase, "pins[]=3", "override 'pins[]=3': malformed key path"));
  EXPECT_TRUE(overrideRejects(kBase, "pins=[0,", "override 'pins=[0,': cannot parse the value"));
  EXPECT_TRUE(overrideRejects(kBase, "cloth.rows.x=3", "override 'cloth.rows.x=3': cloth.rows is not a map"));
  EXPECT_TRUE(overrideRejects(kBase, "pins[5]=3", "override 'pins[5]=3': pins has no element [5]"));
  EXPECT_TRUE(overrideRejects(kBase, "solver[0]=3", "override 'solver[0]=3': solver has no element [0]"));
  // Well-formed overrides with bad content get the field's own message.
  EXPECT_TRUE(overrideRejects(kBase, "solver.dtt=0.1", "solver.dtt: unknown key"));
  EXPECT_TRUE(overrideRejects(kBase, "solver.dt=fast", "solver.dt: expected a number, got 'fast'"));
  EXPECT_TRUE(overrideRejects(kBase, "solver.dt=", "solver.dt: expected a number", "null"));
  EXPECT_TRUE(overrideRejects(kBase, "pins=[0, 0]", "pins[1]: duplicate node 0"));
}

// --------------------------------------------------------------- files ----

std::string writeTempFile(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

TEST(SceneLoad, UnreadableFile) {
  const std::string missing = ::testing::TempDir() + "cloth_sim_no_such_scene.yaml";
  std::remove(missing.c_str());
  try {
    loadScene(missing);
    FAIL() << "accepted a missing file";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), missing + ": cannot read file");
  }
  const std::string directory = kSourceDir + "/config";
  try {
    loadScene(directory);
    FAIL() << "accepted a directory";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), directory + ": cannot read file");
  }
}

TEST(SceneLoad, SyntaxErrorNamesFileLineAndColumn) {
  const std::string path =
      writeTempFile("cloth_sim_bad_syntax.yaml", "cloth: {rows: 3, cols: 3}\npins: [0, 1\nsolver: {}\n");
  try {
    loadScene(path);
    FAIL() << "accepted bad YAML";
  } catch (const SceneError& e) {
    const std::string message = e.what();
    EXPECT_TRUE(messageIs(message, path + ": YAML syntax error at line ", "column"));
    EXPECT_NE(message.find("line 3"), std::string::npos) << message;
  }
  std::remove(path.c_str());
  EXPECT_TRUE(rejects("cloth: {rows: 3, cols: 3\n", "YAML syntax error at line 2, column 1"));
}

TEST(SceneLoad, FieldErrorsFromAFileStartWithTheFieldPath) {
  const std::string path = writeTempFile("cloth_sim_bad_field.yaml", "cloth: {rows: 1, cols: 3}\n");
  try {
    loadScene(path);
    FAIL() << "accepted rows: 1";
  } catch (const SceneError& e) {
    EXPECT_EQ(std::string(e.what()), "cloth.rows: must be >= 2, got 1");
  }
  std::remove(path.c_str());
}

// -------------------------------------------- validating built scenes ----

TEST(SceneValidate, ParsedScenesPass) {
  EXPECT_NO_THROW(validateScene(validScene()));
  EXPECT_NO_THROW(validateScene(parseScene(kWithEvents)));
}

TEST(SceneValidate, ChecksScenesBuiltInCode) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  {
    Scene scene;  // rows and cols have no default
    EXPECT_EQ(validationErrorOf(scene), "cloth.rows: must be >= 2, got 0");
  }
  {
    Scene scene = validScene();
    scene.springs[static_cast<int>(SpringType::Shear)].stiffness = 0.0;
    EXPECT_TRUE(messageIs(validationErrorOf(scene), "springs.shear.stiffness: must be > 0", "got 0"));
    scene.springs[static_cast<int>(SpringType::Shear)].enabled = false;
    EXPECT_EQ(validationErrorOf(scene), "(accepted)") << "a disabled group may have stiffness 0";
  }
  {
    Scene scene = validScene();
    scene.springs[static_cast<int>(SpringType::Bend)].damping = -1.0;
    EXPECT_EQ(validationErrorOf(scene), "springs.bend.damping: must be >= 0, got -1");
  }
  {
    Scene scene = validScene();
    scene.gravity.z() = nan;
    EXPECT_EQ(validationErrorOf(scene), "gravity[2]: must be a finite number, got nan");
  }
  {
    Scene scene = validScene();
    scene.cloth.mass = std::numeric_limits<double>::infinity();
    EXPECT_EQ(validationErrorOf(scene), "cloth.mass: must be a finite number, got inf");
  }
  {
    Scene scene = validScene();
    scene.pins = {0, 576};
    EXPECT_EQ(validationErrorOf(scene), "pins[1]: index 576 out of range [0, 575]");
  }
  {
    Scene scene = validScene();
    scene.cloth.node_mass[-2] = 1.0;
    EXPECT_EQ(validationErrorOf(scene), "cloth.node_mass.-2: index -2 out of range [0, 575]");
  }
  {
    Scene scene = validScene();
    scene.solver.dt = 0.0;
    EXPECT_EQ(validationErrorOf(scene), "solver.dt: must be > 0, got 0");
  }
  {
    Scene scene = validScene();
    scene.initial.scatter = nan;
    EXPECT_EQ(validationErrorOf(scene), "initial.scatter: must be a finite number, got nan");
  }
}

TEST(SceneValidate, ChecksEventsBuiltInCode) {
  Scene scene = validScene();
  SceneEvent stiffen;
  stiffen.kind = SceneEvent::Kind::SetStiffness;
  stiffen.time = 1.0;
  stiffen.spring_type = SpringType::Stretch;
  stiffen.stiffness = 10.0;
  stiffen.damping = -1.0;  // keep the current damping
  scene.events = {stiffen};
  EXPECT_EQ(validationErrorOf(scene), "(accepted)");

  scene.events[0].damping = -2.0;
  EXPECT_TRUE(messageIs(validationErrorOf(scene), "events[0].set_stiffness.damping: must be >= 0",
                        "got -2"));
  scene.events[0].damping = 1.0;

  SceneEvent early = stiffen;
  early.time = 0.5;
  scene.events.push_back(early);
  EXPECT_EQ(validationErrorOf(scene), "events[1].time: events must be in time order, got 0.5 after 1");

  SceneEvent move;
  move.kind = SceneEvent::Kind::MovePin;
  move.time = 2.0;
  move.index = 0;
  move.velocity = Vec3(1, 0, 0);
  move.duration = 0.0;
  scene.events = {stiffen, move};
  EXPECT_EQ(validationErrorOf(scene), "events[1].move_pin.duration: must be > 0, got 0");
  scene.events[1].duration = 0.5;
  EXPECT_EQ(validationErrorOf(scene), "(accepted)");
  scene.events[1].velocity.reset();
  scene.events[1].duration = 0.0;
  EXPECT_TRUE(messageIs(validationErrorOf(scene), "events[1].move_pin: expected position", ""));

  SceneEvent release;
  release.kind = SceneEvent::Kind::Release;
  release.time = 3.0;
  scene.events = {release};
  EXPECT_EQ(validationErrorOf(scene), "events[0].release: must list at least one node");
  scene.events[0].release_all = true;
  EXPECT_EQ(validationErrorOf(scene), "(accepted)");
}

}  // namespace
}  // namespace cloth_sim
