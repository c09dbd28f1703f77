// Shared wording of step failures (simulation.cpp, simulation_recovery.cpp).
#pragma once

#include <sstream>
#include <string>

#include "cloth_sim/step_stats.hpp"

namespace cloth_sim {

/// A number as a message shows it (6 significant digits).
inline std::string fmt(double value) {
  std::ostringstream s;
  s << value;
  return s.str();
}

inline std::string newtonFailure(const StepStats& stats) {
  return "newton did not converge (residual " + fmt(stats.newton_residual) +
         " of the initial after " + std::to_string(stats.newton_iterations) + " iterations)";
}

}  // namespace cloth_sim
