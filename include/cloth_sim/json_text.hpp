// JSON text for the tools' machine-readable output (cloth_sim_run --stats,
// the stability map's runs): numbers and strings, nothing more.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

namespace cloth_sim {

/// `value` with `significant_digits` digits (17: round-trips a double). JSON
/// has no NaN or infinity: those become null.
inline std::string jsonNumber(double value, int significant_digits = 17) {
  if (!std::isfinite(value)) return "null";
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*g", significant_digits, value);
  return buf;
}

/// `text` quoted, with quotes, backslashes and control characters escaped.
inline std::string jsonString(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

}  // namespace cloth_sim
