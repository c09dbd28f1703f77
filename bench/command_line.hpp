// Command-line parsing shared by the benchmark tools: a bad argument throws
// UsageError naming the flag, which main() prints with the usage text.
#pragma once

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <string>

namespace cloth_sim::bench {

struct UsageError {
  std::string message;
};

/// A finite double, the whole of `text`.
inline double parseNumber(const std::string& flag, const std::string& text) {
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(value))
    throw UsageError{flag + ": expected a finite number, got '" + text + "'"};
  return value;
}

/// An integer >= min_value, the whole of `text`.
inline long parseCount(const std::string& flag, const std::string& text, long min_value) {
  char* end = nullptr;
  errno = 0;
  const long value = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE)
    throw UsageError{flag + ": expected an integer, got '" + text + "'"};
  if (value < min_value)
    throw UsageError{flag + ": must be >= " + std::to_string(min_value) + ", got " + text};
  return value;
}

/// Whole steps of dt to time t; throws UsageError naming `what` unless t is on a step.
inline long stepsTo(double t, double dt, const std::string& what) {
  const long n = std::lround(t / dt);
  if (std::abs(n * dt - t) > 1e-9 * std::max(1.0, t)) {
    throw UsageError{what + " at " + std::to_string(t) + " s is not on a step of " +
                     std::to_string(dt) + " s"};
  }
  return n;
}

}  // namespace cloth_sim::bench
