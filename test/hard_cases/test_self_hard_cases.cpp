// The self-collision hard cases of config/scenes/hard/self/ (issue 14), for
// every implicit stepper. Each scene states its bounds in `# pass.KEY:`
// header lines, as the contact hard cases do:
//   pass.duration   simulated seconds
//   pass.transient  seconds after which the strain bound applies
//   pass.max_strain bound on |d|/L - 1 over springs with a free end
//   pass.min_self_distance_below  the layers must come this close (m) at
//                   some step, so the case really exercises self-collision
// Every step must succeed (recovery may split it), stay finite, keep every
// node at least thickness - 1e-6 m from every collider, and end with no two
// triangles that share no node intersecting (exact test, every step).
// DISABLED_CostTable prints the cost with self-collision on and off (the
// table in docs/stability.md): --gtest_also_run_disabled_tests.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <fstream>
#include <map>
#include <sstream>

#include "cloth_sim/collision_geometry.hpp"
#include "cloth_sim/simulation.hpp"
#include "../common/cloth_checks.hpp"

namespace cloth_sim {
namespace {

const std::string kDir = std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/self/";
constexpr double kMaxPenetration = 1e-6;  // m, as the contact hard cases

struct SelfRun {
  std::string file;
  Method method;
};
void PrintTo(const SelfRun& r, std::ostream* os) { *os << r.file << " " << toString(r.method); }

struct Outcome {
  long steps = 0, rejected = 0;
  double cpu_s = 0.0, self_s = 0.0;  ///< whole run, and the filter's part
  double worst_strain = 0.0, min_self = 0.0;
  int max_intersections = 0;
  bool completed = false;  ///< every step ok (the unchecked run stops at a failed one)
};

/// Runs one case; with `check`, asserts every bound (gtest fatal failures
/// end the run early, so callers test HasFatalFailure()).
void runCase(const SelfRun& run, bool self_collision, bool check, Outcome* out) {
  const auto bounds = test::passBounds(kDir + run.file);
  Scene scene = loadScene(kDir + run.file);
  scene.solver.method = run.method;
  scene.self_collision.enabled = self_collision;
  Simulation sim(scene);
  const double duration = std::stod(bounds.at("duration"));
  const double transient = std::stod(bounds.at("transient"));
  const double max_strain = std::stod(bounds.at("max_strain"));
  const long steps = std::lround(duration / scene.solver.dt);
  if (check) ASSERT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0) << "the start must be clean";
  for (long n = 0; n < steps; ++n) {
    const std::clock_t c0 = std::clock();
    const StepStats st = sim.step();
    out->cpu_s += static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
    out->self_s += st.self_collision_s;
    out->rejected += st.rejected;
    ++out->steps;
    if (!check) {
      if (!st.ok) return;
      continue;
    }
    ASSERT_TRUE(st.ok) << "step " << n << " t = " << sim.time() << ": " << st.failure;
    ASSERT_TRUE(sim.positions().allFinite() && sim.velocities().allFinite()) << "step " << n;
    ASSERT_LE(st.max_penetration, kMaxPenetration) << "step " << n;
    const int crossing = test::selfIntersections(sim.model(), sim.positions());
    out->max_intersections = std::max(out->max_intersections, crossing);
    ASSERT_EQ(crossing, 0) << "step " << n << " t = " << sim.time();
    if (sim.time() > transient + 1e-9) {
      double strain = 0.0;
      for (const Spring& s : sim.model().springs) {
        if (sim.isPinned(s.i) && sim.isPinned(s.j)) continue;
        strain = std::max(strain, (sim.position(s.j) - sim.position(s.i)).norm() / s.rest_length - 1.0);
      }
      out->worst_strain = std::max(out->worst_strain, strain);
      ASSERT_LE(strain, max_strain) << "t = " << sim.time();
    }
  }
  out->completed = true;
  out->min_self = sim.minSelfDistance();
  if (!check) return;
  EXPECT_NEAR(sim.time(), duration, 1e-9);
  EXPECT_LT(sim.minSelfDistance(), std::stod(bounds.at("min_self_distance_below")))
      << "the layers never met: the case does not exercise self-collision";
  EXPECT_GT(sim.minSelfDistance(), 0.0);
  for (size_t k = 0; k < sim.colliders().size(); ++k) {
    for (int i = 0; i < sim.numNodes(); ++i) {
      ASSERT_GE(sim.colliders()[k].closest(sim.position(i), sim.colliderState(static_cast<int>(k)).pose).distance,
                scene.contact.thickness - kMaxPenetration);
    }
  }
}

class SelfHardCase : public testing::TestWithParam<SelfRun> {};

TEST_P(SelfHardCase, NeverIntersects) {
  const SelfRun& run = GetParam();
  Outcome o;
  runCase(run, true, true, &o);
  if (HasFatalFailure()) return;
  std::printf("[ self     ] %s %s: %ld steps, %ld rejected, strain %.3g after the transient, "
              "min self distance %.3g m, %.2f s CPU (%.2f s in the filter)\n",
              run.file.c_str(), toString(run.method), o.steps, o.rejected, o.worst_strain,
              o.min_self, o.cpu_s, o.self_s);
}

const std::vector<std::string> kFiles = {"s1_heap.yaml", "s2_rod.yaml", "s3_fling.yaml",
                                         "s4_twist.yaml"};

std::vector<SelfRun> runs() {
  std::vector<SelfRun> out;
  for (const std::string& f : kFiles) {
    for (Method m : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) out.push_back({f, m});
  }
  return out;
}

std::string name(const testing::TestParamInfo<SelfRun>& info) {
  return test::caseName(info.param.file, toString(info.param.method));
}

INSTANTIATE_TEST_SUITE_P(Scenes, SelfHardCase, testing::ValuesIn(runs()), name);

// The cost table: each case and stepper with self-collision on (checked as
// above) and off (same scene; it may intersect, so it is only timed).
TEST(SelfHardCaseCost, DISABLED_CostTable) {
  std::printf("| case | stepper | CPU on (s) | in filter (s) | rejected on | CPU off (s) | rejected off | on/off | min self distance (m) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  for (const SelfRun& run : runs()) {
    Outcome on, off;
    runCase(run, true, true, &on);
    runCase(run, false, false, &off);
    std::printf("| %s | %s | %.2f | %.2f | %ld | %.2f%s | %ld | %.2f | %.2g |\n", run.file.c_str(),
                toString(run.method), on.cpu_s, on.self_s, on.rejected, off.cpu_s,
                off.completed ? "" : " (a step failed)",
                off.rejected, on.cpu_s / off.cpu_s, on.min_self);
    std::fflush(stdout);
  }
}

}  // namespace
}  // namespace cloth_sim
