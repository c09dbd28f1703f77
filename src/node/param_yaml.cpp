#include "param_yaml.hpp"

#include <cmath>
#include <cstdio>
#include <regex>

#include "cloth_sim/json_text.hpp"

namespace cloth_sim_ros {
namespace {

// A JSON string is a YAML double-quoted scalar (YAML reads \uXXXX escapes too).
std::string quote(const std::string& text) { return cloth_sim::jsonString(text); }

std::string number(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.17g", value);
  return buf;
}

/// rosparam reads YAML 1.1, where `1.0e6` (no sign after e) is a string,
/// while scene files are YAML 1.2, where it is a number: pass such strings
/// through as numbers so a scene file means the same to the node and the CLI.
bool isExponentNumber(const std::string& text) {
  static const std::regex pattern(R"([-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+)");
  return std::regex_match(text, pattern);
}

}  // namespace

std::string toYaml(const XmlRpc::XmlRpcValue& value) {
  // XmlRpcValue's accessors are non-const; copying is cheap for parameter trees.
  XmlRpc::XmlRpcValue v = value;
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return static_cast<bool>(v) ? "true" : "false";
    case XmlRpc::XmlRpcValue::TypeInt:
      return std::to_string(static_cast<int>(v));
    case XmlRpc::XmlRpcValue::TypeDouble:
      return number(static_cast<double>(v));
    case XmlRpc::XmlRpcValue::TypeString: {
      const std::string text = static_cast<std::string>(v);
      return isExponentNumber(text) ? text : quote(text);
    }
    case XmlRpc::XmlRpcValue::TypeArray: {
      std::string out = "[";
      for (int k = 0; k < v.size(); ++k) out += (k ? ", " : "") + toYaml(v[k]);
      return out + "]";
    }
    case XmlRpc::XmlRpcValue::TypeStruct: {
      std::string out = "{";
      bool first = true;
      for (const auto& entry : v) {
        out += (first ? "" : ", ") + quote(entry.first) + ": " + toYaml(entry.second);
        first = false;
      }
      return out + "}";
    }
    case XmlRpc::XmlRpcValue::TypeInvalid:
      return "null";
    default:  // dateTime, base64: no scene field takes these; the validator names the field
      return quote(v.toXml());
  }
}

std::string sceneYaml(const XmlRpc::XmlRpcValue& private_ns,
                      const std::set<std::string>& node_keys) {
  if (private_ns.getType() != XmlRpc::XmlRpcValue::TypeStruct) return "{}";
  XmlRpc::XmlRpcValue tree = private_ns;
  std::string out = "{";
  bool first = true;
  for (const auto& entry : tree) {
    if (node_keys.count(entry.first)) continue;
    out += (first ? "" : ", ") + quote(entry.first) + ": " + toYaml(entry.second);
    first = false;
  }
  return out + "}";
}

}  // namespace cloth_sim_ros
