// The node's own parameters (everything in the private namespace that is not
// scene schema), read and validated before anything starts.
#pragma once

#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include <std_msgs/ColorRGBA.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include "cloth_sim/types.hpp"

namespace cloth_sim_ros {

/// A bad node parameter; what() starts with the parameter's name,
/// e.g. "rate: must be a finite number > 0, got 0".
class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Nodes attached to a tf2 frame at start-up (same meaning as ~pin_nodes).
struct TfPinParam {
  std::vector<int> indices;
  std::string frame_id;
  std::vector<cloth_sim::Vec3> positions;  ///< offsets in frame_id; empty: keep where they are
};

struct NodeParams {
  double rate = 60.0;               ///< timer ticks per second, Hz
  std::string frame_id = "world";   ///< frame of every published point
  std::string cloth_frame = "cloth";  ///< tf frame at the cloth's centre of mass; empty: none
  std_msgs::ColorRGBA color;        ///< ~cloth colour (set in readNodeParams)
  bool publish_strain = true;       ///< advertise ~strain
  std::vector<TfPinParam> tf_pins;  ///< pins attached to tf2 frames at start-up
  double tf_timeout = 0.5;          ///< a pin frame older than this is lost, s
  double tf_wait = 10.0;            ///< start-up wait for tf_pins frames, s
  double drag_radius = 0.0;         ///< a drag takes the nodes this close to the picked one, m
  double drag_pick_distance = 0.1;  ///< a clicked point farther from every node makes no handle, m
  double diagnostic_period = 1.0;   ///< s between diagnostics; the one parameter re-read at runtime
};

/// Private-namespace keys that belong to the node, not to the scene.
const std::set<std::string>& nodeParamKeys();

/// The default ~cloth colour, an opaque orange (kept distinct from TF axes).
std_msgs::ColorRGBA defaultClothColor();

/// Reads the node's parameters from the private-namespace tree; absent ones
/// keep their defaults. Throws ParamError naming the parameter.
NodeParams readNodeParams(const XmlRpc::XmlRpcValue& private_ns);

/// Upper bound of ~diagnostic_period, s (ros::Duration's range is far above it).
constexpr double kMaxDiagnosticPeriod = 3600.0;

/// ~diagnostic_period's value: a finite number in (0, kMaxDiagnosticPeriod] s.
/// Used at start-up and when the node re-reads it while running. Throws
/// ParamError naming diagnostic_period.
double readDiagnosticPeriod(const XmlRpc::XmlRpcValue& value);

}  // namespace cloth_sim_ros
