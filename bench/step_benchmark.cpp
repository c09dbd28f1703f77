// Time per step, CG iterations and residual on the seed scene and the demo
// cloth at 32x32, 64x64, 128x128. Release build, single thread.
//   step_benchmark [--steps N] [--repeats R] [--set key=value ...] [SCENE.yaml ...]
// With no scene arguments it runs the standard set from the package config.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cloth_sim/simulation.hpp"

namespace {

struct Case {
  std::string label;
  std::string path;
  std::vector<std::string> overrides;
};

struct Result {
  double us_per_step = 0.0;
  double cg_mean = 0.0;
  int cg_max = 0;
  double max_residual = 0.0;
  double assembly_share = 0.0;
};

/// Median over repeats of wall time per step for `steps` steps from rest.
Result run(const cloth_sim::Scene& scene, int steps, int repeats) {
  std::vector<double> times;
  Result r;
  for (int rep = 0; rep <= repeats; ++rep) {  // rep 0 warms up
    cloth_sim::Simulation sim(scene);
    long cg = 0;
    int cg_max = 0;
    double residual = 0.0, assembly = 0.0, total = 0.0;
    const auto start = std::chrono::steady_clock::now();
    for (int n = 0; n < steps; ++n) {
      const cloth_sim::StepStats s = sim.step();
      cg += s.cg_iterations;
      cg_max = std::max(cg_max, s.cg_iterations);
      residual = std::max(residual, s.residual);
      assembly += s.assembly_s;
      total += s.wall_time_s;
    }
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (rep == 0) continue;
    times.push_back(elapsed / steps * 1e6);
    r.cg_mean = static_cast<double>(cg) / steps;
    r.cg_max = cg_max;
    r.max_residual = residual;
    r.assembly_share = total > 0 ? assembly / total : 0.0;
  }
  std::sort(times.begin(), times.end());
  r.us_per_step = times[times.size() / 2];
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  int steps = 200, repeats = 5;
  std::vector<Case> cases;
  std::vector<std::string> sets;  // applied to every case, after its own overrides
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg == "--steps" && a + 1 < argc) {
      steps = std::atoi(argv[++a]);
    } else if (arg == "--repeats" && a + 1 < argc) {
      repeats = std::atoi(argv[++a]);
    } else if (arg == "--set" && a + 1 < argc) {
      sets.push_back(argv[++a]);
    } else {
      cases.push_back({arg, arg, {}});
    }
  }
  if (cases.empty()) {
    const std::string dir = CLOTH_SIM_SOURCE_DIR "/config/";
    const std::string seed = dir + "scenes/seed.yaml", demo = dir + "demo.yaml";
    cases = {
        {"seed, original setting (plain CG to 1e-2)", seed, {}},
        {"seed, block-Jacobi CG to 1e-8", seed, {"solver.preconditioner=block_jacobi", "solver.tolerance=1e-8"}},
        {"seed, Cholesky to 1e-8", seed, {"solver.preconditioner=cholesky", "solver.tolerance=1e-8"}},
    };
    for (int n : {32, 64, 128}) {
      const std::string size = std::to_string(n);
      const std::vector<std::string> grid = {"cloth.rows=" + size, "cloth.cols=" + size,
                                             "pins=[0," + std::to_string(n - 1) + "]"};
      for (const char* pre : {"block_jacobi", "cholesky", "multigrid"}) {
        auto o = grid;
        o.push_back(std::string("solver.preconditioner=") + pre);
        o.push_back("solver.tolerance=1e-6");
        cases.push_back({"demo " + size + "x" + size + ", " + pre + " CG to 1e-6", demo, o});
      }
    }
  }
  for (Case& c : cases) c.overrides.insert(c.overrides.end(), sets.begin(), sets.end());
  std::printf("%-46s %12s %9s %7s %11s %9s\n", "scene", "us/step", "CG mean", "CG max",
              "max resid", "assembly");
  for (const Case& c : cases) {
    try {
      const cloth_sim::Scene scene = cloth_sim::loadScene(c.path, c.overrides);
      const Result r = run(scene, steps, repeats);
      std::printf("%-46s %12.1f %9.1f %7d %11.2e %8.0f%%\n", c.label.c_str(), r.us_per_step,
                  r.cg_mean, r.cg_max, r.max_residual, 100.0 * r.assembly_share);
      std::fflush(stdout);
    } catch (const cloth_sim::SceneError& e) {
      std::fprintf(stderr, "%s: %s\n", c.label.c_str(), e.what());
      return 2;
    }
  }
  return 0;
}
