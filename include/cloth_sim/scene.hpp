// A scene: everything that defines a simulation, parsed and validated from YAML.
// One schema for the CLI and the ROS node. Units SI, z up (REP 103).
#pragma once

#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// Thrown for any invalid scene; what() names the field, e.g.
/// "springs.stretch.stiffness: must be > 0, got -3".
class SceneError : public std::runtime_error {
 public:
  /// Control characters in the message (keys and values come from untrusted
  /// text) are written as \xNN, so what() is the whole message, printable.
  explicit SceneError(const std::string& message);
};

struct SpringGroupParams {
  bool enabled = false;    ///< absent from the scene -> absent from the model
  double stiffness = 0.0;  ///< N/m, > 0 when enabled
  double damping = 0.0;    ///< N*s/m, >= 0
};

/// A rigid shape the cloth's nodes cannot enter (docs/scene.md, "colliders").
struct ColliderParams {
  enum class Type { Plane, Sphere, Box, Capsule };
  std::string name;                   ///< unique; empty: "colliders[k]"
  Type type = Type::Plane;
  Vec3 point = Vec3::Zero();          ///< plane: a point on it
  Vec3 normal = Vec3::UnitZ();        ///< plane: outward normal (normalised when read)
  Vec3 center = Vec3::Zero();         ///< sphere, box
  double radius = 0.0;                ///< sphere, capsule: > 0
  Vec3 half_extents = Vec3::Zero();   ///< box: > 0 each
  Vec3 rpy = Vec3::Zero();            ///< box: roll, pitch, yaw (rad, REP 103)
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();  ///< capsule: segment ends
  std::optional<double> friction;     ///< Coulomb mu >= 0; absent: contact.friction
  std::string frame;                  ///< node only: pose relative to this tf frame
};
const char* toString(ColliderParams::Type type);

/// An action applied between steps at simulated time `time`.
struct SceneEvent {
  enum class Kind { SetStiffness, MovePin, Pin, Release, MoveCollider };
  double time = 0.0;
  Kind kind = Kind::SetStiffness;
  // set_stiffness
  bool all_types = false;          ///< spring_type: all
  SpringType spring_type = SpringType::Stretch;
  double stiffness = 0.0;
  double damping = -1.0;           ///< < 0 keeps the current damping
  // move_pin
  int index = -1;
  std::optional<Vec3> position;    ///< jump the target here
  std::optional<Vec3> velocity;    ///< drive the target at this velocity ...
  double duration = 0.0;           ///< ... for this long (s)
  // pin / release
  std::vector<int> indices;
  bool release_all = false;
  // move_collider (position, velocity, duration as move_pin)
  std::string collider;
};

struct Scene {
  struct Cloth {
    int rows = 0;  ///< required, >= 2
    int cols = 0;  ///< required, >= 1 (one column is a chain)
    double width = 1.0;   ///< extent along the columns (+x), m
    double length = 1.0;  ///< extent along the rows (-y or -z), m
    Plane plane = Plane::Horizontal;
    Vec3 origin = Vec3(0.0, 0.0, 1.5);  ///< position of node 0
    double mass = 0.3;                  ///< total, spread equally, kg
    std::map<int, double> node_mass;    ///< per-node overrides, kg
  } cloth;

