// cloth_sim_run: headless runner. Loads a scene, steps it, writes the final
// state, statistics, an OBJ mesh and a position trace. Uses the core API only.
//
// Exit codes: 0 success, 2 bad input (scene or arguments), 3 the simulation
// failed (a step was rejected or the state became non-finite).
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "cloth_sim/json_text.hpp"
#include "cloth_sim/limits.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"

namespace {

using cloth_sim::jsonNumber;
using cloth_sim::jsonString;

constexpr int kExitOk = 0;
constexpr int kExitBadInput = 2;
constexpr int kExitSimulationFailed = 3;

const char* const kUsage =
    "usage: cloth_sim_run SCENE.yaml [--duration S | --steps N] [--set key.path=value]...\n"
    "                     [--out FILE] [--stats FILE] [--obj FILE] [--trace FILE] [--obj-sequence DIR]\n"
    "                     [--every K]";

const char* const kHelp =
    "\n"
    "Runs a cloth_sim scene headless and writes its results.\n"
    "\n"
    "  --duration S       simulate S seconds: ceil(S / solver.dt) steps (default 1 s);\n"
    "                     with solver.error_tolerance the steps its control picks\n"
    "  --steps N          simulate exactly N steps\n"
    "  --set key=value    override a scene field, e.g. --set solver.dt=0.001 (repeatable)\n"
    "  --out FILE         final state, one line per node: x y z vx vy vz\n"
    "  --stats FILE       run statistics as one JSON object\n"
    "  --obj FILE         final mesh as Wavefront OBJ with vertex normals\n"
    "  --trace FILE       positions over time, one line per sample: t x0 y0 z0 x1 ...\n"
    "  --obj-sequence DIR one OBJ per sample, DIR/frame_00000.obj, frame_00001.obj, ... (t = 0\n"
    "                     and every K steps; DIR must exist): a sequence to render\n"
    "  --every K          trace / obj-sequence every K steps (and at t = 0); default 1\n"
    "  --help             print this help\n"
    "\n"
    "Exit status: 0 success, 2 bad input, 3 the simulation failed (non-finite state or\n"
    "a rejected step); --stats is written in that case too, --out and --obj are not.\n";

/// Bad command line: what() names the flag.
struct UsageError {
  std::string message;
};

struct Options {
  std::string scene_path;
  std::optional<double> duration;
  std::optional<long> steps;
  std::vector<std::string> overrides;
  std::string out_path, stats_path, obj_path, trace_path, obj_dir;
  std::optional<long> every;
  bool help = false;
};

double parseNumber(const std::string& flag, const std::string& text) {
  const char* begin = text.c_str();
  char* end = nullptr;
  const double value = std::strtod(begin, &end);
  if (text.empty() || end != begin + text.size() || !std::isfinite(value))
    throw UsageError{flag + ": expected a finite number, got '" + text + "'"};
  return value;
}

long parseCount(const std::string& flag, const std::string& text, long min_value) {
  const char* begin = text.c_str();
  char* end = nullptr;
  errno = 0;
  const long value = std::strtol(begin, &end, 10);
  if (text.empty() || end != begin + text.size() || errno == ERANGE)
    throw UsageError{flag + ": expected an integer, got '" + text + "'"};
  if (value < min_value)
    throw UsageError{flag + ": must be >= " + std::to_string(min_value) + ", got " + text};
  return value;
}

Options parseArguments(int argc, char** argv) {
  Options opt;
  std::vector<std::string> positional;
  for (int a = 1; a < argc; ++a) {
    std::string arg = argv[a];
    if (arg == "--help" || arg == "-h") {
      opt.help = true;
      return opt;
    }
    if (arg.size() < 2 || arg.compare(0, 2, "--") != 0) {
      positional.push_back(arg);
      continue;
    }
    // Accept both "--flag value" and "--flag=value".
    std::string flag = arg, value;
    bool has_value = false;
    const size_t eq = arg.find('=');
    if (eq != std::string::npos) {
      flag = arg.substr(0, eq);
      value = arg.substr(eq + 1);
      has_value = true;
    }
    auto takeValue = [&]() -> std::string {
      if (has_value) return value;
      if (a + 1 >= argc) throw UsageError{flag + ": missing value"};
      return argv[++a];
    };
    auto takePath = [&]() -> std::string {
      std::string path = takeValue();
      if (path.empty()) throw UsageError{flag + ": missing file name"};
      return path;
    };
    auto once = [&](bool already_given) {
      if (already_given) throw UsageError{flag + ": given more than once"};
    };
    if (flag == "--duration") {
      once(opt.duration.has_value());
      const std::string text = takeValue();
      opt.duration = parseNumber(flag, text);
      if (*opt.duration < 0.0) throw UsageError{"--duration: must be >= 0, got " + text};
    } else if (flag == "--steps") {
      once(opt.steps.has_value());
      opt.steps = parseCount(flag, takeValue(), 0);
    } else if (flag == "--set") {
      const std::string assignment = takeValue();
      const size_t at = assignment.find('=');
      if (at == std::string::npos || at == 0)
        throw UsageError{"--set: expected key.path=value, got '" + assignment + "'"};
      opt.overrides.push_back(assignment);
    } else if (flag == "--out") {
      once(!opt.out_path.empty());
      opt.out_path = takePath();
    } else if (flag == "--stats") {
      once(!opt.stats_path.empty());
      opt.stats_path = takePath();
    } else if (flag == "--obj") {
      once(!opt.obj_path.empty());
      opt.obj_path = takePath();
    } else if (flag == "--trace") {
      once(!opt.trace_path.empty());
      opt.trace_path = takePath();
    } else if (flag == "--obj-sequence") {
      once(!opt.obj_dir.empty());
      opt.obj_dir = takePath();
    } else if (flag == "--every") {
      once(opt.every.has_value());
      opt.every = parseCount(flag, takeValue(), 1);
    } else {
      throw UsageError{arg + ": unknown option"};
    }
  }
  if (positional.empty()) throw UsageError{"SCENE.yaml: missing scene file"};
  if (positional.size() > 1)
    throw UsageError{positional[1] + ": unexpected argument (only one scene file)"};
  opt.scene_path = positional[0];
  if (opt.duration && opt.steps)
    throw UsageError{"--duration, --steps: give at most one of them"};
  if (opt.every && opt.trace_path.empty() && opt.obj_dir.empty())
    throw UsageError{"--every: needs --trace FILE or --obj-sequence DIR"};
  return opt;
}

/// Number of steps that covers `duration` (robust against dt not dividing it).
double stepsForDuration(double duration, double dt) {
  return std::max(0.0, std::ceil(duration / dt - 1e-9));
}

bool allFinite(const cloth_sim::VecX& v) { return v.allFinite(); }

/// Writes "t x0 y0 z0 x1 ..." with %.17g.
void writeTraceLine(std::FILE* f, double t, const cloth_sim::VecX& x) {
  std::fprintf(f, "%.17g", t);
  for (Eigen::Index k = 0; k < x.size(); ++k) std::fprintf(f, " %.17g", x[k]);
  std::fputc('\n', f);
}

bool writeState(const std::string& path, const cloth_sim::Simulation& sim) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) return false;
  const cloth_sim::VecX& x = sim.positions();
  const cloth_sim::VecX& v = sim.velocities();
  for (int i = 0; i < sim.numNodes(); ++i)
    std::fprintf(f, "%.17g %.17g %.17g %.17g %.17g %.17g\n", x[3 * i], x[3 * i + 1],
                 x[3 * i + 2], v[3 * i], v[3 * i + 1], v[3 * i + 2]);
  return std::fclose(f) == 0;
}

