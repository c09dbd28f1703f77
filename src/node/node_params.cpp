#include "node_params.hpp"

#include <cmath>

#include "param_yaml.hpp"

namespace cloth_sim_ros {
namespace {

using XmlRpc::XmlRpcValue;

[[noreturn]] void fail(const std::string& name, const std::string& what,
                       const XmlRpcValue& got) {
  throw ParamError(name + ": " + what + ", got " + toYaml(got));
}

bool isNumber(const XmlRpcValue& v) {
  return v.getType() == XmlRpcValue::TypeInt || v.getType() == XmlRpcValue::TypeDouble;
}

double asNumber(const XmlRpcValue& v) {
  XmlRpcValue copy = v;  // XmlRpcValue's conversions are non-const
  return copy.getType() == XmlRpcValue::TypeInt ? static_cast<int>(copy)
                                                : static_cast<double>(copy);
}

double readNumber(const XmlRpcValue& v, const std::string& name, const std::string& rule,
                  bool (*ok)(double)) {
  if (!isNumber(v) || !std::isfinite(asNumber(v)) || !ok(asNumber(v))) fail(name, rule, v);
  return asNumber(v);
}

std::string readString(const XmlRpcValue& v, const std::string& name) {
  if (v.getType() != XmlRpcValue::TypeString) fail(name, "must be a string", v);
  XmlRpcValue copy = v;
  return static_cast<std::string>(copy);
}

cloth_sim::Vec3 readPoint(const XmlRpcValue& v, const std::string& name) {
  if (v.getType() != XmlRpcValue::TypeArray || v.size() != 3) {
    fail(name, "must be a list of 3 finite numbers [x, y, z]", v);
  }
  cloth_sim::Vec3 p;
  for (int k = 0; k < 3; ++k) {
    if (!isNumber(v[k]) || !std::isfinite(asNumber(v[k]))) {
      fail(name, "must be a list of 3 finite numbers [x, y, z]", v);
    }
    p[k] = asNumber(v[k]);
  }
  return p;
}

std::string element(const std::string& name, int k) {
  return name + "[" + std::to_string(k) + "]";
}

TfPinParam readTfPin(const XmlRpcValue& v, const std::string& name) {
  if (v.getType() != XmlRpcValue::TypeStruct) {
    fail(name, "must be a map {indices: [..], frame_id: .., positions: [[x, y, z], ..]}", v);
  }
  XmlRpcValue entry = v;
  for (const auto& field : entry) {
    if (field.first != "indices" && field.first != "frame_id" && field.first != "positions") {
      throw ParamError(name + "." + field.first +
                       ": unknown key (expected indices, frame_id, positions)");
    }
  }
  TfPinParam pin;
  if (!entry.hasMember("indices")) throw ParamError(name + ".indices: required");
  const XmlRpcValue& indices = entry["indices"];
  if (indices.getType() != XmlRpcValue::TypeArray || indices.size() == 0) {
    fail(name + ".indices", "must be a non-empty list of node indices", indices);
  }
  for (int k = 0; k < indices.size(); ++k) {
    if (indices[k].getType() != XmlRpcValue::TypeInt) {
      fail(element(name + ".indices", k), "must be a node index (integer)", indices[k]);
    }
    XmlRpcValue index = indices[k];
    pin.indices.push_back(static_cast<int>(index));
  }
  if (!entry.hasMember("frame_id")) throw ParamError(name + ".frame_id: required");
  pin.frame_id = readString(entry["frame_id"], name + ".frame_id");
  if (pin.frame_id.empty()) fail(name + ".frame_id", "must name a tf2 frame", entry["frame_id"]);
  if (entry.hasMember("positions")) {
    const XmlRpcValue& positions = entry["positions"];
    if (positions.getType() != XmlRpcValue::TypeArray) {
      fail(name + ".positions", "must be a list of [x, y, z] offsets", positions);
    }
    for (int k = 0; k < positions.size(); ++k) {
      pin.positions.push_back(readPoint(positions[k], element(name + ".positions", k)));
    }
    if (!pin.positions.empty() && pin.positions.size() != pin.indices.size()) {
      throw ParamError(name + ".positions: expected one position per index (" +
                       std::to_string(pin.indices.size()) + "), got " +
                       std::to_string(pin.positions.size()));
    }
  }
  return pin;
}

}  // namespace

const std::set<std::string>& nodeParamKeys() {
  // tuning and drag: the namespaces of the dynamic_reconfigure server and the
  // interactive-marker server (their state, never scene schema).
  static const std::set<std::string> keys = {
      "rate",    "frame_id",  "cloth_frame", "color",      "publish_strain", "tf_pins",
      "tf_timeout", "tf_wait",        "diagnostic_period", "drag_radius",
      "drag_pick_distance", "tuning", "drag"};
  return keys;
}

std_msgs::ColorRGBA defaultClothColor() {
  std_msgs::ColorRGBA c;
  c.r = 0.95f;
  c.g = 0.45f;
  c.b = 0.1f;
  c.a = 1.0f;
  return c;
}

NodeParams readNodeParams(const XmlRpcValue& private_ns) {
  NodeParams p;
  p.color = defaultClothColor();
  if (private_ns.getType() != XmlRpcValue::TypeStruct) return p;
  XmlRpcValue ns = private_ns;

  if (ns.hasMember("rate")) {
    p.rate = readNumber(ns["rate"], "rate", "must be a finite number > 0 (Hz)",
                        [](double x) { return x > 0.0; });
  }
  if (ns.hasMember("frame_id")) {
    p.frame_id = readString(ns["frame_id"], "frame_id");
    if (p.frame_id.empty()) fail("frame_id", "must name a frame", ns["frame_id"]);
  }
  if (ns.hasMember("cloth_frame")) {
    p.cloth_frame = readString(ns["cloth_frame"], "cloth_frame");  // empty: not published
  }
  if (!p.cloth_frame.empty() && p.cloth_frame == p.frame_id) {
    throw ParamError("cloth_frame: must differ from frame_id '" + p.frame_id +
                     "' (its parent), or be empty for no frame");
  }
  if (ns.hasMember("color")) {
    const XmlRpcValue& c = ns["color"];
    const std::string rule = "must be a list of 4 numbers [r, g, b, a] in [0, 1]";
    if (c.getType() != XmlRpcValue::TypeArray || c.size() != 4) fail("color", rule, c);
    float rgba[4];
    for (int k = 0; k < 4; ++k) {
      rgba[k] = static_cast<float>(
          readNumber(c[k], "color", rule, [](double x) { return x >= 0.0 && x <= 1.0; }));
    }
    p.color.r = rgba[0];
    p.color.g = rgba[1];
    p.color.b = rgba[2];
    p.color.a = rgba[3];
  }
  if (ns.hasMember("publish_strain")) {
    if (ns["publish_strain"].getType() != XmlRpcValue::TypeBoolean) {
      fail("publish_strain", "must be true or false", ns["publish_strain"]);
    }
    p.publish_strain = static_cast<bool>(ns["publish_strain"]);
  }
  if (ns.hasMember("tf_pins")) {
    const XmlRpcValue& pins = ns["tf_pins"];
    if (pins.getType() != XmlRpcValue::TypeArray) {
      fail("tf_pins", "must be a list of {indices: [..], frame_id: ..}", pins);
    }
    for (int k = 0; k < pins.size(); ++k) {
      p.tf_pins.push_back(readTfPin(pins[k], element("tf_pins", k)));
      // The cloth would drag itself. pinNodes refuses it too, but only after
      // the start-up wait for the pin's frame, which this one never gets.
      if (p.tf_pins.back().frame_id == p.cloth_frame) {
        throw ParamError(element("tf_pins", k) + ".frame_id: '" + p.cloth_frame +
                         "' is the node's own ~cloth_frame");
      }
    }
  }
  if (ns.hasMember("tf_timeout")) {
    p.tf_timeout = readNumber(ns["tf_timeout"], "tf_timeout", "must be a finite number > 0 (s)",
                              [](double x) { return x > 0.0; });
  }
  if (ns.hasMember("tf_wait")) {
    p.tf_wait = readNumber(ns["tf_wait"], "tf_wait", "must be a finite number >= 0 (s)",
                           [](double x) { return x >= 0.0; });
  }
  if (ns.hasMember("drag_radius")) {
    p.drag_radius = readNumber(ns["drag_radius"], "drag_radius",
                               "must be a finite number >= 0 (m)",
                               [](double x) { return x >= 0.0; });
  }
  if (ns.hasMember("drag_pick_distance")) {
    p.drag_pick_distance =
        readNumber(ns["drag_pick_distance"], "drag_pick_distance",
                   "must be a finite number > 0 (m)", [](double x) { return x > 0.0; });
  }
  if (ns.hasMember("diagnostic_period")) {
    p.diagnostic_period = readDiagnosticPeriod(ns["diagnostic_period"]);
  }
  return p;
}

double readDiagnosticPeriod(const XmlRpcValue& value) {
  return readNumber(value, "diagnostic_period", "must be a finite number > 0 and <= 3600 (s)",
                    [](double x) { return x > 0.0 && x <= kMaxDiagnosticPeriod; });
}

}  // namespace cloth_sim_ros
