// cloth_sim_bench: the work-precision benchmark of one scene (docs/benchmark.md).
//
//   cloth_sim_bench SCENE.yaml --settings FILE.csv --out RESULTS.csv
//                   [--name NAME] [--set key=value]... [--repeats N] [--duration S]
//                   [--sample S] [--ref-dt H] [--ref-preconditioner P] [--ref-cg-tol T]
//                   [--ref-newton-tol T] [--ref-newton-iterations N]
//                   [--solver-error-states K] [--converged-preconditioner P]
//                   [--no-reference] [--append]
//
// For every setting in FILE.csv (header: method,dt,tolerance,preconditioner,
// newton_iterations,newton_tolerance; method bullet runs the Bullet peer) it
// runs the scene from rest for --duration simulated seconds and writes one CSV
// row: CPU seconds per simulated second (median of --repeats timed runs after
// an untimed one) and its parts, work counts, the trajectory error against the
// project's own reference, the one-step solver error, max strain and energy
// drift. The reference (bdf2, Newton to --ref-newton-tol relative, CG to
// --ref-cg-tol) is run at --ref-dt and --ref-dt / 2; the finer one is the
// reference, and the two must differ by less than a tenth of the smallest error
// measured, else the exit status is 1. Newton's relative residual cannot go much
// below 1e-10 in double precision on these scenes (round-off in the spring
// forces), hence the default 1e-10 rather than 1e-12.
//
// Exit status: 0 success, 1 reference not converged, 2 bad input.
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cloth_sim/collider.hpp"
#include "cloth_sim/contact.hpp"
#include "cloth_sim/forces.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"
#include "cloth_sim/stepper.hpp"
#include "command_line.hpp"
#include "rest_diagonal.hpp"
#ifdef CLOTH_SIM_HAVE_BULLET
#include "bullet_peer.hpp"
#include "bullet_scene.hpp"
#endif

namespace {

using cloth_sim::bench::parseCount;
using cloth_sim::bench::parseNumber;
using cloth_sim::bench::restDiagonal;
using cloth_sim::bench::UsageError;
using cloth_sim::Method;
using cloth_sim::Model;
using cloth_sim::Preconditioner;
using cloth_sim::Scene;
using cloth_sim::Simulation;
using cloth_sim::StepStats;
using cloth_sim::Vec3;
using cloth_sim::VecX;

constexpr int kExitOk = 0;
constexpr int kExitReferenceNotConverged = 1;
constexpr int kExitBadInput = 2;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const char* const kUsage =
    "usage: cloth_sim_bench SCENE.yaml --settings FILE.csv --out RESULTS.csv\n"
    "                       [--name NAME] [--set key=value]... [--repeats N] [--duration S]\n"
    "                       [--sample S] [--ref-dt H] [--ref-preconditioner P]\n"
    "                       [--ref-cg-tol T] [--ref-newton-tol T] [--ref-newton-iterations N]\n"
    "                       [--solver-error-states K] [--converged-preconditioner P]\n"
    "                       [--no-reference] [--append]\n";

// ------------------------------------------------------------- parsing ----

std::vector<std::string> splitCsvLine(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream in(line);
  std::string field;
  while (std::getline(in, field, ',')) {
    const size_t a = field.find_first_not_of(" \t\r");
    const size_t b = field.find_last_not_of(" \t\r");
    fields.push_back(a == std::string::npos ? "" : field.substr(a, b - a + 1));
  }
  return fields;
}

/// One row of the settings file: a stepper of cloth_sim or the Bullet peer.
struct Setting {
  std::string method;  ///< implicit_euler | newton | bdf2 | symplectic_euler | bullet
  double dt = 0.0;
  double tolerance = 1e-6;  ///< CG relative residual (Bullet: its squared-residual bound)
  std::string preconditioner = "block_jacobi";
  int newton_iterations = 1;     ///< newton/bdf2 cap; Bullet's Newton iterations
  double newton_tolerance = 1e-8;
  /// > 0: error-controlled stepping (solver.error_tolerance), dt its first step
  double error_tolerance = 0.0;
  bool isBullet() const { return method == "bullet"; }
  bool adaptive() const { return error_tolerance > 0.0; }
};

std::vector<Setting> readSettings(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw UsageError{path + ": cannot read file"};
  std::vector<std::string> expected = {"method", "dt", "tolerance", "preconditioner",
                                       "newton_iterations", "newton_tolerance"};
  std::string line;
  std::vector<Setting> settings;
  int line_number = 0;
  bool header = true;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    const std::vector<std::string> f = splitCsvLine(line);
    const std::string at = path + ":" + std::to_string(line_number);
    if (header) {
      // error_tolerance: an optional last column (empty or 0: fixed steps).
      if (f.size() == expected.size() + 1 && f.back() == "error_tolerance") {
        expected.push_back("error_tolerance");
      }
      if (f != expected) {
        throw UsageError{at + ": header must be method,dt,tolerance,preconditioner,"
                              "newton_iterations,newton_tolerance[,error_tolerance]"};
      }
      header = false;
      continue;
    }
    if (f.size() != expected.size() && !(f.size() == 6 && expected.size() == 7)) {
      throw UsageError{at + ": expected " + std::to_string(expected.size()) + " fields, got " +
                       std::to_string(f.size())};
    }
    Setting s;
    s.method = f[0];
    Method m;
    if (!s.isBullet() && !cloth_sim::parseMethod(s.method, &m)) {
      throw UsageError{at + ": method: unknown '" + s.method + "'"};
    }
#ifndef CLOTH_SIM_HAVE_BULLET
    if (s.isBullet()) {
      throw UsageError{at + ": method: bullet, but this build has no Bullet peer"};
    }
#endif
    s.dt = parseNumber(at + ": dt", f[1]);
    s.tolerance = parseNumber(at + ": tolerance", f[2]);
    s.preconditioner = f[3];
    s.newton_iterations = static_cast<int>(parseCount(at + ": newton_iterations", f[4], 1));
    s.newton_tolerance = parseNumber(at + ": newton_tolerance", f[5]);
    if (f.size() > 6 && !f[6].empty()) {
      s.error_tolerance = parseNumber(at + ": error_tolerance", f[6]);
      if (s.isBullet() && s.adaptive()) {
        throw UsageError{at + ": error_tolerance: the Bullet peer steps at a fixed dt"};
      }
    }
    if (!(s.dt > 0)) throw UsageError{at + ": dt: must be > 0"};
    settings.push_back(s);
  }
  if (header) throw UsageError{path + ": no header line"};
  return settings;
}

