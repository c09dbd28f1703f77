// cloth_sim_self_bench: self-collision scenes on cloth_sim and on the Bullet
// peer with its own self-collision (docs/benchmark_self.md).
//
//   cloth_sim_self_bench SCENE.yaml RUN... [--set key=value]... [--duration S]
//                        [--sample S] [--ref-dt H] [--no-reference] [--cutoff D]
//
// RUN is WHO:DT:SELF, e.g. cloth:0.004:on, bullet:1/960:off. WHO cloth runs
// the scene's solver settings with solver.dt = DT (recovery off); bullet runs
// the peer (1 Newton iteration, CG 1e-6, the compression clamp, the scene's
// colliders as boxes, a plane as a 2 m thick box). SELF off sets
// self_collision.enabled false for cloth_sim and leaves Bullet's off.
// Scripted pins (move_pin with a velocity, pin, release) are replayed on the
// peer; other events are refused. Every DT must put steps on the events'
// and the samples' times.
//
// Per run it prints one JSON line: CPU s per simulated s (thread CPU time
// of the step calls only), intersections (pairs of non-adjacent triangles,
// at every step's end: max per step, steps with any), smallest
// non-adjacent distance (below --cutoff), max strain, and the error against
// the reference: RMS node distance over the cloth's diagonal at every
// sample (max over samples, and at the end). The reference is cloth_sim with
// self-collision, the scene's method, CG to 1e-10, at --ref-dt and
// --ref-dt / 2; the finer one is the reference and their difference is
// printed (a heap is chaotic: it need not converge).
//
// Exit status: 0 success, 2 bad input, 3 a run failed.
#include <time.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "cloth_sim/collider.hpp"
#include "cloth_sim/forces.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"
#include "command_line.hpp"
#include "rest_diagonal.hpp"
#include "self_measure.hpp"
#ifdef CLOTH_SIM_HAVE_BULLET
#include "bullet_scene.hpp"
#endif

