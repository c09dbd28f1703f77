// bullet_check: runs a scene on the Bullet peer, and verifies physically that
// the peer's cloth is cloth_sim's cloth (bench/README.md, "Bullet peer").
//
//   bullet_check run SCENE.yaml [--duration S | --steps N] [--set key=value]...
//                [--dt H] [--newton N] [--newton-tol T] [--cg-iterations N]
//                [--cg-tol T] [--line-search] [--stock-force] [--out FILE]
//   bullet_check verify [--quick]
//
// Exit status: 0 success, 1 a check failed, 2 bad input, 3 non-finite state.
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bullet_peer.hpp"
#include "bullet_scene.hpp"
#include "command_line.hpp"
#include "rest_diagonal.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"
#include "self_measure.hpp"

namespace {

using cloth_sim::bench::parseCount;
using cloth_sim::bench::parseNumber;
using cloth_sim::bench::restDiagonal;
using cloth_sim::bench::UsageError;
using cloth_sim::Method;
using cloth_sim::Model;
using cloth_sim::Scene;
using cloth_sim::Simulation;
using cloth_sim::Vec3;
using cloth_sim::VecX;
using cloth_sim::bench::BulletPeer;
using cloth_sim::bench::BulletSettings;
using cloth_sim::bench::BulletWork;

constexpr int kExitOk = 0;
constexpr int kExitCheckFailed = 1;
constexpr int kExitBadInput = 2;
constexpr int kExitNonFinite = 3;

const char* const kUsage =
    "usage: bullet_check run SCENE.yaml [--duration S | --steps N] [--set key=value]...\n"
    "                        [--dt H] [--newton N] [--newton-tol T] [--cg-iterations N]\n"
    "                        [--cg-tol T] [--line-search] [--stock-force] [--out FILE]\n"
    "       bullet_check verify [--quick]   (--quick: without the demo comparison)\n";

double cpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}


/// RMS over nodes of |a_i - b_i|.
double rmsNodeDistance(const VecX& a, const VecX& b) {
  const int n = static_cast<int>(a.size() / 3);
  double sum = 0;
  for (int i = 0; i < n; ++i) sum += (a.segment<3>(3 * i) - b.segment<3>(3 * i)).squaredNorm();
  return std::sqrt(sum / n);
}

BulletPeer makePeer(const Scene& scene, const BulletSettings& settings, const VecX& v0 = VecX()) {
  const Model model = cloth_sim::buildModel(scene);
  const VecX x0 = cloth_sim::initialPositions(scene, model.rest_positions);
  return BulletPeer(model, x0, scene.pins, settings, v0);
}

// ------------------------------------------------------------------ run ----

struct RunOptions {
  std::string scene_path;
  double duration = 1.0;
  long steps = -1;
  std::vector<std::string> overrides;
  BulletSettings settings;
  bool dt_given = false;
  std::string out_path;
};

RunOptions parseRun(int argc, char** argv) {
  RunOptions o;
  auto value = [&](int& i) -> std::string {
    if (i + 1 >= argc) throw UsageError{std::string(argv[i]) + ": missing value"};
    return argv[++i];
  };
  bool have_duration = false;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--duration") {
      o.duration = parseNumber(a, value(i));
      if (!(o.duration > 0)) throw UsageError{"--duration: must be > 0"};
      have_duration = true;
    } else if (a == "--steps") {
      o.steps = parseCount(a, value(i), 1);
    } else if (a == "--set") {
      o.overrides.push_back(value(i));
    } else if (a == "--dt") {
      o.settings.dt = parseNumber(a, value(i));
      if (!(o.settings.dt > 0)) throw UsageError{"--dt: must be > 0"};
      o.dt_given = true;
    } else if (a == "--newton") {
      o.settings.newton_iterations = static_cast<int>(parseCount(a, value(i), 1));
    } else if (a == "--newton-tol") {
      o.settings.newton_tolerance = parseNumber(a, value(i));
    } else if (a == "--cg-iterations") {
      o.settings.cg_max_iterations = static_cast<int>(parseCount(a, value(i), 1));
    } else if (a == "--cg-tol") {
      o.settings.cg_tolerance = parseNumber(a, value(i));
    } else if (a == "--line-search") {
      o.settings.line_search = true;
    } else if (a == "--stock-force") {
      o.settings.stock_force = true;
    } else if (a == "--out") {
      o.out_path = value(i);
    } else if (!a.empty() && a[0] == '-') {
      throw UsageError{a + ": unknown option"};
    } else if (o.scene_path.empty()) {
      o.scene_path = a;
    } else {
      throw UsageError{a + ": only one scene file"};
    }
  }
  if (o.scene_path.empty()) throw UsageError{"SCENE.yaml: missing"};
  if (have_duration && o.steps > 0) throw UsageError{"--duration and --steps: give one"};
  return o;
}

