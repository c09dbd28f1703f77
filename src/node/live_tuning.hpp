// Live tuning through dynamic_reconfigure (server at ~tuning): spring
// stiffness and damping, gravity, air drag and the solver. A request is turned
// into scene overrides (the CLI's --set) of the node's scene text and parsed by
// the scene file's parser and validator, then handed to Simulation::retune. A
// refused request names the field in the config's `result` and in the log, and
// leaves the simulation untouched. The published config is always what the
// simulation uses.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <boost/thread/recursive_mutex.hpp>
#include <dynamic_reconfigure/server.h>
#include <ros/ros.h>

#include "cloth_sim/ClothSimConfig.h"
#include "cloth_sim/simulation.hpp"

namespace cloth_sim_ros {

/// The reconfigurable values of `tuning` (an absent spring group shows 0, 0).
cloth_sim::ClothSimConfig tuningConfig(const cloth_sim::Tuning& tuning);

/// The config as scene overrides, e.g. "springs.stretch.stiffness=3000",
/// "gravity=[0, 0, -9.81]", "solver.method=\"bdf2\"". Doubles round-trip.
std::vector<std::string> tuningOverrides(const cloth_sim::ClothSimConfig& config);

/// Parses `scene_yaml` with the config's overrides (cloth_sim::parseScene:
/// the validator of scene files) and returns its tunable part in *tuning.
/// Errors name the scene field.
cloth_sim::Status tuningFromConfig(const std::string& scene_yaml,
                                   const cloth_sim::ClothSimConfig& config,
                                   cloth_sim::Tuning* tuning);

/// True if every reconfigurable value of a and b agrees.
bool sameTunables(const cloth_sim::Tuning& a, const cloth_sim::Tuning& b);

class LiveTuning {
 public:
  /// Serves on `nh` (the node uses ~tuning). Publishes the simulation's
  /// current settings at once, whatever the parameter server held before.
  /// `on_applied` runs after every accepted change. A dt that would ask more
  /// than cloth_sim::kMaxTickNodeSteps of one tick of `tick_s` is refused.
  LiveTuning(const ros::NodeHandle& nh, cloth_sim::Simulation* sim, std::string scene_yaml,
             double tick_s, std::function<void()> on_applied);

  /// Republishes the config if the simulation's settings changed by another
  /// way (~set_stiffness, ~reset, scene events). Cheap: call every tick.
  void sync();

 private:
  void onRequest(cloth_sim::ClothSimConfig& config, uint32_t level);
  void show(const cloth_sim::Tuning& tuning);

  cloth_sim::Simulation* sim_;
  std::string scene_yaml_;
  std::function<void()> on_applied_;
  double tick_s_;
  boost::recursive_mutex mutex_;
  dynamic_reconfigure::Server<cloth_sim::ClothSimConfig> server_;
  cloth_sim::Tuning shown_;   ///< what the published config says
  std::string result_;        ///< the last request's outcome
};

}  // namespace cloth_sim_ros
