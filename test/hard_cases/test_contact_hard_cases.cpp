// The contact hard cases of config/scenes/hard/contact/, for every implicit
// stepper (the contact issue). Each scene states its bounds in `# pass.KEY:`
// header lines, as the other hard cases do:
//   pass.duration   simulated seconds
//   pass.transient  seconds after which the strain bound applies
//   pass.max_strain bound on |d|/L - 1 over springs with a free end
//   pass.max_stretch_strain  (optional) the same over the stretch springs only
//   pass.inputs     none: energy never increases (static colliders, no pins
//                   moving, no stiffness events); otherwise what does work
// Every step must succeed (recovery may split it), stay finite, and end with
// every node at least thickness - 1e-6 m from every collider.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include "cloth_sim/simulation.hpp"
#include "../common/cloth_checks.hpp"

namespace cloth_sim {
namespace {

const std::string kDir = std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/contact/";
constexpr double kMaxPenetration = 1e-6;  // m
constexpr double kStepEnergyTolerance = 1e-6;  // of the energy scale, as the core's recovery

struct ContactRun {
  std::string file;
  Method method;
};
void PrintTo(const ContactRun& r, std::ostream* os) { *os << r.file << " " << toString(r.method); }

class ContactHardCase : public testing::TestWithParam<ContactRun> {};

TEST_P(ContactHardCase, PassesWithoutPenetration) {
  const ContactRun& run = GetParam();
  const auto bounds = test::passBounds(kDir + run.file);
  Scene scene = loadScene(kDir + run.file);
  scene.solver.method = run.method;
  Simulation sim(scene);
  const double duration = std::stod(bounds.at("duration"));
  const double transient = std::stod(bounds.at("transient"));
  const double max_strain = std::stod(bounds.at("max_strain"));
  const double max_stretch_strain = bounds.count("max_stretch_strain")
                                        ? std::stod(bounds.at("max_stretch_strain"))
                                        : max_strain;
  const bool no_inputs = bounds.at("inputs") == "none";
  double mass = 0.0;
  for (double m : sim.model().mass) mass += m;
  const double size = std::hypot(scene.cloth.width, scene.cloth.length);
  const long steps = std::lround(duration / scene.solver.dt);
  long rejected = 0, passes = 0, linearized = 0;
  double worst_strain = 0.0, previous = sim.energy();
  const auto start = std::chrono::steady_clock::now();
  for (long n = 0; n < steps; ++n) {
    const double scale = sim.kineticEnergy() + sim.elasticEnergy() +
                         mass * scene.gravity.norm() * size + 1e-12;
    const StepStats st = sim.step();
    ASSERT_TRUE(st.ok) << "step " << n << " t = " << sim.time() << ": " << st.failure;
    ASSERT_TRUE(sim.positions().allFinite() && sim.velocities().allFinite());
    ASSERT_LE(st.max_penetration, kMaxPenetration) << "step " << n;
    rejected += st.rejected;
    linearized += st.linearized;
    passes += st.contact_passes;
    if (no_inputs) {
      ASSERT_LE(st.energy - previous, kStepEnergyTolerance * scale + st.energy_round_off)
          << "energy grew at step " << n;
    }
    previous = st.energy;
    if (sim.time() > transient + 1e-9) {
      double strain = 0.0, stretch = 0.0;
      const SpringGroup& stretch_group = sim.group(SpringType::Stretch);
      for (int k = 0; k < static_cast<int>(sim.model().springs.size()); ++k) {
        const Spring& s = sim.model().springs[k];
        if (sim.isPinned(s.i) && sim.isPinned(s.j)) continue;
        const double e = (sim.position(s.j) - sim.position(s.i)).norm() / s.rest_length - 1.0;
        strain = std::max(strain, e);
        if (k >= stretch_group.begin && k < stretch_group.end) stretch = std::max(stretch, e);
      }
      worst_strain = std::max(worst_strain, strain);
      ASSERT_LE(strain, max_strain) << "t = " << sim.time();
      ASSERT_LE(stretch, max_stretch_strain) << "stretch springs, t = " << sim.time();
    }
  }
  EXPECT_NEAR(sim.time(), duration, 1e-9);
  // Every node outside every collider, checked directly at the end.
  for (size_t k = 0; k < sim.colliders().size(); ++k) {
    for (int i = 0; i < sim.numNodes(); ++i) {
      ASSERT_GE(sim.colliders()[k].closest(sim.position(i), sim.colliderState(static_cast<int>(k)).pose).distance,
                scene.contact.thickness - kMaxPenetration);
    }
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("[ contact  ] %s %s: %ld steps, %ld rejected, %ld linearized, %.2f contact passes/step, strain %.3g "
              "after the transient, max penetration %.2g m, %.2f s\n",
              run.file.c_str(), toString(run.method), steps, rejected, linearized,
              static_cast<double>(passes) / steps, worst_strain, sim.maxPenetration(), wall);
}

std::vector<ContactRun> runs() {
  std::vector<ContactRun> out;
  for (const char* f : {"c1_fast_drop.yaml", "c2_pinched.yaml", "c3_edge_drag.yaml",
                        "c4_stiffen_on_table.yaml"}) {
    for (Method m : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) out.push_back({f, m});
  }
  return out;
}

std::string name(const testing::TestParamInfo<ContactRun>& info) {
  return test::caseName(info.param.file, toString(info.param.method));
}

INSTANTIATE_TEST_SUITE_P(Scenes, ContactHardCase, testing::ValuesIn(runs()), name);

}  // namespace
}  // namespace cloth_sim