int runScene(const RunOptions& o) {
  const Scene scene = cloth_sim::loadScene(o.scene_path, o.overrides);
  BulletSettings settings = o.settings;
  if (!o.dt_given) settings.dt = scene.solver.dt;  // same dt as cloth_sim_run
  const long steps = o.steps > 0 ? o.steps
                                 : static_cast<long>(std::ceil(o.duration / settings.dt - 1e-9));
  BulletPeer peer = makePeer(scene, settings);
  const double cpu0 = cpuSeconds();
  for (long s = 0; s < steps; ++s) peer.step();
  const double cpu = cpuSeconds() - cpu0;
  const VecX x = peer.positions();
  const VecX v = peer.velocities();
  const bool finite = x.allFinite() && v.allFinite();
  const BulletWork w = peer.work();
  std::printf(
      "{\"nodes\": %d, \"steps\": %ld, \"dt\": %.17g, \"sim_time\": %.17g, \"cpu_s\": %.6g, "
      "\"cpu_ms_per_step\": %.6g, \"cpu_s_per_sim_s\": %.6g, \"newton_iterations\": %d, "
      "\"force_evaluations_per_step\": %.4g, \"newton_solves_per_step\": %.4g, "
      "\"cg_iterations_per_solve\": %.4g, \"finite\": %s}\n",
      peer.numNodes(), steps, settings.dt, peer.time(), cpu, 1e3 * cpu / steps,
      cpu / peer.time(), settings.newton_iterations,
      double(w.force_evaluations) / steps, double(w.newton_solves) / steps,
      w.newton_solves ? double(w.cg_iterations()) / w.newton_solves : 0.0,
      finite ? "true" : "false");
  if (!o.out_path.empty() && finite) {
    FILE* f = std::fopen(o.out_path.c_str(), "w");
    if (!f) {
      std::fprintf(stderr, "--out: cannot write %s\n", o.out_path.c_str());
      return kExitBadInput;
    }
    for (int i = 0; i < peer.numNodes(); ++i) {
      std::fprintf(f, "%.17g %.17g %.17g %.17g %.17g %.17g\n", x[3 * i], x[3 * i + 1],
                   x[3 * i + 2], v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    }
    std::fclose(f);
  }
  return finite ? kExitOk : kExitNonFinite;
}

// --------------------------------------------------------------- verify ----

int g_failures = 0;

void report(bool ok, const char* name, const std::string& detail) {
  std::printf("%s  %-28s %s\n", ok ? "PASS" : "FAIL", name, detail.c_str());
  std::fflush(stdout);
  if (!ok) ++g_failures;
}

std::string fmt(const char* format, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, format, a, b, c);
  return buf;
}