namespace {

using cloth_sim::Model;
using cloth_sim::Scene;
using cloth_sim::SceneEvent;
using cloth_sim::Vec3;
using cloth_sim::VecX;
using cloth_sim::bench::parseNumber;
using cloth_sim::bench::restDiagonal;
using cloth_sim::bench::stepsTo;
using cloth_sim::bench::UsageError;

const char* const kUsage =
    "usage: cloth_sim_self_bench SCENE.yaml WHO:DT:SELF... [--set key=value]...\n"
    "                            [--duration S] [--sample S] [--ref-dt H] [--no-reference]\n"
    "                            [--cutoff D]\n"
    "       WHO: cloth | bullet, DT: seconds or 1/N, SELF: on | off\n";
constexpr double kInf = std::numeric_limits<double>::infinity();

double threadCpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/// "0.004" or "1/960".
double parseDt(const std::string& text) {
  const size_t slash = text.find('/');
  const double dt = slash == std::string::npos
                        ? parseNumber("dt", text)
                        : parseNumber("dt", text.substr(0, slash)) /
                              parseNumber("dt", text.substr(slash + 1));
  if (!(dt > 0) || !std::isfinite(dt)) throw UsageError{"dt: must be > 0, got " + text};
  return dt;
}

struct RunSpec {
  std::string who;  ///< cloth | bullet
  double dt = 0;
  bool self = true;
  std::string text;
};

struct Options {
  std::string scene_path;
  std::vector<RunSpec> runs;
  std::vector<std::string> overrides;
  double duration = 1.0, sample = 0.1, ref_dt = 1.0 / 1920, cutoff = 0.01;
  bool reference = true;
};

/// What one run measured.
struct Result {
  bool ok = true;
  std::string failure;
  long steps = 0;
  double cpu_s = 0;
  int max_intersections = 0;
  long steps_intersecting = 0;
  double min_distance = kInf;
  double max_strain = 0;
  std::vector<VecX> samples;  ///< positions at every sample time, t = sample .. duration
};

/// Folds one step's end state into the result; keeps it if on a sample.
void measure(const Model& model, const VecX& x, long step, long steps_per_sample,
             double cutoff, Result* r) {
  const int crossings = cloth_sim::bench::selfIntersections(model, x);
  r->max_intersections = std::max(r->max_intersections, crossings);
  r->steps_intersecting += crossings > 0;
  r->min_distance = std::min(r->min_distance, cloth_sim::bench::minSelfDistance(model, x, cutoff));
  r->max_strain = std::max(r->max_strain, cloth_sim::maxStrain(model, x));
  if ((step + 1) % steps_per_sample == 0) r->samples.push_back(x);
}

Scene sceneFor(const Options& o, bool self, double dt) {
  std::vector<std::string> overrides = o.overrides;
  if (!self) overrides.push_back("self_collision.enabled=false");
  Scene scene = cloth_sim::loadScene(o.scene_path, overrides);
  scene.solver.dt = dt;
  scene.solver.recovery = false;
  scene.solver.error_tolerance.reset();
  cloth_sim::validateScene(scene);
  return scene;
}

Result runCloth(const Scene& scene, const Options& o, bool timed = true) {
  const long steps = stepsTo(o.duration, scene.solver.dt, "duration");
  const long per_sample = stepsTo(o.sample, scene.solver.dt, "sample");
  cloth_sim::Simulation sim(scene);
  const Model model = cloth_sim::buildModel(scene);
  Result r;
  for (long n = 0; n < steps; ++n) {
    const double cpu0 = threadCpuSeconds();
    const cloth_sim::StepStats s = sim.step();
    r.cpu_s += threadCpuSeconds() - cpu0;
    ++r.steps;
    if (!s.ok || !sim.positions().allFinite()) {
      r.ok = false;
      r.failure = "step " + std::to_string(n) + ": " + (s.ok ? "non-finite state" : s.failure);
      break;
    }
    if (timed) measure(model, sim.positions(), n, per_sample, o.cutoff, &r);
    else if ((n + 1) % per_sample == 0) r.samples.push_back(sim.positions());
  }
  return r;
}

#ifdef CLOTH_SIM_HAVE_BULLET
using cloth_sim::bench::bulletContact;
using cloth_sim::bench::PinChange;
using cloth_sim::bench::pinScript;

Result runBullet(const Scene& scene, const Options& o, double dt, bool self) {
  const long steps = stepsTo(o.duration, dt, "duration");
  const long per_sample = stepsTo(o.sample, dt, "sample");
  const Model model = cloth_sim::buildModel(scene);
  const VecX x0 = cloth_sim::initialPositions(scene, model.rest_positions);
  VecX v0(x0.size());
  for (int i = 0; i < model.numNodes(); ++i) v0.segment<3>(3 * i) = scene.initial.velocity;
  cloth_sim::bench::BulletSettings settings;
  settings.dt = dt;
  settings.cg_tolerance = 1e-6;     // the work-precision benchmark's Bullet setting
  settings.project_compression = true;  // contact and heaps compress links (bullet_peer.hpp)
  cloth_sim::bench::BulletPeer peer(model, x0, scene.pins, settings, v0,
                                    bulletContact(scene, self));
  const auto script = pinScript(scene, dt);
  std::vector<bool> held(model.numNodes(), false);
  for (int i : scene.pins) held[i] = true;
  Result r;
  for (long n = 0; n < steps; ++n) {
    for (auto it = script.lower_bound(n); it != script.upper_bound(n); ++it) {
      const PinChange& c = it->second;
      if (c.hold) {
        peer.holdNode(c.node, c.velocity);
      } else if (held[c.node]) {
        peer.releaseNode(c.node);
      }
      held[c.node] = c.hold;
    }
    const double cpu0 = threadCpuSeconds();
    peer.step();
    r.cpu_s += threadCpuSeconds() - cpu0;
    ++r.steps;
    const VecX x = peer.positions();
    if (!x.allFinite()) {
      r.ok = false;
      r.failure = "step " + std::to_string(n) + ": non-finite state";
      break;
    }
    measure(model, x, n, per_sample, o.cutoff, &r);
  }
  return r;
}
#endif

/// RMS over nodes of |a_i - b_i| over the diagonal: max over samples, and the last.
std::pair<double, double> trajectoryError(const std::vector<VecX>& a, const std::vector<VecX>& b,
                                          double diagonal) {
  if (a.size() != b.size() || a.empty()) return {NAN, NAN};
  double worst = 0, last = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    last = std::sqrt((a[k] - b[k]).squaredNorm() / (a[k].size() / 3)) / diagonal;
    worst = std::max(worst, last);
  }
  return {worst, last};
}