  std::array<SpringGroupParams, kNumSpringTypes> springs{};  ///< by SpringType
  DampingModel damping_model = DampingModel::AlongSpring;
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);  ///< m/s^2; zero turns it off
  double air_drag = 0.0;                 ///< N*s/m per node; zero turns it off
  std::vector<int> pins;                 ///< node indices held at their start

  struct Solver {
    Method method = Method::ImplicitEuler;
    double dt = 0.004;             ///< s
    double tolerance = 1e-6;       ///< CG stop: ||r|| <= tolerance * ||b||
    int max_iterations = 500;      ///< CG cap
    Preconditioner preconditioner = Preconditioner::Auto;
    int multigrid_reuse = 4;       ///< multigrid: solves one hierarchy may serve (1: rebuilt every solve)
    bool project_compression = true;
    double newton_tolerance = 1e-8;   ///< newton/bdf2: ||g|| <= tol * ||g0||
    int newton_max_iterations = 20;
    int max_halvings = 8;          ///< recovery: a rejected step splits at most this deep
    bool recovery = true;
    /// Threads a step's large loops run on (the spring sweeps, the matrix
    /// product, the multigrid's smoother and transfers; OpenMP), 1..64. The
    /// one-thread answer is the reference: more threads give the same answer
    /// except through the multigrid smoother (its parts are relaxed side by
    /// side), within the CG tolerance.
    int threads = 1;
    /// Error-controlled stepping (step_size_control.hpp): when set, each
    /// step's local position error estimate, RMS over the free nodes and
    /// relative to the cloth's diagonal, is held within error_tolerance * h / 1 s
    /// (error per unit step: the global error after t seconds is about
    /// error_tolerance * t where errors add up, less where the cloth damps
    /// them). dt is then the first step, dt_min and dt_max the bounds.
    std::optional<double> error_tolerance;
    double dt_min = 1e-5;  ///< s; only with error_tolerance
    double dt_max = 0.05;  ///< s; only with error_tolerance
  } solver;

  /// Contact defaults for every collider.
  struct Contact {
    double thickness = 0.002;  ///< m, >= 0: nodes keep this far from every surface
    double friction = 0.3;     ///< Coulomb mu >= 0 (static = kinetic)
    /// m/s, >= 0. 0: exact stick/slip states throughout. > 0: Coulomb's
    /// law smoothed below this slip speed (IPC's f1, Li et al. 2020) in
    /// every step where a contact slides, so one solve finds which nodes
    /// slide (docs/design.md "Friction: exact at rest, smoothed in motion").
    double friction_smoothing = 1.0e-3;
    /// With friction_smoothing > 0: true, a contact that ends a step slipping
    /// slower than friction_smoothing sticks exactly (held to its surface)
    /// until a force beyond its cone moves it (with self_collision enabled: exact
    /// stick/slip states throughout, friction_smoothing unused); false, no
    /// stick state ever (a node under a load inside its cone creeps at under
    /// friction_smoothing).
    bool exact_sticking = true;
  } contact;
  std::vector<ColliderParams> colliders;  ///< none: no contact code runs

  /// The cloth against itself (self_collision.hpp). Disabled: no
  /// self-collision code runs at all.
  struct SelfCollision {
    bool enabled = false;
    double thickness = 0.002;  ///< m, > 0 when enabled: non-adjacent parts keep this far apart
    double friction = 0.2;     ///< Coulomb mu >= 0 between layers
  } self_collision;

  struct Initial {
    Vec3 velocity = Vec3::Zero();  ///< uniform initial velocity, m/s
    double stretch = 1.0;  ///< scale about the centroid at t = 0
    double scatter = 0.0;  ///< random offset within a cube of this size, m
    unsigned seed = 0;
    bool collapse = false; ///< all nodes at the centroid
  } initial;

  std::vector<SceneEvent> events;  ///< sorted by time

  int numNodes() const { return cloth.rows * cloth.cols; }
};

/// The solver of a scene file that names no `solver.method` (docs/scene.md,
/// "solver"): linearly implicit bdf2 (one Newton iteration a step) at a
/// fixed dt of 1/160 s, CG to 1e-2 with the automatic preconditioner. On the
/// benchmark's hang32 and hang64 it costs within 1.5x of the cheapest setting
/// at its error (~1e-3; docs/benchmark.md), and a stiff cloth (stretch up to
/// 1e9) still runs faster than real time (an error-controlled default did
/// not: docs/stability.md). Fields the scene names override it. A
/// default-constructed Scene::Solver is the plain implicit_euler of the table.
Scene::Solver automaticSolver();

/// Parses and validates YAML text. Throws SceneError naming the field.
Scene parseScene(const std::string& yaml_text,
                 const std::vector<std::string>& overrides = {});
/// Reads a file, then parseScene. Throws SceneError (also for unreadable files).
Scene loadScene(const std::string& path,
                const std::vector<std::string>& overrides = {});
/// Checks every field of an already built Scene (as parseScene does).
void validateScene(const Scene& scene);

}  // namespace cloth_sim