/// Accumulated over the run.
struct RunStats {
  long steps = 0;
  double wall_time_s = 0.0;
  long cg_iterations_total = 0;
  int cg_iterations_max = 0;
  long newton_iterations_total = 0;
  double max_residual = 0.0;
  double energy_initial = 0.0;
  double energy_final = 0.0;
  double max_strain = 0.0;
  bool finite = true;
  long substeps = 0;
  long rejected_steps = 0;
  long error_rejected_steps = 0;  ///< error control: steps redone smaller
  double h_min = 0.0, h_max = 0.0;  ///< step sizes taken, s
  long refined_steps = 0;        ///< implicit_euler steps solved on by newton
  long order_reduced_steps = 0;  ///< bdf2 steps retried as backward Euler
  int max_halvings = 0;
  int contacts = 0;                   ///< at the final step
  double contact_normal_force = 0.0;  ///< at the final step, N
  long contact_passes = 0;
  long contact_queries = 0;
  int self_contacts = 0;  ///< at the final step
  double self_collision_s = 0.0;
  std::optional<std::string> failure;

  void add(const cloth_sim::StepStats& s) {
    ++steps;
    cg_iterations_total += s.cg_iterations;
    cg_iterations_max = std::max(cg_iterations_max, s.cg_iterations);
    newton_iterations_total += s.newton_iterations;
    max_residual = std::max(max_residual, s.residual);
    max_strain = std::max(max_strain, s.max_strain);
    substeps += s.substeps;
    rejected_steps += s.rejected;
    error_rejected_steps += s.error_rejected;
    h_min = cloth_sim::smallerStep(h_min, s.h_min);
    h_max = std::max(h_max, s.h_max);
    refined_steps += s.refined;
    order_reduced_steps += s.order_reduced;
    max_halvings = std::max(max_halvings, s.halvings);
    contacts = s.contacts;
    contact_normal_force = s.contact_normal_force;
    contact_passes += s.contact_passes;
    contact_queries += s.contact_queries;
    self_contacts = s.self_contacts;
    self_collision_s += s.self_collision_s;
  }
  double perStep(double total) const { return steps > 0 ? total / steps : 0.0; }
};

