// Bounds on the work a scene and a run may ask for, so that a typo or an
// untrusted input (rows: 200000, solver.dt: 1e-300, --steps 1e15) is refused
// up front with the limit named instead of running for days or exhausting
// memory. Header only: the CLI and the node check these before any work.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// Node-steps (nodes x steps) one cloth_sim_run may ask for: about 3 hours at
/// the ~1 us per node-step of a 64x64 cloth (README Performance).
constexpr double kMaxRunNodeSteps = 1e10;
/// Node-steps one tick of the ROS node may ask for (rate, solver.dt and the
/// grid together): ~10 s of work in one tick of a real-time node.
constexpr double kMaxTickNodeSteps = 1e7;

namespace detail {
inline std::string limitNumber(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}
}  // namespace detail

/// ok, or an error starting with `what` that names the work and the limit.
inline Status checkWork(const std::string& what, double steps, long long nodes, double limit) {
  const double work = steps * static_cast<double>(nodes);
  if (!(work <= limit)) {  // also NaN
    return Status::error(what + ": " + detail::limitNumber(steps) + " steps of " +
                         std::to_string(nodes) + " nodes = " + detail::limitNumber(work) +
                         " node-steps exceeds the limit of " + detail::limitNumber(limit));
  }
  return Status::success();
}

}  // namespace cloth_sim
