// libFuzzer harness over the node's parameter path: the private namespace as
// the parameter server sends it (an XML-RPC value, here parsed from the
// input's text), through readNodeParams (the node's own parameters) and
// sceneYaml + parseScene (the scene parameters), as cloth_sim_node's main()
// does. Each input must end in ParamError or SceneError naming the parameter,
// or a valid configuration; anything else (a crash, a sanitizer report,
// another exception, an empty message) is a finding.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "cloth_sim/scene.hpp"
#include "node_params.hpp"
#include "param_yaml.hpp"

namespace {
[[noreturn]] void finding(const std::string& what) {
  std::fprintf(stderr, "param_fuzzer finding: %s\n", what.c_str());
  std::abort();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size > 64 * 1024) return 0;
  const std::string xml(reinterpret_cast<const char*>(data), size);
  int offset = 0;
  XmlRpc::XmlRpcValue tree(xml, &offset);
  if (!tree.valid()) return 0;  // the parameter server sends only valid values
  try {
    cloth_sim_ros::readNodeParams(tree);
  } catch (const cloth_sim_ros::ParamError& e) {
    if (std::string(e.what()).empty()) finding("ParamError without a message");
  }
  try {
    cloth_sim::parseScene(cloth_sim_ros::sceneYaml(tree, cloth_sim_ros::nodeParamKeys()));
  } catch (const cloth_sim::SceneError& e) {
    if (std::string(e.what()).empty()) finding("SceneError without a message");
  }
  return 0;
}