/// (a) No springs: every Bullet step is exact backward (= symplectic) Euler
/// under constant gravity, x(t) = x0 + v0 t + 1/2 g t (t + h).
void checkFreeFall() {
  Scene s = cloth_sim::parseScene(
      "cloth: {rows: 3, cols: 3, plane: horizontal, origin: [0, 0, 1.5], mass: 0.09}\n"
      "gravity: [0.5, 0, -9.81]\n");
  const Model model = cloth_sim::buildModel(s);
  const VecX x0 = model.rest_positions;
  VecX v0(x0.size());
  for (int i = 0; i < model.numNodes(); ++i) v0.segment<3>(3 * i) = Vec3(0.3, -0.2, 1.0 + 0.1 * i);
  for (int newton : {1, 4}) {
    BulletSettings b;
    b.dt = 0.01;
    b.newton_iterations = newton;
    b.newton_tolerance = 0;
    BulletPeer peer(model, x0, {}, b, v0);
    double worst = 0;
    for (int k = 1; k <= 200; ++k) {
      peer.step();
      const double t = k * b.dt;
      const VecX exact = x0 + v0 * t +
                         VecX(model.gravity.replicate(model.numNodes(), 1)) * (0.5 * t * (t + b.dt));
      worst = std::max(worst, (peer.positions() - exact).cwiseAbs().maxCoeff());
    }
    report(worst < 1e-12, newton == 1 ? "free_fall (1 Newton it.)" : "free_fall (4 Newton it.)",
           fmt("max |x - (x0 + v0 t + g t(t+h)/2)| over 200 steps = %.2e m", worst));
  }
}

/// (b) A hanging chain settles to the static extension of spring i (from the
/// top, 1-based, N springs): (N - i + 1) m g / k.
void checkChain() {
  const int rows = 11, springs = rows - 1;
  const double k = 100.0, mass = 0.11, g = 9.81;  // 0.01 kg per node
  Scene s = cloth_sim::parseScene(
      "cloth: {rows: 11, cols: 1, length: 1.0, plane: vertical, origin: [0, 0, 2], mass: 0.11}\n"
      "springs: {stretch: {stiffness: 100.0, damping: 1.0}}\n"
      "gravity: [0, 0, -9.81]\n"
      "pins: [0]\n");
  const double m = mass / rows;
  for (int newton : {1, 3}) {
    BulletSettings b;
    b.dt = 1.0 / 240.0;
    b.newton_iterations = newton;
    BulletPeer peer = makePeer(s, b);
    for (int step = 0; step < 240 * 40; ++step) peer.step();
    const VecX x = peer.positions();
    double worst = 0;
    for (int i = 1; i <= springs; ++i) {
      const double extension = (x.segment<3>(3 * (i - 1)) - x.segment<3>(3 * i)).norm() - 0.1;
      const double exact = (springs - i + 1) * m * g / k;
      worst = std::max(worst, std::abs(extension / exact - 1));
    }
    report(worst < 1e-9, newton == 1 ? "hanging_chain (1 Newton)" : "hanging_chain (3 Newton)",
           fmt("after 40 s: max relative error of the spring extensions = %.2e", worst));
  }
}

/// The per-link force is Bullet's btDeformableMassSpringForce with
/// coefficients per link: where the stock force can carry the scene, both
/// must give the same trajectory.
void checkStockEquivalence() {
  for (const char* model : {"along_spring", "relative_velocity"}) {
    Scene s = cloth_sim::parseScene(
        std::string("cloth: {rows: 8, cols: 8, mass: 0.1}\n"
                    "springs:\n"
                    "  stretch: {stiffness: 2000.0, damping: 0.7}\n"
                    "  shear: {stiffness: 2000.0, damping: 0.7}\n"
                    "  bend: {stiffness: 3.0, damping: 0.7}\n"
                    "  damping_model: ") + model + "\n"
                    "pins: [0, 7]\n");
    double diff = 0;
    VecX x[2];
    for (int stock = 0; stock < 2; ++stock) {
      BulletSettings b;
      b.dt = 0.005;
      b.newton_iterations = 2;
      b.stock_force = stock == 1;
      BulletPeer peer = makePeer(s, b);
      for (int step = 0; step < 200; ++step) peer.step();
      x[stock] = peer.positions();
    }
    diff = (x[0] - x[1]).cwiseAbs().maxCoeff();
    report(diff <= 1e-12, model[0] == 'a' ? "per_link == stock (along)" : "per_link == stock (rel.v)",
           fmt("max |x_per_link - x_stock| after 1 s = %.2e m", diff));
  }
}

