// cloth_sim_node: the cloth simulation as a ROS node (see docs/node_api.md).
// Bad parameters stop it here with one message naming the parameter, exit 1.
#include <exception>
#include <memory>

#include <ros/ros.h>

#include "cloth_node.hpp"
#include "cloth_sim/scene.hpp"
#include "node_params.hpp"
#include "param_yaml.hpp"

int main(int argc, char** argv) {
  ros::init(argc, argv, "cloth_sim");
  ros::NodeHandle nh;
  ros::NodeHandle private_nh("~");
  const std::string ns = private_nh.getNamespace();
  std::unique_ptr<cloth_sim_ros::ClothNode> node;
  try {
    XmlRpc::XmlRpcValue tree;
    if (!ros::param::get(ns, tree)) tree = XmlRpc::XmlRpcValue();  // nothing set: all defaults
    const cloth_sim_ros::NodeParams params = cloth_sim_ros::readNodeParams(tree);
    cloth_sim::Scene scene;
    const std::string scene_yaml = cloth_sim_ros::sceneYaml(tree, cloth_sim_ros::nodeParamKeys());
    try {
      scene = cloth_sim::parseScene(scene_yaml);
    } catch (const cloth_sim::SceneError& e) {
      ROS_FATAL("bad scene parameter ~%s (scene parameters are read from %s)", e.what(),
                ns.c_str());
      return 1;
    }
    node = std::make_unique<cloth_sim_ros::ClothNode>(nh, private_nh, params, scene, scene_yaml);
  } catch (const cloth_sim_ros::ParamError& e) {
    ROS_FATAL("bad parameter ~%s", e.what());
    return 1;
  } catch (const cloth_sim::SceneError& e) {
    ROS_FATAL("bad scene parameter ~%s", e.what());
    return 1;
  } catch (const std::exception& e) {
    ROS_FATAL("cloth_sim_node failed to start: %s", e.what());
    return 1;
  }
  ros::spin();  // single-threaded: services run between ticks, never inside a step
  return 0;
}
