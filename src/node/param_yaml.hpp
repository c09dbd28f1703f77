// ROS parameter tree -> YAML text, so the node's scene goes through the one
// scene validator (cloth_sim::parseScene) the CLI uses.
#pragma once

#include <set>
#include <string>

#include <xmlrpcpp/XmlRpcValue.h>

namespace cloth_sim_ros {

/// One value as YAML flow text: strings quoted, doubles exact (%.17g, .nan,
/// .inf), lists as [..], structs as {..}. Also used to quote bad values.
std::string toYaml(const XmlRpc::XmlRpcValue& value);

/// The scene part of a node's private namespace as YAML text: every entry of
/// `private_ns` except `node_keys` (so a misspelt scene key still reaches the
/// validator and is rejected there). An invalid or empty tree gives "{}".
std::string sceneYaml(const XmlRpc::XmlRpcValue& private_ns,
                      const std::set<std::string>& node_keys);

}  // namespace cloth_sim_ros
