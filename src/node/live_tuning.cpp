#include "live_tuning.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cloth_sim/json_text.hpp"
#include "cloth_sim/limits.hpp"
#include "cloth_sim/scene.hpp"

namespace cloth_sim_ros {
namespace {

using cloth_sim::ClothSimConfig;
using cloth_sim::Status;
using cloth_sim::Tuning;

constexpr int kStretch = static_cast<int>(cloth_sim::SpringType::Stretch);
constexpr int kShear = static_cast<int>(cloth_sim::SpringType::Shear);
constexpr int kBend = static_cast<int>(cloth_sim::SpringType::Bend);

/// A double as YAML: exact, and NaN/infinity as YAML spells them (so the
/// validator says "must be finite" rather than "not a number").
std::string yamlNumber(double x) {
  if (std::isnan(x)) return ".nan";
  if (std::isinf(x)) return x > 0 ? ".inf" : "-.inf";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", x);
  return buf;
}

const char* preconditionerName(cloth_sim::Preconditioner p) {
  switch (p) {
    case cloth_sim::Preconditioner::None: return "none";
    case cloth_sim::Preconditioner::BlockJacobi: return "block_jacobi";
    case cloth_sim::Preconditioner::Cholesky: return "cholesky";
    case cloth_sim::Preconditioner::Multigrid: return "multigrid";
    case cloth_sim::Preconditioner::Auto: return "auto";
  }
  return "?";
}

}  // namespace

ClothSimConfig tuningConfig(const Tuning& t) {
  ClothSimConfig c = ClothSimConfig::__getDefault__();
  c.stretch_stiffness = t.springs[kStretch].stiffness;
  c.stretch_damping = t.springs[kStretch].damping;
  c.shear_stiffness = t.springs[kShear].stiffness;
  c.shear_damping = t.springs[kShear].damping;
  c.bend_stiffness = t.springs[kBend].stiffness;
  c.bend_damping = t.springs[kBend].damping;
  c.gravity_x = t.gravity.x();
  c.gravity_y = t.gravity.y();
  c.gravity_z = t.gravity.z();
  c.air_drag = t.air_drag;
  c.method = cloth_sim::toString(t.solver.method);
  c.dt = t.solver.dt;
  c.tolerance = t.solver.tolerance;
  c.preconditioner = preconditionerName(t.solver.preconditioner);
  c.result = "";
  return c;
}

std::vector<std::string> tuningOverrides(const ClothSimConfig& c) {
  const std::pair<const char*, double> numbers[] = {
      {"springs.stretch.stiffness", c.stretch_stiffness},
      {"springs.stretch.damping", c.stretch_damping},
      {"springs.shear.stiffness", c.shear_stiffness},
      {"springs.shear.damping", c.shear_damping},
      {"springs.bend.stiffness", c.bend_stiffness},
      {"springs.bend.damping", c.bend_damping},
      {"air_drag", c.air_drag},
      {"solver.dt", c.dt},
      {"solver.tolerance", c.tolerance},
  };
  std::vector<std::string> out;
  for (const auto& [key, value] : numbers) out.push_back(std::string(key) + "=" + yamlNumber(value));
  out.push_back("gravity=[" + yamlNumber(c.gravity_x) + ", " + yamlNumber(c.gravity_y) + ", " +
                yamlNumber(c.gravity_z) + "]");
  out.push_back("solver.method=" + cloth_sim::jsonString(c.method));
  out.push_back("solver.preconditioner=" + cloth_sim::jsonString(c.preconditioner));
  return out;
}

Status tuningFromConfig(const std::string& scene_yaml, const ClothSimConfig& config,
                        Tuning* tuning) {
  cloth_sim::Scene scene;
  try {
    std::vector<std::string> overrides = tuningOverrides(config);
    // The scene's own method is not written back: naming it would turn a
    // scene without one from the automatic solver to the method's plain
    // fixed-step defaults (cloth_sim::automaticSolver).
    if (config.method == cloth_sim::toString(cloth_sim::parseScene(scene_yaml).solver.method)) {
      overrides.erase(std::remove_if(overrides.begin(), overrides.end(),
                                     [](const std::string& o) {
                                       return o.rfind("solver.method=", 0) == 0;
                                     }),
                      overrides.end());
    }
    scene = cloth_sim::parseScene(scene_yaml, overrides);
  } catch (const cloth_sim::SceneError& e) {
    return Status::error(e.what());
  }
  tuning->springs = scene.springs;
  tuning->gravity = scene.gravity;
  tuning->air_drag = scene.air_drag;
  tuning->solver = scene.solver;
  return Status::success();
}

bool sameTunables(const Tuning& a, const Tuning& b) {
  for (int k = 0; k < cloth_sim::kNumSpringTypes; ++k) {
    if (a.springs[k].enabled != b.springs[k].enabled ||
        a.springs[k].stiffness != b.springs[k].stiffness ||
        a.springs[k].damping != b.springs[k].damping) {
      return false;
    }
  }
  return a.gravity == b.gravity && a.air_drag == b.air_drag &&
         a.solver.method == b.solver.method && a.solver.dt == b.solver.dt &&
         a.solver.tolerance == b.solver.tolerance &&
         a.solver.preconditioner == b.solver.preconditioner;
}

LiveTuning::LiveTuning(const ros::NodeHandle& nh, cloth_sim::Simulation* sim,
                       std::string scene_yaml, double tick_s, std::function<void()> on_applied)
    : sim_(sim),
      scene_yaml_(std::move(scene_yaml)),
      on_applied_(std::move(on_applied)),
      tick_s_(tick_s),
      server_(mutex_, nh) {
  // The scene decides the start: overwrite whatever the parameter server held.
  show(sim_->tuning());
  server_.setCallback(
      [this](ClothSimConfig& config, uint32_t level) { onRequest(config, level); });
}

void LiveTuning::show(const Tuning& tuning) {
  shown_ = tuning;
  ClothSimConfig config = tuningConfig(tuning);
  config.result = result_;
  server_.updateConfig(config);
}

void LiveTuning::sync() {
  const Tuning now = sim_->tuning();
  if (!sameTunables(now, shown_)) show(now);
}

void LiveTuning::onRequest(ClothSimConfig& config, uint32_t /*level*/) {
  const Tuning before = sim_->tuning();
  Tuning wanted;
  Status status = tuningFromConfig(scene_yaml_, config, &wanted);
  // A group the scene does not model has neither stiffness nor damping.
  for (int k = 0; status && k < cloth_sim::kNumSpringTypes; ++k) {
    if (!before.springs[k].enabled && wanted.springs[k].damping != 0.0) {
      const std::string name = cloth_sim::toString(static_cast<cloth_sim::SpringType>(k));
      status = Status::error("springs." + name + ".damping: the scene does not model the " +
                             name + " group, and only a scene decides what is modelled");
    }
  }
  if (status) {  // the node's bound on one tick's work, as at start-up
    status = cloth_sim::checkWork("solver.dt", std::ceil(tick_s_ / wanted.solver.dt - 1e-9),
                                  sim_->numNodes(), cloth_sim::kMaxTickNodeSteps);
  }
  if (status) status = sim_->retune(wanted);
  if (status) {
    result_ = "applied";
    if (!sameTunables(before, sim_->tuning())) {
      ROS_INFO("tuning: applied (%s, dt %g s, %g N/m stretch)",
               cloth_sim::toString(sim_->tuning().solver.method), sim_->dt(),
               sim_->tuning().springs[kStretch].stiffness);
    }
    if (on_applied_) on_applied_();
  } else {
    result_ = "refused: " + status.message;
    ROS_WARN("tuning refused: %s", status.message.c_str());
  }
  // What the simulation uses, whatever was asked.
  shown_ = sim_->tuning();
  config = tuningConfig(shown_);
  config.result = result_;
}

}  // namespace cloth_sim_ros