/// The shortest %g form that reads back as exactly v.
std::string shortestNumber(double v) {
  char buf[64];
  for (int digits = 6; digits <= 17; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

/// Scene overrides that turn a Setting into cloth_sim solver fields; the same
/// strings go into the CSV so a row can be re-run with cloth_sim_run --set.
std::vector<std::string> solverOverrides(const Setting& s) {
  auto num = [](double v) { return shortestNumber(v); };
  std::vector<std::string> overrides = {"solver.method=" + s.method,
          "solver.dt=" + num(s.dt),
          "solver.tolerance=" + num(s.tolerance),
          "solver.preconditioner=" + s.preconditioner,
          "solver.newton_max_iterations=" + std::to_string(s.newton_iterations),
          "solver.newton_tolerance=" + num(s.newton_tolerance),
          // A setting is exactly its dt: a failed step fails it, no halving.
          "solver.recovery=false"};
  if (s.adaptive()) overrides.push_back("solver.error_tolerance=" + num(s.error_tolerance));
  return overrides;
}

// ------------------------------------------------------------ measures ----

double threadCpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

using WallClock = std::chrono::steady_clock;

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}


/// Sum over nodes of |a_i - b_i|^2.
double squaredNodeDistance(const VecX& a, const VecX& b) { return (a - b).squaredNorm(); }

/// Positions at the sample times t_k = k * sample (k = 1..K), from the step
/// ends (t, x, v): exact where a step ends on t_k, else cubic Hermite between
/// the two step ends around it (error O(h^4), far below any method's).
class Sampler {
 public:
  Sampler(double sample, int count) : sample_(sample), count_(count) {}
  /// Called after each step with the state before (x0, v0 at t0) and after it.
  void afterStep(double t0, const VecX& x0, const VecX& v0, double t1, const VecX& x1,
                 const VecX& v1) {
    const double h = t1 - t0;
    while (static_cast<int>(samples_.size()) < count_) {
      const double ts = (samples_.size() + 1) * sample_;
      if (ts > t1 + 1e-9 * h) break;
      if (std::abs(ts - t1) <= 1e-9 * h) {
        samples_.push_back(x1);
        continue;
      }
      const double s = (ts - t0) / h;
      const double h00 = (1 + 2 * s) * (1 - s) * (1 - s), h10 = s * (1 - s) * (1 - s);
      const double h01 = s * s * (3 - 2 * s), h11 = s * s * (s - 1);
      samples_.push_back(h00 * x0 + (h10 * h) * v0 + h01 * x1 + (h11 * h) * v1);
    }
  }
  const std::vector<VecX>& samples() const { return samples_; }

 private:
  double sample_;
  int count_;
  std::vector<VecX> samples_;
};

/// RMS over nodes and samples of |x - x_ref|, divided by `diagonal`.
double trajectoryError(const std::vector<VecX>& a, const std::vector<VecX>& b, double diagonal) {
  if (a.size() != b.size() || a.empty()) return kNaN;
  double sum = 0.0;
  for (size_t k = 0; k < a.size(); ++k) sum += squaredNodeDistance(a[k], b[k]);
  const double nodes = static_cast<double>(a[0].size() / 3);
  return std::sqrt(sum / (nodes * a.size())) / diagonal;
}

/// A state on the way, from which the one-step solver error is measured.
struct Snapshot {
  VecX x, v, x_prev, v_prev;
  bool has_prev = false;
};

/// One run of a setting from rest.
struct Run {
  bool ok = true;
  std::string failure;
  long steps = 0;
  double cpu_s = 0.0;          ///< thread CPU time of the stepping loop
  double wall_s = 0.0;         ///< wall time of the stepping loop
  double assembly_wall_s = 0.0, solve_wall_s = 0.0;
  long cg_iterations = 0, newton_iterations = 0, matrix_products = -1;
  double max_residual = 0.0, max_newton_residual = 0.0, max_strain = 0.0, energy_final = kNaN;
  // Contact scenes (recorded runs; NaN without colliders), measured from the
  // positions at every step's end the same way for cloth_sim and Bullet:
  double max_penetration = kNaN;  ///< max over steps, nodes, colliders of thickness - distance (>= 0)
  double max_depth = kNaN;        ///< the same of -distance: depth inside the collider itself
  double contacts_sum = 0.0;      ///< cloth_sim's StepStats::contacts, summed over steps
  double contact_passes_sum = 0.0;  ///< cloth_sim's StepStats::contact_passes, summed
  VecX x_final;
  std::vector<VecX> samples;        ///< only when recording
  std::vector<Snapshot> snapshots;  ///< only when recording
};

struct RunPlan {
  double duration = 2.0;
  double sample = 0.05;
  bool record = false;
  std::vector<long> snapshot_steps;  ///< steps (0-based) before which to keep the state
};

/// Steps of dt in duration; dt must divide it (`what` names dt in the message).
long stepCount(double duration, double dt, const std::string& what = "dt") {
  const double n = duration / dt;
  const long steps = std::lround(n);
  if (steps < 1 || std::abs(n - steps) > 1e-6 * n) {
    throw UsageError{what + " " + shortestNumber(dt) + " does not divide the duration " +
                     shortestNumber(duration) + " s"};
  }
  return steps;
}

Scene sceneFor(const Scene& base, const Setting& s) {
  Scene scene = base;
  scene.solver.recovery = false;
  Method m;
  cloth_sim::parseMethod(s.method, &m);
  scene.solver.method = m;
  scene.solver.dt = s.dt;
  scene.solver.tolerance = s.tolerance;
  scene.solver.newton_max_iterations = s.newton_iterations;
  scene.solver.newton_tolerance = s.newton_tolerance;
  // A fixed setting is fixed even where the scene (or --set) asks for error
  // control; the bounds dt_min, dt_max stay the scene's.
  scene.solver.error_tolerance =
      s.adaptive() ? std::optional<double>(s.error_tolerance) : std::nullopt;
  if (s.preconditioner == "none") {
    scene.solver.preconditioner = Preconditioner::None;
  } else if (s.preconditioner == "block_jacobi") {
    scene.solver.preconditioner = Preconditioner::BlockJacobi;
  } else if (s.preconditioner == "cholesky") {
    scene.solver.preconditioner = Preconditioner::Cholesky;
  } else if (s.preconditioner == "multigrid") {
    scene.solver.preconditioner = Preconditioner::Multigrid;
  } else if (s.preconditioner == "auto") {
    scene.solver.preconditioner = Preconditioner::Auto;
  } else {
    throw UsageError{"preconditioner: unknown '" + s.preconditioner +
                     "' (expected none, block_jacobi, cholesky, multigrid, auto)"};
  }
  cloth_sim::validateScene(scene);  // throws SceneError naming the field
  return scene;
}

/// The scene's colliders at their scene poses (the benchmark's are static).
struct StaticColliders {
  std::vector<cloth_sim::Collider> colliders;
  cloth_sim::CollidersOverStep over_step;
  explicit StaticColliders(const Scene& scene) {
    for (const cloth_sim::ColliderParams& p : scene.colliders) {
      colliders.push_back(cloth_sim::Collider::fromParams(p, scene.contact.friction));
    }
    over_step.colliders = &colliders;
    for (const cloth_sim::Collider& c : colliders) {
      over_step.start.push_back(c.scenePose());
      over_step.end.push_back(c.scenePose());
    }
    over_step.thickness = scene.contact.thickness;
  }
  bool empty() const { return colliders.empty(); }
  /// Folds the positions x into run.max_penetration and run.max_depth.
  void measure(const VecX& x, Run& run) const {
    if (colliders.empty()) return;
    double deepest = -INFINITY;  // max over nodes and colliders of -signed distance
    for (int i = 0; i < static_cast<int>(x.size() / 3); ++i) {
      for (size_t k = 0; k < colliders.size(); ++k) {
        deepest = std::max(deepest,
                           -colliders[k].closest(x.segment<3>(3 * i), over_step.end[k]).distance);
      }
    }
    const double depth = std::max(0.0, deepest);
    const double penetration = std::max(0.0, over_step.thickness + deepest);
    run.max_depth = std::isnan(run.max_depth) ? depth : std::max(run.max_depth, depth);
    run.max_penetration = std::isnan(run.max_penetration)
                              ? penetration
                              : std::max(run.max_penetration, penetration);
  }
};

/// The scene's uniform initial velocity on every unpinned node (3n).
VecX initialVelocities(const Scene& scene) {
  const int n = scene.numNodes();
  VecX v(3 * n);
  for (int i = 0; i < n; ++i) v.segment<3>(3 * i) = scene.initial.velocity;
  return v;
}

Run runCloth(const Scene& base, const Setting& setting, const RunPlan& plan) {
  const Scene scene = sceneFor(base, setting);
  // Error-controlled: as many steps as the control takes, the last one
  // landing on the duration.
  const long steps = setting.adaptive() ? std::numeric_limits<long>::max()
                                        : stepCount(plan.duration, setting.dt);
  Simulation sim(scene);
  const StaticColliders measure(base);
  Run run;
  const int sample_count = static_cast<int>(std::lround(plan.duration / plan.sample));
  Sampler sampler(plan.sample, sample_count);
  VecX x0, v0, x_before, v_before;  // state before this step and before the last one
  size_t next_snapshot = 0;

  const auto wall_start = WallClock::now();
  const double cpu_start = threadCpuSeconds();
  const double end_slack = 1e-9 * plan.duration;
  for (long n = 0; n < steps && sim.time() < plan.duration - end_slack; ++n) {
    const double t0 = sim.time();
    if (plan.record) {
      x_before.swap(x0);
      v_before.swap(v0);
      x0 = sim.positions();
      v0 = sim.velocities();
      if (next_snapshot < plan.snapshot_steps.size() && plan.snapshot_steps[next_snapshot] == n) {
        Snapshot snap;
        snap.x = x0;
        snap.v = v0;
        snap.has_prev = n > 0;  // bdf2's history: the state one step back
        if (snap.has_prev) {
          snap.x_prev = x_before;
          snap.v_prev = v_before;
        }
        run.snapshots.push_back(snap);
        ++next_snapshot;
      }
    }
    const StepStats s = setting.adaptive() ? sim.stepToward(plan.duration) : sim.step();
    if (!s.ok) {
      run.ok = false;
      run.failure = "step " + std::to_string(n) + ": " + s.failure;
      break;
    }
    run.assembly_wall_s += s.assembly_s;
    run.solve_wall_s += s.solve_s;
    run.cg_iterations += s.cg_iterations;
    run.newton_iterations += s.newton_iterations;
    run.max_residual = std::max(run.max_residual, s.residual);
    run.max_newton_residual = std::max(run.max_newton_residual, s.newton_residual);
    run.max_strain = std::max(run.max_strain, s.max_strain);
    run.contacts_sum += s.contacts;
    run.contact_passes_sum += s.contact_passes;
    ++run.steps;
    if (plan.record) {
      measure.measure(sim.positions(), run);
      if (setting.adaptive()) {
        sampler.afterStep(t0, x0, v0, sim.time(), sim.positions(), sim.velocities());
      } else {
        sampler.afterStep(n * setting.dt, x0, v0, (n + 1) * setting.dt, sim.positions(),
                          sim.velocities());
      }
    }
  }
  run.cpu_s = threadCpuSeconds() - cpu_start;
  run.wall_s = std::chrono::duration<double>(WallClock::now() - wall_start).count();
  run.x_final = sim.positions();
  run.energy_final = sim.energy();
  if (run.ok && !run.x_final.allFinite()) {
    run.ok = false;
    run.failure = "non-finite state";
  }
  run.samples = sampler.samples();
  return run;
}

#ifdef CLOTH_SIM_HAVE_BULLET
cloth_sim::bench::BulletSettings bulletSettings(const Setting& s) {
  cloth_sim::bench::BulletSettings b;
  b.dt = s.dt;
  b.newton_iterations = s.newton_iterations;
  b.newton_tolerance = s.newton_tolerance;
  b.cg_tolerance = s.tolerance;
  return b;
}
#endif


double totalEnergy(const Model& model, const VecX& x, const VecX& v) {
  return cloth_sim::measureEnergy(model, x, v).total();
}

Run runBullet(const Scene& base, const Setting& setting, const RunPlan& plan) {
  Run run;
#ifdef CLOTH_SIM_HAVE_BULLET
  const Model model = cloth_sim::buildModel(base);
  const VecX x_init = cloth_sim::initialPositions(base, model.rest_positions);
  const long steps = stepCount(plan.duration, setting.dt);
  const StaticColliders measure(base);
  cloth_sim::bench::BulletSettings settings = bulletSettings(setting);
  // Contact needs the compression clamp (bullet_peer.hpp); hang scenes keep
  // Bullet's exact Hessian.
  settings.project_compression = !base.colliders.empty();
  cloth_sim::bench::BulletPeer peer(model, x_init, base.pins, settings,
                                    initialVelocities(base),
                                    cloth_sim::bench::bulletContact(base, false));
  const int sample_count = static_cast<int>(std::lround(plan.duration / plan.sample));
  Sampler sampler(plan.sample, sample_count);
  VecX x0 = x_init, v0 = peer.velocities(), x1, v1;
  const double cpu_start = threadCpuSeconds();
  const auto wall_start = WallClock::now();
  for (long n = 0; n < steps; ++n) {
    if (plan.record) {
      for (long k : plan.snapshot_steps) {
        if (k == n) {
          Snapshot snap;
          snap.x = x0;
          snap.v = v0;
          run.snapshots.push_back(snap);
        }
      }
    }
    peer.step();
    ++run.steps;
    if (plan.record) {
      x1 = peer.positions();
      v1 = peer.velocities();
      // Strain needs positions: only in the recorded run (not timed).
      run.max_strain = std::max(run.max_strain, cloth_sim::maxStrain(model, x1));
      measure.measure(x1, run);
      if (!x1.allFinite()) {
        run.ok = false;
        run.failure = "step " + std::to_string(n) + ": non-finite state";
        break;
      }
      sampler.afterStep(n * setting.dt, x0, v0, (n + 1) * setting.dt, x1, v1);
      x0.swap(x1);
      v0.swap(v1);
    }
  }
  run.cpu_s = threadCpuSeconds() - cpu_start;
  run.wall_s = std::chrono::duration<double>(WallClock::now() - wall_start).count();
  run.x_final = peer.positions();
  const VecX v_final = peer.velocities();
  run.energy_final = totalEnergy(model, run.x_final, v_final);
  if (run.ok && !(run.x_final.allFinite() && v_final.allFinite())) {
    run.ok = false;
    run.failure = "non-finite state";
  }
  const cloth_sim::bench::BulletWork work = peer.work();
  run.cg_iterations = work.cg_iterations();
  run.newton_iterations = work.newton_solves;
  run.samples = sampler.samples();
#else
  (void)base;
  (void)setting;
  (void)plan;
  run.ok = false;
  run.failure = "built without the Bullet peer";
#endif
  return run;
}

Run runSetting(const Scene& base, const Setting& s, const RunPlan& plan) {
  return s.isBullet() ? runBullet(base, s, plan) : runCloth(base, s, plan);
}

// ------------------------------------------------- one-step solver error ----

/// One step of h from a snapshot with a Stepper of the given solver settings.
/// Returns the positions after the step (empty if the step failed).
VecX oneStep(const Model& model, const Scene& scene, const Scene::Solver& solver,
             const Snapshot& snap, double h, bool use_history) {
  cloth_sim::Stepper stepper(solver);
  cloth_sim::PinnedEnds pins;
  const VecX x_init = cloth_sim::initialPositions(scene, model.rest_positions);
  for (int p : scene.pins) {
    pins.nodes.push_back(p);
    pins.targets.push_back(x_init.segment<3>(3 * p));  // static pins
  }
  cloth_sim::History history;
  if (use_history && snap.has_prev) history = cloth_sim::History{&snap.x_prev, &snap.v_prev, h};
  VecX x = snap.x, v = snap.v;
  const StaticColliders colliders(scene);  // contact scenes: the step with its contacts
  const StepStats s = stepper.step(model, h, pins, history, x, v, std::nullopt,
                                   colliders.empty() ? cloth_sim::CollidersOverStep()
                                                     : colliders.over_step);
  if (!s.ok) return VecX();
  return x;
}

/// How the reference and the converged one-step solves are solved.
struct ConvergedSolve {
  Preconditioner preconditioner = Preconditioner::BlockJacobi;
  double cg_tolerance = 1e-12;
  double newton_tolerance = 1e-10;
  int newton_max_iterations = 10;
  /// false: the exact elastic Hessian (Newton converges faster; the matrix
  /// stays positive definite at a reference's small dt).
  bool project_compression = true;
};

Scene::Solver convergedSolver(const Scene::Solver& base, Method method,
                              const ConvergedSolve& c) {
  Scene::Solver s = base;
  s.method = method;
  s.tolerance = c.cg_tolerance;
  s.max_iterations = 20000;
  s.preconditioner = c.preconditioner;
  s.newton_tolerance = c.newton_tolerance;
  s.newton_max_iterations = c.newton_max_iterations;
  s.project_compression = c.project_compression;
  s.recovery = false;
  return s;
}

#ifdef CLOTH_SIM_HAVE_BULLET
VecX bulletOneStep(const Model& model, const Scene& scene, const Setting& setting,
                   const Snapshot& snap) {
  cloth_sim::bench::BulletPeer peer(model, snap.x, scene.pins, bulletSettings(setting), snap.v);
  peer.step();
  return peer.positions();
}
#endif

/// RMS over the snapshots of the one-step difference between the setting's
/// step and the same scheme solved to convergence (backward Euler for
/// implicit_euler, newton and Bullet; bdf2 for bdf2), over the diagonal.
/// NaN for symplectic_euler (no solver) or when a step failed.
double solverError(const Scene& base, const Setting& setting, const std::vector<Snapshot>& snaps,
                   const ConvergedSolve& converged_solve, double diagonal) {
  if (setting.method == "symplectic_euler" || snaps.empty()) return kNaN;
  const Model model = cloth_sim::buildModel(base);
  double sum = 0.0;
  int count = 0;
  for (const Snapshot& snap : snaps) {
    VecX x_setting;
    Method converged_method = Method::Newton;
    if (setting.isBullet()) {
      // Bullet's contact is its own model: no converged cloth_sim step to compare with.
      if (!base.colliders.empty()) return kNaN;
#ifdef CLOTH_SIM_HAVE_BULLET
      x_setting = bulletOneStep(model, base, setting, snap);
#endif
    } else {
      const Scene scene = sceneFor(base, setting);
      if (scene.solver.method == Method::Bdf2) converged_method = Method::Bdf2;
      x_setting = oneStep(model, base, scene.solver, snap, setting.dt, true);
    }
    const Scene::Solver converged =
        convergedSolver(base.solver, converged_method, converged_solve);
    const VecX x_converged = oneStep(model, base, converged, snap, setting.dt, true);
    if (x_setting.size() == 0 || x_converged.size() == 0 || !x_setting.allFinite()) return kNaN;
    sum += squaredNodeDistance(x_setting, x_converged) / model.numNodes();
    ++count;
  }
  return std::sqrt(sum / count) / diagonal;
}

// ---------------------------------------------------------------- main ----

struct Options {
  std::string scene_path, settings_path, out_path, name;
  std::vector<std::string> overrides;
  int repeats = 5;
  double duration = 2.0;
  double sample = 0.05;
  double ref_dt = 1.0 / 640.0;
  std::string ref_preconditioner = "block_jacobi";
  double ref_cg_tol = 1e-7;
  double ref_newton_tol = 1e-6;
  int ref_newton_iterations = 5;
  bool ref_projected = false;
  bool no_reference = false;  ///< timing only: no reference, no errors
  std::string converged_preconditioner = "cholesky";
  int solver_error_states = 2;
  bool append = false;
};

Options parseArgs(int argc, char** argv) {
  Options o;
  auto value = [&](int& i) -> std::string {
    if (i + 1 >= argc) throw UsageError{std::string(argv[i]) + ": missing value"};
    return argv[++i];
  };
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--settings") {
      o.settings_path = value(i);
    } else if (a == "--out") {
      o.out_path = value(i);
    } else if (a == "--name") {
      o.name = value(i);
    } else if (a == "--set") {
      o.overrides.push_back(value(i));
    } else if (a == "--repeats") {
      o.repeats = static_cast<int>(parseCount(a, value(i), 0));  // 0: errors only
    } else if (a == "--duration") {
      o.duration = parseNumber(a, value(i));
      if (!(o.duration > 0)) throw UsageError{"--duration: must be > 0"};
    } else if (a == "--sample") {
      o.sample = parseNumber(a, value(i));
      if (!(o.sample > 0)) throw UsageError{"--sample: must be > 0"};
    } else if (a == "--ref-dt") {
      o.ref_dt = parseNumber(a, value(i));
      if (!(o.ref_dt > 0)) throw UsageError{"--ref-dt: must be > 0"};
    } else if (a == "--ref-preconditioner") {
      o.ref_preconditioner = value(i);
    } else if (a == "--ref-cg-tol") {
      o.ref_cg_tol = parseNumber(a, value(i));
    } else if (a == "--ref-newton-tol") {
      o.ref_newton_tol = parseNumber(a, value(i));
    } else if (a == "--converged-preconditioner") {
      o.converged_preconditioner = value(i);
    } else if (a == "--no-reference") {
      o.no_reference = true;
    } else if (a == "--ref-projected") {
      o.ref_projected = true;
    } else if (a == "--ref-newton-iterations") {
      o.ref_newton_iterations = static_cast<int>(parseCount(a, value(i), 1));
    } else if (a == "--solver-error-states") {
      o.solver_error_states = static_cast<int>(parseCount(a, value(i), 0));
    } else if (a == "--append") {
      o.append = true;
    } else if (!a.empty() && a[0] == '-') {
      throw UsageError{a + ": unknown option"};
    } else if (o.scene_path.empty()) {
      o.scene_path = a;
    } else {
      throw UsageError{"one scene only, got '" + a + "' after '" + o.scene_path + "'"};
    }
  }
  if (o.scene_path.empty()) throw UsageError{"missing SCENE.yaml"};
  if (o.settings_path.empty()) throw UsageError{"--settings: missing"};
  if (o.out_path.empty()) throw UsageError{"--out: missing"};
  const double samples = o.duration / o.sample;
  if (std::abs(samples - std::lround(samples)) > 1e-6 * samples || std::lround(samples) < 1) {
    throw UsageError{"--sample: must divide --duration"};
  }
  if (o.name.empty()) {
    const size_t slash = o.scene_path.find_last_of('/');
    std::string base = o.scene_path.substr(slash == std::string::npos ? 0 : slash + 1);
    o.name = base.substr(0, base.find('.'));
  }
  return o;
}