/// Pins stay exactly put and Bullet keeps our rest lengths even when the
/// cloth starts stretched (Bullet would otherwise reset them from positions).
void checkPinsAndRestLengths() {
  Scene s = cloth_sim::loadScene(CLOTH_SIM_SOURCE_DIR "/config/demo.yaml",
                                 {"initial.stretch=1.1", "cloth.rows=12", "cloth.cols=12",
                                  "pins=[0, 11]"});
  BulletSettings b;
  b.dt = s.solver.dt;
  const Model model = cloth_sim::buildModel(s);
  const VecX x0 = cloth_sim::initialPositions(s, model.rest_positions);
  BulletPeer peer(model, x0, s.pins, b);
  double pin_error = 0;
  for (int step = 0; step < 100; ++step) {
    peer.step();
    const VecX x = peer.positions();
    for (int p : s.pins) pin_error = std::max(pin_error, (x - x0).segment<3>(3 * p).norm());
  }
  report(pin_error == 0.0, "pins_exact", fmt("max pinned-node displacement over 100 steps = %.1e m", pin_error));
  report(peer.restLengthDrift() == 0.0, "rest_lengths_kept",
         fmt("max |L_bullet - L_model| after 100 steps from a 1.1x stretched start = %.1e m",
             peer.restLengthDrift()));
}

/// From rest, one Bullet step with one Newton iteration is the Baraff-Witkin
/// step cloth_sim's implicit_euler takes: same matrix M - h D - h^2 K, same
/// right side h f. This pins down masses, stiffness, damping and gravity.
void checkFirstStepMatches() {
  for (const char* model : {"along_spring", "relative_velocity"}) {
    Scene s = cloth_sim::loadScene(CLOTH_SIM_SOURCE_DIR "/config/demo.yaml",
                                   {std::string("springs.damping_model=") + model,
                                    "solver.tolerance=1e-13", "solver.max_iterations=5000"});
    Simulation sim(s);
    sim.step();
    BulletSettings b;
    b.dt = s.solver.dt;
    b.cg_tolerance = 1e-30;
    b.cg_max_iterations = 5000;
    BulletPeer peer = makePeer(s, b);
    peer.step();
    const double moved = (sim.positions() - cloth_sim::initialPositions(s, sim.model().rest_positions))
                             .cwiseAbs()
                             .maxCoeff();
    const double diff = (sim.positions() - peer.positions()).cwiseAbs().maxCoeff();
    report(diff <= 1e-9 * moved,
           model[0] == 'a' ? "first_step == BW (along)" : "first_step == BW (rel.v)",
           fmt("demo, one step of %.4g s: max |x_bullet - x_cloth_sim| = %.2e m (moved %.2e m)",
               s.solver.dt, diff, moved));
  }
}

/// Without damping Bullet's Newton, iterated to convergence, solves the same
/// backward Euler equations as cloth_sim's newton stepper, step after step.
void checkConvergedBackwardEuler() {
  Scene s = cloth_sim::loadScene(CLOTH_SIM_SOURCE_DIR "/config/demo.yaml",
                                 {"cloth.rows=12", "cloth.cols=12", "pins=[0, 11]",
                                  "springs.stretch.damping=0", "springs.shear.damping=0",
                                  "springs.bend.damping=0", "solver.method=newton",
                                  "solver.newton_tolerance=1e-13", "solver.tolerance=1e-13",
                                  "solver.max_iterations=5000", "solver.newton_max_iterations=50",
                                  "solver.dt=0.004"});
  Simulation sim(s);
  BulletSettings b;
  b.dt = s.solver.dt;
  b.newton_iterations = 30;
  b.newton_tolerance = 1e-13;
  b.cg_tolerance = 1e-30;
  b.cg_max_iterations = 5000;
  BulletPeer peer = makePeer(s, b);
  double worst = 0;
  for (int step = 0; step < 250; ++step) {
    sim.step();
    peer.step();
    worst = std::max(worst, (sim.positions() - peer.positions()).cwiseAbs().maxCoeff());
  }
  report(worst < 1e-8, "converged_BE == newton",
         fmt("undamped 12x12 demo, 1 s: max |x_bullet - x_cloth_sim| = %.2e m", worst));
}

