// Command-line parsing shared by the benchmark tools: a bad argument throws
// UsageError naming the flag, which main() prints with the usage text.
#pragma once

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

}  // namespace cloth_sim::bench