bool writeStats(const std::string& path, const RunStats& r, const cloth_sim::Simulation& sim) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) return false;
  const cloth_sim::Scene& scene = sim.scene();
  std::fprintf(f, "{\n");
  std::fprintf(f, "  \"steps\": %ld,\n", r.steps);
  std::fprintf(f, "  \"sim_time\": %s,\n", jsonNumber(sim.time()).c_str());
  std::fprintf(f, "  \"wall_time_s\": %s,\n", jsonNumber(r.wall_time_s).c_str());
  std::fprintf(f, "  \"ms_per_step\": %s,\n", jsonNumber(1e3 * r.perStep(r.wall_time_s)).c_str());
  std::fprintf(f, "  \"cg_iterations_mean\": %s,\n",
               jsonNumber(r.perStep(static_cast<double>(r.cg_iterations_total))).c_str());
  std::fprintf(f, "  \"cg_iterations_max\": %d,\n", r.cg_iterations_max);
  std::fprintf(f, "  \"newton_iterations_mean\": %s,\n",
               jsonNumber(r.perStep(static_cast<double>(r.newton_iterations_total))).c_str());
  std::fprintf(f, "  \"max_residual\": %s,\n", jsonNumber(r.max_residual).c_str());
  std::fprintf(f, "  \"energy_initial\": %s,\n", jsonNumber(r.energy_initial).c_str());
  std::fprintf(f, "  \"energy_final\": %s,\n", jsonNumber(r.energy_final).c_str());
  std::fprintf(f, "  \"max_strain\": %s,\n", jsonNumber(r.max_strain).c_str());
  std::fprintf(f, "  \"finite\": %s,\n", r.finite ? "true" : "false");
  std::fprintf(f, "  \"substeps\": %ld,\n", r.substeps);
  std::fprintf(f, "  \"rejected_steps\": %ld,\n", r.rejected_steps);
  std::fprintf(f, "  \"error_rejected_steps\": %ld,\n", r.error_rejected_steps);
  std::fprintf(f, "  \"dt_smallest\": %s,\n", jsonNumber(r.h_min).c_str());
  std::fprintf(f, "  \"dt_largest\": %s,\n", jsonNumber(r.h_max).c_str());
  std::fprintf(f, "  \"refined_steps\": %ld,\n", r.refined_steps);
  std::fprintf(f, "  \"order_reduced_steps\": %ld,\n", r.order_reduced_steps);
  std::fprintf(f, "  \"max_halvings\": %d,\n", r.max_halvings);
  // Contact: zeros without colliders.
  std::fprintf(f, "  \"contacts\": %d,\n", r.contacts);
  std::fprintf(f, "  \"contact_normal_force\": %s,\n", jsonNumber(r.contact_normal_force).c_str());
  std::fprintf(f, "  \"max_penetration\": %s,\n", jsonNumber(sim.maxPenetration()).c_str());
  std::fprintf(f, "  \"contact_passes_mean\": %s,\n",
               jsonNumber(r.perStep(static_cast<double>(r.contact_passes))).c_str());
  std::fprintf(f, "  \"contact_queries_mean\": %s,\n",
               jsonNumber(r.perStep(static_cast<double>(r.contact_queries))).c_str());
  // Self-collision: 0 and null without it.
  std::fprintf(f, "  \"self_contacts\": %d,\n", r.self_contacts);
  std::fprintf(f, "  \"min_self_distance\": %s,\n", jsonNumber(sim.minSelfDistance()).c_str());
  std::fprintf(f, "  \"self_collision_ms_per_step\": %s,\n",
               jsonNumber(1e3 * r.perStep(r.self_collision_s)).c_str());
  std::fprintf(f, "  \"failure\": %s,\n", r.failure ? jsonString(*r.failure).c_str() : "null");
  std::fprintf(f, "  \"method\": %s,\n", jsonString(cloth_sim::toString(scene.solver.method)).c_str());
  std::fprintf(f, "  \"dt\": %s,\n", jsonNumber(scene.solver.dt).c_str());
  std::fprintf(f, "  \"nodes\": %d\n", sim.numNodes());
  std::fprintf(f, "}\n");
  return std::fclose(f) == 0;
}

