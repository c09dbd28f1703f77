// The scene's `solver` section: read and checked like every other section
// (messages name the field).
#include <string>

#include "scene_yaml.hpp"

namespace cloth_sim {
namespace scene_yaml {
namespace {
constexpr int kMaxHalvings = 30;  // dt / 2^30 is far below any useful step
constexpr int kMaxThreads = 64;
}  // namespace

void readSolver(const YAML::Node& node, Scene::Solver* solver) {
  const Fields f(node, "solver",
                 {"method", "dt", "tolerance", "max_iterations", "preconditioner",
                  "multigrid_reuse", "project_compression", "newton_tolerance",
                  "newton_max_iterations", "max_halvings", "recovery", "error_tolerance",
                  "dt_min", "dt_max", "threads"});
  // No method named: the fast path (automaticSolver), under what is named.
  if (!f.has("method")) {
    *solver = automaticSolver();
  } else {
    const std::string name = readName(f.get("method"), f.path("method"));
    if (!parseMethod(name, &solver->method)) {
      fail(f.path("method"), "unknown method '" + name +
                                 "' (expected implicit_euler, newton, bdf2, symplectic_euler)");
    }
  }
  if (f.has("dt")) solver->dt = readNumber(f.get("dt"), f.path("dt"));
  if (f.has("tolerance")) solver->tolerance = readNumber(f.get("tolerance"), f.path("tolerance"));
  if (f.has("max_iterations")) {
    solver->max_iterations = readInt(f.get("max_iterations"), f.path("max_iterations"));
  }
  if (f.has("preconditioner")) {
    const std::string name = readName(f.get("preconditioner"), f.path("preconditioner"));
    if (name == "none") {
      solver->preconditioner = Preconditioner::None;
    } else if (name == "block_jacobi") {
      solver->preconditioner = Preconditioner::BlockJacobi;
    } else if (name == "cholesky") {
      solver->preconditioner = Preconditioner::Cholesky;
    } else if (name == "multigrid") {
      solver->preconditioner = Preconditioner::Multigrid;
    } else if (name == "auto") {
      solver->preconditioner = Preconditioner::Auto;
    } else {
      fail(f.path("preconditioner"), "unknown preconditioner '" + name +
                                         "' (expected auto, none, block_jacobi, cholesky, multigrid)");
    }
  }
  if (f.has("multigrid_reuse")) {
    solver->multigrid_reuse = readInt(f.get("multigrid_reuse"), f.path("multigrid_reuse"));
  }
  if (f.has("project_compression")) {
    solver->project_compression =
        readBool(f.get("project_compression"), f.path("project_compression"));
  }
  if (f.has("newton_tolerance")) {
    solver->newton_tolerance = readNumber(f.get("newton_tolerance"), f.path("newton_tolerance"));
  }
  if (f.has("newton_max_iterations")) {
    solver->newton_max_iterations =
        readInt(f.get("newton_max_iterations"), f.path("newton_max_iterations"));
  }
  if (f.has("max_halvings")) {
    solver->max_halvings = readInt(f.get("max_halvings"), f.path("max_halvings"));
  }
  if (f.has("recovery")) solver->recovery = readBool(f.get("recovery"), f.path("recovery"));
  if (f.has("threads")) solver->threads = readInt(f.get("threads"), f.path("threads"));
  if (f.has("error_tolerance")) {
    solver->error_tolerance = readNumber(f.get("error_tolerance"), f.path("error_tolerance"));
  }
  // Bounds without error control would be silently ignored: refused instead.
  for (const char* bound : {"dt_min", "dt_max"}) {
    if (!f.has(bound)) continue;
    if (!f.has("error_tolerance")) {
      fail(f.path(bound), "only with solver.error_tolerance (a fixed step is solver.dt)");
    }
    (bound == std::string("dt_min") ? solver->dt_min : solver->dt_max) =
        readNumber(f.get(bound), f.path(bound));
  }
}

void validateSolver(const Scene::Solver& solver) {
  requirePositive(solver.dt, "solver.dt");
  requireFraction(solver.tolerance, "solver.tolerance");
  requireAtLeast(solver.max_iterations, 1, "solver.max_iterations");
  requireAtLeast(solver.multigrid_reuse, 1, "solver.multigrid_reuse");
  requireFraction(solver.newton_tolerance, "solver.newton_tolerance");
  requireAtLeast(solver.newton_max_iterations, 1, "solver.newton_max_iterations");
  requireAtLeast(solver.max_halvings, 0, "solver.max_halvings");
  if (solver.max_halvings > kMaxHalvings) {
    fail("solver.max_halvings", "must be <= " + std::to_string(kMaxHalvings) + ", got " +
                                    std::to_string(solver.max_halvings));
  }
  requireAtLeast(solver.threads, 1, "solver.threads");
  if (solver.threads > kMaxThreads) {
    fail("solver.threads", "must be <= " + std::to_string(kMaxThreads) + ", got " +
                               std::to_string(solver.threads));
  }
  if (!solver.error_tolerance) return;
  requireFraction(*solver.error_tolerance, "solver.error_tolerance");
  if (solver.method == Method::SymplecticEuler) {
    fail("solver.error_tolerance",
         "symplectic_euler has no error estimate: its step is bounded by stability, not "
         "accuracy (use implicit_euler, newton or bdf2)");
  }
  requirePositive(solver.dt_min, "solver.dt_min");
  requirePositive(solver.dt_max, "solver.dt_max");
  if (solver.dt_max < solver.dt_min) {
    fail("solver.dt_max", "must be >= solver.dt_min (" + formatNumber(solver.dt_min) + "), got " +
                              formatNumber(solver.dt_max));
  }
  if (solver.dt < solver.dt_min || solver.dt > solver.dt_max) {
    fail("solver.dt", "the first step must lie in [dt_min, dt_max] = [" +
                          formatNumber(solver.dt_min) + ", " + formatNumber(solver.dt_max) +
                          "], got " + formatNumber(solver.dt));
  }
}

}  // namespace scene_yaml

Scene::Solver automaticSolver() {
  Scene::Solver solver;
  solver.method = Method::Bdf2;
  solver.newton_max_iterations = 1;
  solver.dt = 1.0 / 160.0;
  solver.tolerance = 1e-2;
  solver.preconditioner = Preconditioner::Auto;
  return solver;
}

}  // namespace cloth_sim