/// (c) The demo after 1 s: Bullet at several dt and Newton counts against a
/// cloth_sim reference (newton to 1e-12 at dt/8 of the demo's). Informational,
/// plus one expectation: Bullet's error shrinks as dt does (first order).
void compareDemo() {
  const std::string demo = CLOTH_SIM_SOURCE_DIR "/config/demo.yaml";
  Scene ref_scene = cloth_sim::loadScene(
      demo, {"solver.method=newton", "solver.dt=0.0005", "solver.newton_tolerance=1e-12",
             "solver.tolerance=1e-12", "solver.max_iterations=5000"});
  Simulation ref(ref_scene);
  while (ref.time() < 1.0 - 1e-9) ref.step();
  const double diagonal = restDiagonal(ref.model());
  std::printf("\n  demo after 1 s, error = RMS over nodes |x - x_ref| / diagonal (%.3f m);\n"
              "  x_ref: cloth_sim newton, dt 0.0005, tol 1e-12\n", diagonal);
  std::printf("  %-34s %8s %12s %14s %14s\n", "setting", "dt", "error", "cpu ms/step", "cpu s/sim s");
  auto row = [&](const std::string& name, double dt, const VecX& x, double cpu, long steps) {
    std::printf("  %-34s %8.5f %12.3e %14.4f %14.4f\n", name.c_str(), dt,
                rmsNodeDistance(x, ref.positions()) / diagonal, 1e3 * cpu / steps, cpu / (steps * dt));
  };
  std::vector<double> bullet_error;
  for (double dt : {0.004, 0.002, 0.001}) {
    for (int newton : {1, 3}) {
      Scene s = cloth_sim::loadScene(demo);
      BulletSettings b;
      b.dt = dt;
      b.newton_iterations = newton;
      BulletPeer peer = makePeer(s, b);
      const long steps = std::lround(1.0 / dt);
      const double cpu0 = cpuSeconds();
      for (long k = 0; k < steps; ++k) peer.step();
      const double cpu = cpuSeconds() - cpu0;
      const BulletWork w = peer.work();
      char name[96];
      std::snprintf(name, sizeof name, "bullet newton %d (%.1f CG it/solve)", newton,
                    w.newton_solves ? double(w.cg_iterations()) / w.newton_solves : 0.0);
      row(name, dt, peer.positions(), cpu, steps);
      if (newton == 1) bullet_error.push_back(rmsNodeDistance(peer.positions(), ref.positions()) / diagonal);
    }
    for (const char* method : {"implicit_euler", "newton"}) {
      Scene s = cloth_sim::loadScene(demo, {std::string("solver.method=") + method,
                                            "solver.dt=" + std::to_string(dt)});
      Simulation sim(s);
      const long steps = std::lround(1.0 / dt);
      const double cpu0 = cpuSeconds();
      for (long k = 0; k < steps; ++k) sim.step();
      row(std::string("cloth_sim ") + method, dt, sim.positions(), cpuSeconds() - cpu0, steps);
    }
  }
  const bool first_order = bullet_error[1] < 0.75 * bullet_error[0] && bullet_error[2] < 0.75 * bullet_error[1];
  report(first_order, "demo_error_shrinks_with_dt",
         fmt("bullet (1 Newton) error at dt 0.004/0.002/0.001: %.2e %.2e %.2e", bullet_error[0],
             bullet_error[1], bullet_error[2]));
}

/// (g) The self-collision benchmark's intersection count (the hard cases'
/// exact test) on hand-built states of a 4 x 4 grid, 1 m apart, rows along
/// -y: flat, none; rows 2 and 3 stood up as a wall through the middle of the
/// band of rows 0-1 (no node shared with it), some; the same wall lifted
/// 1 mm clear of it, none, at 1 mm.
void checkIntersectionCounter() {
  const Scene s = cloth_sim::parseScene(
      "cloth: {rows: 4, cols: 4, width: 3, length: 3, plane: horizontal, "
      "origin: [0, 0, 0], mass: 0.16}\n");
  const Model model = cloth_sim::buildModel(s);
  const VecX flat = model.rest_positions;
  auto wall = [&](double lift) {
    VecX x = flat;
    for (int c = 0; c < 4; ++c) {
      x.segment<3>(3 * (2 * 4 + c)) = Vec3(c, -0.5, 1.0);          // row 2 above ...
      x.segment<3>(3 * (3 * 4 + c)) = Vec3(c, -0.5, lift > 0 ? lift : -1.0);  // ... row 3
    }
    return x;
  };
  const int n_flat = cloth_sim::bench::selfIntersections(model, flat);
  const int n_cross = cloth_sim::bench::selfIntersections(model, wall(0));
  const int n_clear = cloth_sim::bench::selfIntersections(model, wall(1e-3));
  const double d_clear = cloth_sim::bench::minSelfDistance(model, wall(1e-3), 0.01);
  const double d_flat = cloth_sim::bench::minSelfDistance(model, flat, 0.01);
  report(n_flat == 0 && n_cross > 0 && n_clear == 0 && std::abs(d_clear - 1e-3) < 1e-12 &&
             std::isinf(d_flat),
         "intersection_counter",
         fmt("flat %.0f, wall through the cloth %.0f, wall 1 mm clear %.0f pairs", n_flat,
             n_cross, n_clear) +
             fmt("; min distance %.3g m (flat: %g)", d_clear, d_flat));
}

