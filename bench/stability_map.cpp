// One run of the stability map (scripts/stability_map): a scene with
// overrides, simulated for a given time under a wall-time cap, classified as
// the hard-case suite judges a run, printed as one JSON line.
//
//   cloth_sim_stability_run SCENE.yaml --time T --wall-cap S [--set key=value]...
//
// status:  pass       every step succeeded with no recovery
//          recovered  every step succeeded, some after step halving (max_halvings;
//                     linearized: newton/bdf2 sub-steps taken as linearized
//                     backward-Euler steps at the deepest halving)
//          fail       a step failed even after recovery (reason: energy, newton,
//                     linear, non-finite, ...), or was accepted with a solver short
//                     of its tolerance (reason: unconverged; a linearized sub-step
//                     is the recovery's, not that), or the energy rose
//                     silently (reason: energy rise: without inputs above 1e-9 of
//                     the energy scale (1e-6 with colliders or self-collision)
//                     plus the step's energy_round_off in a step, else above the
//                     initial energy plus the work in by 1e-6 of the initial scale)
//          slow       the wall-time cap ran out first (sim_time says how far it got)
// Exit status: 0 whenever a line was printed (whatever the status), 2 on bad input.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cloth_sim/json_text.hpp"
#include "cloth_sim/simulation.hpp"

namespace {

using Clock = std::chrono::steady_clock;
using cloth_sim::jsonNumber;
using cloth_sim::jsonString;

/// Short reason from a StepStats failure text.
std::string category(const std::string& failure) {
  if (failure.find("non-finite") != std::string::npos) return "non-finite";
  if (failure.find("energy") != std::string::npos) return "energy";
  if (failure.find("newton") != std::string::npos) return "newton";
  if (failure.find("linear") != std::string::npos) return "linear";
  return failure.empty() ? "unknown" : failure;
}

double energyScale(const cloth_sim::Simulation& sim) {
  double mass = 0.0;
  for (double m : sim.model().mass) mass += m;
  const auto& c = sim.scene().cloth;
  const double size = std::hypot(c.cols > 1 ? c.width : 0.0, c.length);
  return sim.kineticEnergy() + sim.elasticEnergy() + mass * sim.model().gravity.norm() * size +
         1e-12;
}

/// Inputs do work: moving pins, stiffness changes. Pinning and releasing do not.
bool hasInputs(const cloth_sim::Scene& scene) {
  for (const auto& e : scene.events) {
    if (e.kind == cloth_sim::SceneEvent::Kind::MovePin ||
        e.kind == cloth_sim::SceneEvent::Kind::SetStiffness) {
      return true;
    }
  }
  return false;
}

int usage(const std::string& message) {
  std::fprintf(stderr,
               "cloth_sim_stability_run: %s\n"
               "usage: cloth_sim_stability_run SCENE.yaml --time T --wall-cap S "
               "[--set key=value]...\n",
               message.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_path;
  double sim_time = -1.0, wall_cap = -1.0;
  std::vector<std::string> overrides;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&](const char* flag) -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "cloth_sim_stability_run: %s needs a value\n", flag);
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--time") {
      sim_time = std::atof(value("--time"));
    } else if (arg == "--wall-cap") {
      wall_cap = std::atof(value("--wall-cap"));
    } else if (arg == "--set") {
      overrides.push_back(value("--set"));
    } else if (!arg.empty() && arg[0] != '-' && scene_path.empty()) {
      scene_path = arg;
    } else {
      return usage("unknown argument '" + arg + "'");
    }
  }
  if (scene_path.empty()) return usage("no scene file");
  if (!(sim_time > 0.0)) return usage("--time: must be > 0");
  if (!(wall_cap > 0.0)) return usage("--wall-cap: must be > 0");

  cloth_sim::Scene scene;
  try {
    scene = cloth_sim::loadScene(scene_path, overrides);
  } catch (const std::exception& e) {
    return usage(e.what());
  }
  cloth_sim::Simulation sim(scene);
  const bool inputs = hasInputs(scene);
  const bool symplectic = scene.solver.method == cloth_sim::Method::SymplecticEuler;
  // A step's allowed energy gain without inputs, as the suites judge it: 1e-9
  // of the scale; with colliders or self-collision 1e-6, as the contact suite
  // and the core's check (their friction is lagged across passes and steps).
  const double rise_allowance =
      scene.colliders.empty() && !scene.self_collision.enabled ? 1e-9 : 1e-6;
  const double e0 = sim.energy(), scale0 = energyScale(sim);
  const long steps = std::max(1L, std::lround(sim_time / scene.solver.dt));

  std::string status = "pass", reason;
  int max_halvings = 0;
  long rejected = 0, substeps = 0, done = 0, linearized = 0, refined = 0;
  double max_strain = 0.0, previous = e0;
  const auto start = Clock::now();
  for (long n = 0; n < steps; ++n) {
    if (std::chrono::duration<double>(Clock::now() - start).count() > wall_cap) {
      status = "slow";
      reason = "wall-time cap";
      break;
    }
    const double scale = energyScale(sim);
    const cloth_sim::StepStats s = sim.step();
    rejected += s.rejected;
    linearized += s.linearized;
    refined += s.refined;
    max_halvings = std::max(max_halvings, s.halvings);
    if (!s.ok) {
      status = "fail";
      reason = category(s.failure);
      break;
    }
    ++done;
    substeps += s.substeps;
    if (!(s.finite && sim.positions().allFinite() && sim.velocities().allFinite())) {
      status = "fail";
      reason = "non-finite (silent)";
      break;
    }
    if (!s.linear_converged || (!s.newton_converged && s.linearized == 0)) {
      status = "fail";
      reason = std::string("unconverged ") + (s.linear_converged ? "newton" : "linear");
      break;
    }
    // symplectic_euler's energy oscillates by design: only the core's blow-up
    // test applies to it.
    const bool rise = !symplectic && (inputs ? s.energy > e0 + sim.totalWorkIn() + 1e-6 * scale0
                                             : s.energy - previous > rise_allowance * scale + s.energy_round_off);
    if (rise) {
      status = "fail";
      reason = "energy rise";
      break;
    }
    previous = s.energy;
    max_strain = std::max(max_strain, s.max_strain);
  }
  if (status == "pass" && max_halvings > 0) status = "recovered";
  const double wall = std::chrono::duration<double>(Clock::now() - start).count();

  std::printf(
      "{\"scene\": %s, \"method\": %s, \"stretch\": %s, \"dt\": %s, \"status\": %s, "
      "\"reason\": %s, \"max_halvings\": %d, \"rejected\": %ld, \"linearized\": %ld, "
      "\"refined\": %ld, \"steps\": %ld, "
      "\"substeps\": %ld, \"sim_time\": %s, \"wall_s\": %s, \"max_strain\": %s}\n",
      jsonString(scene_path).c_str(), jsonString(cloth_sim::toString(scene.solver.method)).c_str(),
      jsonNumber(sim.group(cloth_sim::SpringType::Stretch).present
                     ? scene.springs[static_cast<int>(cloth_sim::SpringType::Stretch)].stiffness
                     : 0.0,
                 6)
          .c_str(),
      jsonNumber(scene.solver.dt, 6).c_str(), jsonString(status).c_str(), jsonString(reason).c_str(),
      max_halvings, rejected, linearized, refined, done, substeps, jsonNumber(sim.time(), 6).c_str(),
      jsonNumber(wall, 6).c_str(), jsonNumber(max_strain, 6).c_str());
  return 0;
}