int badInput(const std::string& message) {
  std::fprintf(stderr, "cloth_sim_run: %s\n%s\n", message.c_str(), kUsage);
  return kExitBadInput;
}

int run(const Options& opt) {
  std::optional<cloth_sim::Simulation> sim;
  try {
    sim.emplace(cloth_sim::loadScene(opt.scene_path, opt.overrides));
  } catch (const std::exception& e) {  // SceneError, or a parser error that escaped
    // Name the file unless the message already does.
    const std::string message = e.what();
    return badInput(message.rfind(opt.scene_path, 0) == 0 ? message
                                                          : opt.scene_path + ": " + message);
  }

  const double dt = sim->dt();
  long total_steps = 0;
  if (opt.steps) {
    const cloth_sim::Status work =
        cloth_sim::checkWork("--steps", static_cast<double>(*opt.steps), sim->numNodes(),
                             cloth_sim::kMaxRunNodeSteps);
    if (!work) return badInput(work.message);
    total_steps = *opt.steps;
  } else {
    const double n = stepsForDuration(opt.duration.value_or(1.0), dt);
    const cloth_sim::Status work =
        cloth_sim::checkWork("--duration (at solver.dt " + jsonNumber(dt) + " s)", n,
                             sim->numNodes(), cloth_sim::kMaxRunNodeSteps);
    if (!work) return badInput(work.message);
    total_steps = static_cast<long>(n);
  }
  const long every = opt.every.value_or(1);

  // Open streamed outputs first, so a bad path fails before any work.
  std::FILE* trace = nullptr;
  if (!opt.trace_path.empty()) {
    trace = std::fopen(opt.trace_path.c_str(), "w");
    if (!trace) return badInput("--trace: cannot write '" + opt.trace_path + "': " + std::strerror(errno));
  }
  if (!opt.stats_path.empty()) {
    std::FILE* probe = std::fopen(opt.stats_path.c_str(), "w");
    if (!probe) {
      if (trace) std::fclose(trace);
      return badInput("--stats: cannot write '" + opt.stats_path + "': " + std::strerror(errno));
    }
    std::fclose(probe);
  }

  // The OBJ sequence: frame_00000.obj at t = 0, then one per trace sample.
  long frame = 0;
  std::string frame_error;
  auto writeFrame = [&]() {
    char name[32];
    std::snprintf(name, sizeof name, "/frame_%05ld.obj", frame++);
    const std::string path = opt.obj_dir + name;
    if (!cloth_sim::writeObj(path, sim->model(), sim->positions())) {
      frame_error = "--obj-sequence: cannot write '" + path + "'";
    }
    return frame_error.empty();
  };
  if (!opt.obj_dir.empty() && !writeFrame()) {
    if (trace) std::fclose(trace);
    return badInput(frame_error);
  }

  RunStats stats;
  stats.energy_initial = sim->energy();
  if (!allFinite(sim->positions()) || !allFinite(sim->velocities())) {
    stats.finite = false;
    stats.failure = "initial state is not finite";
  } else if (trace) {
    writeTraceLine(trace, sim->time(), sim->positions());
  }

  using Clock = std::chrono::steady_clock;
  // Error-controlled stepping runs to the duration in the steps its control
  // picks, the last one landing on it; --steps N takes N such steps.
  const bool to_time = sim->adaptive() && !opt.steps;
  const double t_end = opt.duration.value_or(1.0);
  for (long k = 0; (to_time ? sim->time() < t_end - 1e-9 * dt : k < total_steps) && !stats.failure;
       ++k) {
    const double t_before = sim->time();
    cloth_sim::StepStats s;
    const auto start = Clock::now();
    try {
      s = to_time ? sim->stepToward(t_end) : sim->step();
    } catch (const std::exception& e) {
      s.ok = false;
      s.failure = std::string("exception: ") + e.what();
    }
    const double wall = std::chrono::duration<double>(Clock::now() - start).count();
    const bool finite = s.finite && allFinite(sim->positions()) && allFinite(sim->velocities());
    if (!s.ok || !finite) {
      stats.rejected_steps += s.rejected;
      stats.max_halvings = std::max(stats.max_halvings, s.halvings);
      stats.finite = false;  // the run did not stay finite and well-posed to the end
      stats.failure = !s.failure.empty() ? s.failure
                                         : std::string(finite ? "step failed" : "state became non-finite");
      std::fprintf(stderr, "cloth_sim_run: step %ld (t = %.9g s) failed: %s\n", k + 1, t_before,
                   stats.failure->c_str());
      break;
    }
    stats.add(s);
    stats.wall_time_s += wall;  // completed steps only, so ms_per_step is per step
    if (trace && (k + 1) % every == 0) writeTraceLine(trace, sim->time(), sim->positions());
    if (!opt.obj_dir.empty() && (k + 1) % every == 0 && !writeFrame()) break;
  }
  const bool failed = stats.failure.has_value();
  stats.energy_final = sim->energy();

  int status = kExitOk;
  if (!frame_error.empty()) status = badInput(frame_error);
  if (trace && std::fclose(trace) != 0)
    status = badInput("--trace: error writing '" + opt.trace_path + "'");
  if (!opt.stats_path.empty() && !writeStats(opt.stats_path, stats, *sim))
    status = badInput("--stats: error writing '" + opt.stats_path + "'");
  if (!failed) {  // a failed state is never written
    if (!opt.out_path.empty() && !writeState(opt.out_path, *sim))
      status = badInput("--out: cannot write '" + opt.out_path + "'");
    if (!opt.obj_path.empty() && !cloth_sim::writeObj(opt.obj_path, sim->model(), sim->positions()))
      status = badInput("--obj: cannot write '" + opt.obj_path + "'");
  }

  std::printf("cloth_sim_run: %s%ld steps, sim time %.6g s, %.4g ms/step, mean CG iterations %.1f\n",
              failed ? "FAILED after " : "", stats.steps, sim->time(),
              1e3 * stats.perStep(stats.wall_time_s),
              stats.perStep(static_cast<double>(stats.cg_iterations_total)));
  return failed ? kExitSimulationFailed : status;
}

}  // namespace

int main(int argc, char** argv) {
  Options opt;
  try {
    opt = parseArguments(argc, argv);
  } catch (const UsageError& e) {
    return badInput(e.message);
  }
  if (opt.help) {
    std::printf("%s\n%s", kUsage, kHelp);
    return kExitOk;
  }
  return run(opt);
}
