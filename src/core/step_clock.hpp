// The steppers' wall-clock measure (StepStats' assembly and solve times).
#pragma once

#include <chrono>

namespace cloth_sim {

using Clock = std::chrono::steady_clock;

inline double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace cloth_sim
