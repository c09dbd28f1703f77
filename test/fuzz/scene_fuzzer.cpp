// libFuzzer harness over everything that reads untrusted text or values:
// the scene YAML, the --set key.path=value overrides, and the runtime
// requests the node's services map onto (pin, release, move, stiffness,
// reset). Built with -fsanitize=address,undefined (test/sanitize/).
//
// Input layout: the scene YAML text, where every line that starts with
// "--set " is taken out of the text and becomes one override (as
// cloth_sim_run's --set), and every line that starts with "#call " is a
// runtime request (see applyCall) made between the first steps.
//
// Each input must end in one of: a SceneError (the CLI's exit 2), a run that
// stays finite, or steps that fail loudly (ok = false, a reason, the state of
// before the step). Anything else aborts: an exception of another type, a
// non-finite state or statistic after a step reported ok, a failed step
// without a reason or that changed the state, an empty error message.
//
// Work per input is bounded so the fuzzer explores instead of waiting: only
// scenes of at most kMaxFuzzNodes nodes are stepped, for at most kMaxFuzzSteps
// steps and kFuzzNodeSteps node-steps, with the CG cap (100), Newton cap (5)
// and halving depth (2) clamped. The parse and
// validation of every scene, whatever its size, are fuzzed in full; the run
// limits themselves are checked by the CLI tests (test/core/test_hardening.cpp).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"

namespace {

constexpr int kMaxFuzzNodes = 144;       // 12 x 12: multigrid still has two levels
constexpr int kFuzzNodeSteps = 300;      // steps = clamp(300 / nodes, 1, 6)
constexpr int kMaxFuzzSteps = 6;
constexpr int kMaxFuzzCalls = 16;

[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "scene_fuzzer finding: %s\n", what.c_str());
  std::abort();
}

struct FuzzInput {
  std::string scene;
  std::vector<std::string> overrides;
  std::vector<std::string> calls;
};

FuzzInput split(const std::string& text) {
  FuzzInput in;
  size_t pos = 0;
  while (pos <= text.size()) {
    size_t end = text.find('\n', pos);
    const bool last = end == std::string::npos;
    if (last) end = text.size();
    const std::string line = text.substr(pos, end - pos);
    if (line.rfind("--set ", 0) == 0) {
      in.overrides.push_back(line.substr(6));
    } else if (line.rfind("#call ", 0) == 0) {
      if (in.calls.size() < kMaxFuzzCalls) in.calls.push_back(line.substr(6));
    } else {
      in.scene += line;
      if (!last) in.scene += '\n';
    }
    if (last) break;
    pos = end + 1;
  }
  return in;
}

/// Numbers as a service request carries them: any double, NaN and inf too.
double number(std::istringstream& words) {
  std::string token;
  if (!(words >> token)) return 0.0;
  if (token == "nan") return std::nan("");
  if (token == "inf") return HUGE_VAL;
  if (token == "-inf") return -HUGE_VAL;
  char* end = nullptr;
  const double value = std::strtod(token.c_str(), &end);
  return value;
}

long integer(std::istringstream& words) {
  std::string token;
  if (!(words >> token)) return 0;
  return std::strtol(token.c_str(), nullptr, 10);
}