/// (h) The peer with Bullet's own self-collision on the heap hard case
/// (s1_heap: the table plane as a box, 0.6 s at dt 1/480): it runs finite,
/// the option changes the trajectory (self-collision off: the layers pass
/// through each other freely), and it leaves fewer intersecting pairs than
/// without it (measured: 65 against 192 at most in a step).
void checkBulletSelfCollision() {
  const Scene s =
      cloth_sim::loadScene(CLOTH_SIM_SOURCE_DIR "/config/scenes/hard/self/s1_heap.yaml");
  const Model model = cloth_sim::buildModel(s);
  const VecX x0 = cloth_sim::initialPositions(s, model.rest_positions);
  VecX v0(x0.size());
  for (int i = 0; i < model.numNodes(); ++i) v0.segment<3>(3 * i) = s.initial.velocity;
  BulletSettings b;
  b.dt = 1.0 / 480;
  b.cg_tolerance = 1e-6;
  b.project_compression = true;
  VecX end[2];
  int worst[2] = {0, 0};
  bool finite = true;
  for (int self = 0; self < 2; ++self) {
    BulletPeer peer(model, x0, s.pins, b, v0, cloth_sim::bench::bulletContact(s, self == 1));
    for (int k = 0; k < 288; ++k) {
      peer.step();
      const VecX x = peer.positions();
      finite = finite && x.allFinite();
      if (!finite) break;
      worst[self] = std::max(worst[self], cloth_sim::bench::selfIntersections(model, x));
    }
    end[self] = peer.positions();
  }
  const double moved = finite ? (end[1] - end[0]).cwiseAbs().maxCoeff() : NAN;
  report(finite && moved > 1e-3 && worst[1] < worst[0], "bullet_self_collision",
         fmt("s1_heap 0.6 s: self on vs off differ by %.2e m; max intersecting pairs: "
             "off %.0f, on %.0f", moved, worst[0], worst[1]));
}

int verify(bool quick) {
  checkFreeFall();
  checkChain();
  checkStockEquivalence();
  checkPinsAndRestLengths();
  checkFirstStepMatches();
  checkConvergedBackwardEuler();
  checkIntersectionCounter();
  checkBulletSelfCollision();
  if (!quick) compareDemo();
  std::printf("%d check(s) failed\n", g_failures);
  return g_failures == 0 ? kExitOk : kExitCheckFailed;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc >= 2 && std::string(argv[1]) == "verify") {
      const bool quick = argc == 3 && std::string(argv[2]) == "--quick";
      if (argc > 3 || (argc == 3 && !quick)) throw UsageError{"verify: only --quick is allowed"};
      return verify(quick);
    }
    if (argc >= 3 && std::string(argv[1]) == "run") return runScene(parseRun(argc, argv));
    std::fputs(kUsage, stderr);
    return kExitBadInput;
  } catch (const UsageError& e) {
    std::fprintf(stderr, "%s\n%s", e.message.c_str(), kUsage);
  } catch (const cloth_sim::SceneError& e) {
    std::fprintf(stderr, "%s\n", e.what());
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "%s\n", e.what());
  }
  return kExitBadInput;
}