Options parse(int argc, char** argv) {
  Options o;
  auto value = [&](int& i) -> std::string {
    if (i + 1 >= argc) throw UsageError{std::string(argv[i]) + ": missing value"};
    return argv[++i];
  };
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--set") {
      o.overrides.push_back(value(i));
    } else if (a == "--duration") {
      o.duration = parseNumber(a, value(i));
    } else if (a == "--sample") {
      o.sample = parseNumber(a, value(i));
    } else if (a == "--ref-dt") {
      o.ref_dt = parseDt(value(i));
    } else if (a == "--cutoff") {
      o.cutoff = parseNumber(a, value(i));
    } else if (a == "--no-reference") {
      o.reference = false;
    } else if (a.rfind("--", 0) == 0) {
      throw UsageError{a + ": unknown option"};
    } else if (o.scene_path.empty()) {
      o.scene_path = a;
    } else {
      const size_t c1 = a.find(':'), c2 = a.rfind(':');
      if (c1 == std::string::npos || c1 == c2) throw UsageError{a + ": expected WHO:DT:SELF"};
      RunSpec r{a.substr(0, c1), parseDt(a.substr(c1 + 1, c2 - c1 - 1)), true, a};
      const std::string self = a.substr(c2 + 1);
      if ((r.who != "cloth" && r.who != "bullet") || (self != "on" && self != "off")) {
        throw UsageError{a + ": WHO is cloth or bullet, SELF on or off"};
      }
      r.self = self == "on";
      o.runs.push_back(r);
    }
  }
  if (o.scene_path.empty() || o.runs.empty()) throw UsageError{"SCENE.yaml and a RUN needed"};
  if (!(o.duration > 0) || !(o.sample > 0) || !(o.cutoff > 0)) {
    throw UsageError{"--duration, --sample, --cutoff: must be > 0"};
  }
  return o;
}

/// `text` as the inside of a JSON string.
std::string jsonEscaped(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c == '\n' ? ' ' : c;
  }
  return out;
}

std::string number(double v) {
  if (std::isnan(v)) return "null";
  if (std::isinf(v)) return "\"inf\"";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

int run(const Options& o) {
  const Scene base = sceneFor(o, true, o.ref_dt);
  const Model model = cloth_sim::buildModel(base);
  const double diagonal = restDiagonal(model);
  std::vector<VecX> reference;
  if (o.reference) {
    // The scene's method with CG and Newton solved tight (tolerance is CG's).
    Scene coarse = base, fine = base;
    coarse.solver.tolerance = fine.solver.tolerance = 1e-10;
    fine.solver.dt = o.ref_dt / 2;
    const Result a = runCloth(coarse, o, false), b = runCloth(fine, o, false);
    if (!a.ok || !b.ok) {
      std::fprintf(stderr, "reference failed: %s\n", (a.ok ? b : a).failure.c_str());
      return 3;
    }
    const auto diff = trajectoryError(a.samples, b.samples, diagonal);
    std::printf("{\"run\": \"reference\", \"dt\": %s, \"differs_from_half_dt_max\": %s, "
                "\"differs_from_half_dt_final\": %s, \"cpu_s_per_sim_s\": %s}\n",
                number(o.ref_dt / 2).c_str(), number(diff.first).c_str(),
                number(diff.second).c_str(), number(b.cpu_s / o.duration).c_str());
    std::fflush(stdout);
    reference = b.samples;
  }
  int status = 0;
  for (const RunSpec& spec : o.runs) {
    const Scene scene = sceneFor(o, spec.self, spec.dt);
    Result r;
    if (spec.who == "cloth") {
      r = runCloth(scene, o);
    } else {
#ifdef CLOTH_SIM_HAVE_BULLET
      r = runBullet(scene, o, spec.dt, spec.self);
#else
      r.ok = false;
      r.failure = "built without the Bullet peer";
#endif
    }
    const auto err = r.ok && o.reference ? trajectoryError(r.samples, reference, diagonal)
                                         : std::pair<double, double>{NAN, NAN};
    std::printf("{\"run\": \"%s\", \"ok\": %s, \"failure\": \"%s\", \"steps\": %ld, "
                "\"cpu_s_per_sim_s\": %s, \"cpu_ms_per_step\": %s, \"max_intersections\": %d, "
                "\"steps_intersecting\": %ld, \"min_distance\": %s, \"max_strain\": %s, "
                "\"error_max\": %s, \"error_final\": %s}\n",
                jsonEscaped(spec.text).c_str(), r.ok ? "true" : "false",
                jsonEscaped(r.failure).c_str(), r.steps,
                number(r.cpu_s / (r.steps * spec.dt)).c_str(),
                number(1e3 * r.cpu_s / r.steps).c_str(), r.max_intersections,
                r.steps_intersecting, number(r.min_distance).c_str(),
                number(r.max_strain).c_str(), number(err.first).c_str(),
                number(err.second).c_str());
    std::fflush(stdout);
    if (!r.ok) status = 3;
  }
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse(argc, argv));
  } catch (const UsageError& e) {
    std::fprintf(stderr, "%s\n%s", e.message.c_str(), kUsage);
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
}