/// One runtime request as the node makes it from a service call:
///   pin I [I...] | pin_at I X Y Z | release I [I...] | release_all |
///   move I X Y Z VX VY VZ D | drive I VX VY VZ D | stiffness TYPE K C | reset
void applyCall(cloth_sim::Simulation& sim, const std::string& call) {
  std::istringstream words(call);
  std::string verb;
  words >> verb;
  cloth_sim::Status status;
  bool has_status = true;
  // Indices arrive as uint32 in the services; the node range-checks them as
  // long before the core sees an int. Values beyond int are clamped here as
  // the node's check would reject them anyway.
  auto index = [&]() {
    const long i = integer(words);
    return static_cast<int>(std::max<long>(-1000000, std::min<long>(1000000, i)));
  };
  if (verb == "pin" || verb == "release") {
    std::vector<int> indices;
    while (words.good() && indices.size() < 8) {
      std::string token;
      if (!(words >> token)) break;
      const long i = std::strtol(token.c_str(), nullptr, 10);
      indices.push_back(static_cast<int>(std::max<long>(-1000000, std::min<long>(1000000, i))));
    }
    status = verb == "pin" ? sim.pin(indices) : sim.release(indices);
  } else if (verb == "pin_at") {
    const int i = index();
    const double x = number(words), y = number(words), z = number(words);
    status = sim.pin({i}, {cloth_sim::Vec3(x, y, z)});
  } else if (verb == "release_all") {
    sim.releaseAll();
    has_status = false;
  } else if (verb == "move") {
    const int i = index();
    const double x = number(words), y = number(words), z = number(words);
    const double vx = number(words), vy = number(words), vz = number(words);
    status = sim.movePin(i, cloth_sim::Vec3(x, y, z), cloth_sim::Vec3(vx, vy, vz), number(words));
  } else if (verb == "drive") {
    const int i = index();
    const double vx = number(words), vy = number(words), vz = number(words);
    status = sim.drivePin(i, cloth_sim::Vec3(vx, vy, vz), number(words));
  } else if (verb == "stiffness") {
    std::string type;
    words >> type;
    const double k = number(words);
    status = sim.setStiffness(type, k, number(words));
  } else if (verb == "reset") {
    sim.reset();
    has_status = false;
  } else {
    return;
  }
  if (has_status && !status.ok && status.message.empty()) {
    finding("request '" + call + "' refused without a message");
  }
}

void checkState(const cloth_sim::Simulation& sim, const std::string& when) {
  if (!sim.positions().allFinite() || !sim.velocities().allFinite()) {
    finding("non-finite state " + when);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size > 64 * 1024) return 0;  // scene files are small; keeps the search on structure
  const FuzzInput in = split(std::string(reinterpret_cast<const char*>(data), size));

  cloth_sim::Scene scene;
  try {
    scene = cloth_sim::parseScene(in.scene, in.overrides);
  } catch (const cloth_sim::SceneError& e) {
    if (std::string(e.what()).empty()) finding("SceneError without a message");
    return 0;  // the CLI's exit 2
  }
  // Any other exception escapes to libFuzzer, which reports it as a crash.

  if (scene.numNodes() > kMaxFuzzNodes) return 0;
  scene.solver.max_iterations = std::min(scene.solver.max_iterations, 100);
  scene.solver.newton_max_iterations = std::min(scene.solver.newton_max_iterations, 5);
  scene.solver.max_halvings = std::min(scene.solver.max_halvings, 2);
  const int steps = std::max(1, std::min(kMaxFuzzSteps, kFuzzNodeSteps / scene.numNodes()));

  cloth_sim::Simulation sim(scene);  // a valid scene must construct
  checkState(sim, "at t = 0");
  size_t next_call = 0;
  for (int k = 0; k < steps; ++k) {
    // The requests are spread over the steps, all of them made.
    const size_t calls_due = in.calls.size() * static_cast<size_t>(k + 1) / steps;
    while (next_call < calls_due) applyCall(sim, in.calls[next_call++]);
    checkState(sim, "after a request");
    const cloth_sim::VecX x_before = sim.positions(), v_before = sim.velocities();
    const double t_before = sim.time();
    const cloth_sim::StepStats stats = sim.step();
    checkState(sim, "after step " + std::to_string(k));
    if (stats.ok) {
      if (!stats.finite) finding("step ok but not finite");
      if (!std::isfinite(stats.energy) || !std::isfinite(stats.max_strain) ||
          !std::isfinite(stats.residual)) {
        finding("step ok with a non-finite statistic");
      }
      if (!(sim.time() > t_before)) finding("step ok but time did not advance");
    } else {
      if (stats.failure.empty()) finding("failed step without a reason");
      if (sim.positions() != x_before || sim.velocities() != v_before) {
        finding("failed step changed the state");
      }
      break;  // the CLI stops here (exit 3)
    }
  }
  // What the CLI would write at the end: energy, strain, normals.
  if (!std::isfinite(sim.energy()) || !std::isfinite(sim.maxStrain())) {
    finding("non-finite energy or strain of a finite state");
  }
  for (const cloth_sim::Vec3& n : cloth_sim::vertexNormals(sim.model(), sim.positions())) {
    if (!n.allFinite()) finding("non-finite vertex normal");
  }
  return 0;
}