const char* const kCsvHeader =
    "scene,nodes,springs,method,dt,tolerance,preconditioner,newton_iterations,"
    "newton_tolerance,ok,failure,steps,repeats,cpu_s_per_sim_s,cpu_s_per_sim_s_min,"
    "cpu_s_per_sim_s_max,cpu_assembly_s_per_sim_s,cpu_solve_s_per_sim_s,cpu_other_s_per_sim_s,"
    "cpu_ms_per_step,wall_s_per_sim_s,cg_iterations_per_step,newton_iterations_per_step,"
    "max_residual,max_newton_residual,error,error_final,solver_error,max_strain,energy_drift,ref_dt,ref_diff,"
    "deterministic,overrides,max_penetration,max_depth,contacts_per_step,contact_passes_per_step,"
    "error_tolerance";

std::string csvNumber(double v) {
  if (!std::isfinite(v)) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

std::string csvText(std::string s) {
  for (char& c : s) {
    if (c == ',' || c == '\n' || c == '"') c = ';';
  }
  return s;
}

struct Row {
  Setting setting;
  Run recorded;                 ///< the untimed run: error, counts
  std::vector<double> cpu;      ///< per timed repeat, s per simulated s
  std::vector<double> wall;
  double assembly_share = kNaN, solve_share = kNaN;
  double error = kNaN, error_final = kNaN, solver_error = kNaN, energy_drift = kNaN;
  bool deterministic = true;
  bool is_reference = false;
  std::vector<std::string> extra_overrides;  ///< beyond the setting's own
};

std::string formatRow(const Options& o, const Model& model, const Row& r, double ref_dt,
                      double ref_diff, const std::vector<std::string>& scene_overrides) {
  const Setting& s = r.setting;
  const Run& run = r.recorded;
  const double cpu = median(r.cpu);
  const double steps_per_sim_s = s.adaptive() ? run.steps / o.duration : 1.0 / s.dt;
  std::vector<std::string> overrides = scene_overrides;
  if (s.isBullet()) {  // bullet_check run's flags
    overrides.push_back("--dt " + shortestNumber(s.dt) + " --newton " +
                        std::to_string(s.newton_iterations) + " --newton-tol " +
                        shortestNumber(s.newton_tolerance) + " --cg-tol " +
                        shortestNumber(s.tolerance));
  } else {
    for (const std::string& x : solverOverrides(s)) overrides.push_back(x);
  }
  for (const std::string& x : r.extra_overrides) overrides.push_back(x);
  std::string joined;
  for (const std::string& x : overrides) joined += (joined.empty() ? "" : " ") + x;
  std::ostringstream out;
  const double steps = std::max<long>(run.steps, 1);
  out << csvText(o.name) << ',' << model.numNodes() << ',' << model.springs.size() << ','
      << (r.is_reference ? "reference" : s.method) << ',' << shortestNumber(s.dt) << ','
      << shortestNumber(s.tolerance) << ',' << (s.isBullet() ? "none" : s.preconditioner) << ','
      << s.newton_iterations << ',' << csvNumber(s.newton_tolerance) << ',' << (run.ok ? 1 : 0)
      << ',' << csvText(run.failure) << ',' << run.steps << ',' << r.cpu.size() << ','
      << csvNumber(cpu) << ',' << csvNumber(r.cpu.empty() ? kNaN : *std::min_element(r.cpu.begin(), r.cpu.end()))
      << ',' << csvNumber(r.cpu.empty() ? kNaN : *std::max_element(r.cpu.begin(), r.cpu.end()))
      << ',' << csvNumber(cpu * r.assembly_share) << ',' << csvNumber(cpu * r.solve_share) << ','
      << csvNumber(cpu * (1.0 - r.assembly_share - r.solve_share)) << ','
      << csvNumber(1e3 * cpu / steps_per_sim_s) << ',' << csvNumber(median(r.wall)) << ','
      << csvNumber(run.cg_iterations / steps) << ',' << csvNumber(run.newton_iterations / steps)
      << ',' << csvNumber(s.isBullet() ? kNaN : run.max_residual) << ','
      << csvNumber(s.isBullet() ? kNaN : run.max_newton_residual) << ',' << csvNumber(r.error)
      << ',' << csvNumber(r.error_final) << ',' << csvNumber(r.solver_error) << ','
      << csvNumber(run.max_strain) << ',' << csvNumber(r.energy_drift) << ','
      << csvNumber(ref_dt) << ',' << csvNumber(ref_diff) << ',' << (r.deterministic ? 1 : 0)
      << ',' << csvText(joined) << ',' << csvNumber(run.max_penetration) << ','
      << csvNumber(run.max_depth) << ','
      << csvNumber(s.isBullet() || !run.contact_passes_sum ? kNaN : run.contacts_sum / steps) << ','
      << csvNumber(s.isBullet() || !run.contact_passes_sum ? kNaN : run.contact_passes_sum / steps)
      << ',' << csvNumber(s.adaptive() ? s.error_tolerance : kNaN);
  return out.str();
}

Preconditioner parsePreconditioner(const std::string& name) {
  if (name == "none") return Preconditioner::None;
  if (name == "block_jacobi") return Preconditioner::BlockJacobi;
  if (name == "cholesky") return Preconditioner::Cholesky;
  if (name == "multigrid") return Preconditioner::Multigrid;
  if (name == "auto") return Preconditioner::Auto;
  throw UsageError{"--ref-preconditioner: unknown '" + name +
                   "' (expected auto, none, block_jacobi, cholesky, multigrid)"};
}

int benchMain(const Options& o) {
  const Scene base = cloth_sim::loadScene(o.scene_path, o.overrides);
  const Model model = cloth_sim::buildModel(base);
  const double diagonal = restDiagonal(model);
  double weight = 0.0;
  for (double m : model.mass) weight += m;
  // Energy scale for the drift: weight times size (J).
  const double energy_scale = weight * std::max(base.gravity.norm(), 1e-12) * diagonal;
  const std::vector<Setting> settings = readSettings(o.settings_path);
  // Reject a bad setting before hours of running, naming its row.
  for (size_t k = 0; k < settings.size(); ++k) {
    if (!settings[k].adaptive()) {
      stepCount(o.duration, settings[k].dt,
                o.settings_path + ": setting " + std::to_string(k + 1) + ": dt");
    }
    if (settings[k].isBullet()) continue;
    try {
      sceneFor(base, settings[k]);
    } catch (const cloth_sim::SceneError& e) {
      throw UsageError{o.settings_path + ": setting " + std::to_string(k + 1) + ": " + e.what()};
    }
  }
  // The one-step solves start from any state at any dt: projected Jacobian
  // (always positive definite), more Newton iterations.
  ConvergedSolve converged;
  converged.preconditioner = parsePreconditioner(o.converged_preconditioner);
  converged.cg_tolerance = 1e-10;
  converged.newton_tolerance = 1e-8;
  converged.newton_max_iterations = 40;
  stepCount(o.duration, o.ref_dt / 2, "--ref-dt / 2");

  auto progress = [&](const std::string& what) {
    std::fprintf(stderr, "progress %s %s\n", o.name.c_str(), what.c_str());
    std::fflush(stderr);
  };

  // The reference: bdf2 solved to convergence at ref_dt and ref_dt / 2.
  RunPlan record;
  record.duration = o.duration;
  record.sample = o.sample;
  record.record = true;
  std::vector<Row> rows;
  std::vector<VecX> x_ref;
  VecX x_ref_final;
  double ref_diff = kNaN, energy_ref = kNaN;
  if (!o.no_reference) {
    Setting ref;
    ref.method = "bdf2";
    ref.dt = o.ref_dt;
    ref.tolerance = o.ref_cg_tol;
    ref.preconditioner = o.ref_preconditioner;
    ref.newton_iterations = o.ref_newton_iterations;
    ref.newton_tolerance = o.ref_newton_tol;
    Scene ref_base = base;
    ref_base.solver.max_iterations = 20000;
    ref_base.solver.project_compression = o.ref_projected;
    const Run ref_coarse = runCloth(ref_base, ref, record);
    progress("reference dt " + csvNumber(ref.dt) + " cpu " + csvNumber(ref_coarse.cpu_s));
    Setting ref_fine_setting = ref;
    ref_fine_setting.dt = o.ref_dt / 2;
    RunPlan fine_plan = record;
    const long fine_steps = stepCount(o.duration, ref_fine_setting.dt);
    for (int k = 1; k <= o.solver_error_states; ++k) {
      fine_plan.snapshot_steps.push_back(fine_steps * k / (o.solver_error_states + 1));
    }
    const Run ref_fine = runCloth(ref_base, ref_fine_setting, fine_plan);
    progress("reference dt " + csvNumber(ref_fine_setting.dt) + " cpu " +
             csvNumber(ref_fine.cpu_s));
    if (!ref_coarse.ok || !ref_fine.ok) {
      std::fprintf(stderr, "cloth_sim_bench: %s: the reference run failed: %s\n", o.name.c_str(),
                   (ref_coarse.ok ? ref_fine.failure : ref_coarse.failure).c_str());
      return kExitReferenceNotConverged;
    }
    x_ref = ref_fine.samples;
    x_ref_final = ref_fine.x_final;
    ref_diff = trajectoryError(ref_coarse.samples, x_ref, diagonal);
    energy_ref = ref_fine.energy_final;

    Row r;
    r.setting = ref_fine_setting;
    r.recorded = ref_fine;
    r.cpu = {ref_fine.cpu_s / o.duration};
    r.wall = {ref_fine.wall_s / o.duration};
    r.assembly_share = ref_fine.assembly_wall_s / ref_fine.wall_s;
    r.solve_share = ref_fine.solve_wall_s / ref_fine.wall_s;
    r.error = 0.0;
    // The reference's own solver error per step, against a much tighter solve
    // of the same step (Newton and CG 1000x tighter).
    ConvergedSolve tighter = converged;
    tighter.cg_tolerance = o.ref_cg_tol * 1e-3;
    tighter.newton_tolerance = o.ref_newton_tol * 1e-3;
    tighter.project_compression = o.ref_projected;
    r.solver_error = solverError(ref_base, ref_fine_setting, ref_fine.snapshots, tighter, diagonal);
    r.is_reference = true;
    r.extra_overrides = {"solver.max_iterations=20000",
                         std::string("solver.project_compression=") +
                             (o.ref_projected ? "true" : "false")};
    rows.push_back(r);
  }

  int index = 0;
  for (const Setting& s : settings) {
    ++index;
    Row r;
    r.setting = s;
    RunPlan plan = record;
    // Snapshots for the one-step solver error: evenly spread, not the first
    // step. Not for error-controlled runs: their steps differ in size.
    const long steps = s.adaptive() ? 0 : stepCount(o.duration, s.dt);
    for (int k = 1; k <= o.solver_error_states && !s.adaptive(); ++k) {
      plan.snapshot_steps.push_back(std::max<long>(1, steps * k / (o.solver_error_states + 1)));
    }
    // The untimed run doubles as warm-up; it records the trajectory.
    r.recorded = runSetting(base, s, plan);
    Run& run = r.recorded;
    if (run.ok && !o.no_reference) {
      r.error = trajectoryError(run.samples, x_ref, diagonal);
      r.error_final = std::sqrt(squaredNodeDistance(run.x_final, x_ref_final) /
                                model.numNodes()) / diagonal;
      r.energy_drift = (run.energy_final - energy_ref) / energy_scale;
    }
    double solver_error_cpu = 0.0;
    if (run.ok) {
      const double cpu0 = threadCpuSeconds();
      r.solver_error = solverError(base, s, run.snapshots, converged, diagonal);
      solver_error_cpu = threadCpuSeconds() - cpu0;
      RunPlan timed;
      timed.duration = o.duration;
      std::vector<double> shares_a, shares_s;
      for (int rep = 0; rep < o.repeats; ++rep) {
        const Run t = runSetting(base, s, timed);
        if (!t.ok || t.x_final != run.x_final) r.deterministic = false;
        r.cpu.push_back(t.cpu_s / o.duration);
        r.wall.push_back(t.wall_s / o.duration);
        shares_a.push_back(t.assembly_wall_s / t.wall_s);
        shares_s.push_back(t.solve_wall_s / t.wall_s);
      }
      if (!s.isBullet()) {
        r.assembly_share = median(shares_a);
        r.solve_share = median(shares_s);
      }
    }
    progress(std::to_string(index) + "/" + std::to_string(settings.size()) + " " + s.method +
             " dt " + csvNumber(s.dt) + " tol " + csvNumber(s.tolerance) + " " +
             s.preconditioner + " it " + std::to_string(s.newton_iterations) + " cpu " +
             csvNumber(median(r.cpu)) + " error " + csvNumber(r.error) + " (solver error check " +
             csvNumber(solver_error_cpu) + " s)" +
             (run.ok ? "" : " FAILED: " + run.failure));
    rows.push_back(std::move(r));
  }

  std::ofstream out(o.out_path, o.append ? std::ios::app : std::ios::trunc);
  if (!out) throw UsageError{o.out_path + ": cannot write"};
  if (!o.append || out.tellp() == 0) out << kCsvHeader << '\n';
  for (const Row& r : rows) {
    out << formatRow(o, model, r, o.no_reference ? kNaN : o.ref_dt, ref_diff, o.overrides)
        << '\n';
  }
  out.close();

  if (o.no_reference) return kExitOk;
  // The reference must be far more accurate than anything it judges.
  double smallest = INFINITY;
  for (const Row& r : rows) {
    if (!r.is_reference && r.recorded.ok && std::isfinite(r.error)) {
      smallest = std::min(smallest, r.error);
    }
  }
  std::fprintf(stderr,
               "cloth_sim_bench: %s: reference dt %.6g vs %.6g differ by %.3g; smallest error %.3g\n",
               o.name.c_str(), o.ref_dt, o.ref_dt / 2, ref_diff, smallest);
  if (!(ref_diff < 0.1 * smallest)) {
    std::fprintf(stderr,
                 "cloth_sim_bench: %s: reference not converged: bdf2 at dt %.6g and %.6g differ "
                 "by %.3g, not below a tenth of the smallest error reported (%.3g)\n",
                 o.name.c_str(), o.ref_dt, o.ref_dt / 2, ref_diff, smallest);
    return kExitReferenceNotConverged;
  }
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return benchMain(parseArgs(argc, argv));
  } catch (const UsageError& e) {
    std::fprintf(stderr, "cloth_sim_bench: %s\n%s", e.message.c_str(), kUsage);
    return kExitBadInput;
  } catch (const cloth_sim::SceneError& e) {
    std::fprintf(stderr, "cloth_sim_bench: %s\n", e.what());
    return kExitBadInput;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "cloth_sim_bench: %s\n", e.what());
    return kExitBadInput;
  }
}
