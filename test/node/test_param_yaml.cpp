// The parameter-tree -> YAML converter feeds the one scene validator: a scene
// loaded with <rosparam> must parse to exactly the scene the CLI reads.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "cloth_sim/scene.hpp"
#include "node_params.hpp"
#include "param_yaml.hpp"

using XmlRpc::XmlRpcValue;
using cloth_sim_ros::nodeParamKeys;
using cloth_sim_ros::sceneYaml;
using cloth_sim_ros::toYaml;

namespace {

XmlRpcValue ints(std::initializer_list<int> values) {
  XmlRpcValue v;
  v.setSize(static_cast<int>(values.size()));
  int k = 0;
  for (int x : values) v[k++] = x;
  return v;
}

XmlRpcValue doubles(std::initializer_list<double> values) {
  XmlRpcValue v;
  v.setSize(static_cast<int>(values.size()));
  int k = 0;
  for (double x : values) v[k++] = x;
  return v;
}

/// config/demo.yaml as rosparam would put it on the parameter server.
XmlRpcValue demoTree() {
  XmlRpcValue t;
  t["cloth"]["rows"] = 24;
  t["cloth"]["cols"] = 24;
  t["cloth"]["width"] = 1.0;
  t["cloth"]["length"] = 1.0;
  t["cloth"]["plane"] = std::string("horizontal");
  t["cloth"]["origin"] = ints({0, 0});
  t["cloth"]["origin"].setSize(3);
  t["cloth"]["origin"][2] = 1.5;
  t["cloth"]["mass"] = 0.3;
  t["springs"]["stretch"]["stiffness"] = 5000.0;
  t["springs"]["stretch"]["damping"] = 2.0;
  t["springs"]["shear"]["stiffness"] = 500.0;
  t["springs"]["shear"]["damping"] = 0.5;
  t["springs"]["bend"]["stiffness"] = 5.0;
  t["springs"]["bend"]["damping"] = 0.0;
  t["springs"]["damping_model"] = std::string("along_spring");
  t["gravity"] = ints({0, 0});
  t["gravity"].setSize(3);
  t["gravity"][2] = -9.81;
  t["air_drag"] = 0.0;
  t["pins"] = ints({0, 23});
  t["solver"]["method"] = std::string("implicit_euler");
  t["solver"]["dt"] = 0.008333333333333333;
  t["solver"]["tolerance"] = 1.0e-4;
  t["solver"]["max_iterations"] = 500;
  t["solver"]["preconditioner"] = std::string("block_jacobi");
  t["solver"]["project_compression"] = true;
  // node parameters live alongside and must not reach the scene validator
  t["rate"] = 60;
  t["frame_id"] = std::string("world");
  t["color"] = doubles({1, 0.5, 0, 1});
  t["publish_strain"] = true;
  return t;
}

TEST(ParamYaml, ScalarsKeepTheirExactValues) {
  EXPECT_EQ(toYaml(XmlRpcValue(true)), "true");
  EXPECT_EQ(toYaml(XmlRpcValue(-3)), "-3");
  EXPECT_EQ(toYaml(XmlRpcValue(0.1)), "0.10000000000000001");
  EXPECT_EQ(toYaml(XmlRpcValue(std::numeric_limits<double>::quiet_NaN())), ".nan");
  EXPECT_EQ(toYaml(XmlRpcValue(-std::numeric_limits<double>::infinity())), "-.inf");
  EXPECT_EQ(toYaml(XmlRpcValue(std::string("a \"b\"\n"))), "\"a \\\"b\\\"\\n\"");
  EXPECT_EQ(toYaml(doubles({1, 0.5})), "[1, 0.5]");
  // rosparam's YAML 1.1 leaves 1.0e6 a string; scene files mean a number.
  EXPECT_EQ(toYaml(XmlRpcValue(std::string("1.0e6"))), "1.0e6");
  EXPECT_EQ(toYaml(XmlRpcValue(std::string("-2e-3"))), "-2e-3");
  EXPECT_EQ(toYaml(XmlRpcValue(std::string("e6"))), "\"e6\"");
  EXPECT_EQ(toYaml(XmlRpcValue(std::string("1.0e6x"))), "\"1.0e6x\"");
  EXPECT_EQ(toYaml(XmlRpcValue()), "null");
}

TEST(ParamYaml, DemoTreeParsesToTheDemoFile) {
  const cloth_sim::Scene from_params =
      cloth_sim::parseScene(sceneYaml(demoTree(), nodeParamKeys()));
  const cloth_sim::Scene from_file =
      cloth_sim::loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/demo.yaml");
  EXPECT_EQ(from_params.cloth.rows, from_file.cloth.rows);
  EXPECT_EQ(from_params.cloth.cols, from_file.cloth.cols);
  EXPECT_EQ(from_params.cloth.origin, from_file.cloth.origin);
  EXPECT_EQ(from_params.cloth.mass, from_file.cloth.mass);
  for (int t = 0; t < cloth_sim::kNumSpringTypes; ++t) {
    EXPECT_EQ(from_params.springs[t].enabled, from_file.springs[t].enabled);
    EXPECT_EQ(from_params.springs[t].stiffness, from_file.springs[t].stiffness);
    EXPECT_EQ(from_params.springs[t].damping, from_file.springs[t].damping);
  }
  EXPECT_EQ(from_params.gravity, from_file.gravity);
  EXPECT_EQ(from_params.pins, from_file.pins);
  EXPECT_EQ(from_params.solver.dt, from_file.solver.dt);
  EXPECT_EQ(from_params.solver.tolerance, from_file.solver.tolerance);
  EXPECT_EQ(from_params.solver.max_iterations, from_file.solver.max_iterations);
}

TEST(ParamYaml, SceneErrorsNameTheField) {
  XmlRpcValue t = demoTree();
  t["springs"]["stretch"]["stiffness"] = -3.0;
  try {
    cloth_sim::parseScene(sceneYaml(t, nodeParamKeys()));
    FAIL() << "accepted a negative stiffness";
  } catch (const cloth_sim::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("springs.stretch.stiffness"), std::string::npos)
        << e.what();
  }
  t = demoTree();
  t["solvr"]["dt"] = 0.1;  // a misspelt key is not silently ignored
  EXPECT_THROW(cloth_sim::parseScene(sceneYaml(t, nodeParamKeys())), cloth_sim::SceneError);
  t = demoTree();
  t["solver"]["dt"] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(cloth_sim::parseScene(sceneYaml(t, nodeParamKeys())), cloth_sim::SceneError);
}

TEST(ParamYaml, EmptyNamespaceIsAnEmptyScene) {
  EXPECT_EQ(sceneYaml(XmlRpcValue(), nodeParamKeys()), "{}");
  EXPECT_THROW(cloth_sim::parseScene("{}"), cloth_sim::SceneError);  // rows, cols required
}

TEST(NodeParams, DefaultsAndValidValues) {
  const auto defaults = cloth_sim_ros::readNodeParams(XmlRpcValue());
  EXPECT_EQ(defaults.rate, 60.0);
  EXPECT_EQ(defaults.frame_id, "world");
  EXPECT_EQ(defaults.color.a, 1.0f);
  EXPECT_TRUE(defaults.publish_strain);
  EXPECT_TRUE(defaults.tf_pins.empty());
  EXPECT_EQ(defaults.diagnostic_period, 1.0);
  EXPECT_EQ(defaults.cloth_frame, "cloth");

  XmlRpcValue t = demoTree();
  XmlRpcValue pin;
  pin["indices"] = ints({23});
  pin["frame_id"] = std::string("gripper");
  t["tf_pins"].setSize(1);
  t["tf_pins"][0] = pin;
  const auto p = cloth_sim_ros::readNodeParams(t);
  EXPECT_EQ(p.rate, 60.0);
  EXPECT_EQ(p.color.g, 0.5f);
  ASSERT_EQ(p.tf_pins.size(), 1u);
  EXPECT_EQ(p.tf_pins[0].indices, std::vector<int>{23});
  EXPECT_EQ(p.tf_pins[0].frame_id, "gripper");
  EXPECT_TRUE(p.tf_pins[0].positions.empty());

  XmlRpcValue no_frame;
  no_frame["cloth_frame"] = std::string("");  // no ~cloth_frame transform
  EXPECT_EQ(cloth_sim_ros::readNodeParams(no_frame).cloth_frame, "");
}

void expectParamError(XmlRpcValue tree, const std::string& must_start) {
  try {
    cloth_sim_ros::readNodeParams(tree);
    FAIL() << "accepted; expected " << must_start;
  } catch (const cloth_sim_ros::ParamError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(must_start, 0), 0u) << e.what();
  }
}

TEST(NodeParams, BadValuesNameTheParameter) {
  XmlRpcValue t;
  t["rate"] = 0;
  expectParamError(t, "rate: must be a finite number > 0 (Hz), got 0");
  t["rate"] = -std::numeric_limits<double>::infinity();
  expectParamError(t, "rate:");
  t = XmlRpcValue();
  t["color"] = doubles({1, 0, 0});
  expectParamError(t, "color: must be a list of 4 numbers [r, g, b, a] in [0, 1], got [1, 0, 0]");
  t["color"] = doubles({1, 0, 0, 1.5});
  expectParamError(t, "color:");
  t = XmlRpcValue();
  t["frame_id"] = 3;
  expectParamError(t, "frame_id: must be a string, got 3");
  t = XmlRpcValue();
  t["publish_strain"] = std::string("yes");
  expectParamError(t, "publish_strain: must be true or false, got \"yes\"");
  t = XmlRpcValue();
  t["tf_pins"].setSize(1);
  t["tf_pins"][0]["indices"] = ints({1, 2});
  t["tf_pins"][0]["frame_id"] = std::string("g");
  t["tf_pins"][0]["positions"].setSize(1);
  t["tf_pins"][0]["positions"][0] = doubles({0, 0, 0});
  expectParamError(t, "tf_pins[0].positions: expected one position per index (2), got 1");
  t["tf_pins"][0]["positions"][0] = doubles({0, 0});
  expectParamError(t, "tf_pins[0].positions[0]:");
  t = XmlRpcValue();
  t["tf_pins"].setSize(1);
  t["tf_pins"][0]["indices"] = ints({1});
  expectParamError(t, "tf_pins[0].frame_id: required");
  t["tf_pins"][0]["frame_id"] = std::string("g");
  t["tf_pins"][0]["frame"] = std::string("g");
  expectParamError(t, "tf_pins[0].frame: unknown key");
  t = XmlRpcValue();
  t["cloth_frame"] = std::string("world");
  expectParamError(t, "cloth_frame: must differ from frame_id 'world'");
  t["cloth_frame"] = 1;
  expectParamError(t, "cloth_frame: must be a string, got 1");
  t = XmlRpcValue();
  t["tf_pins"].setSize(1);
  t["tf_pins"][0]["indices"] = ints({1});
  t["tf_pins"][0]["frame_id"] = std::string("cloth");  // would follow the cloth it holds
  expectParamError(t, "tf_pins[0].frame_id: 'cloth' is the node's own ~cloth_frame");
  t = XmlRpcValue();
  t["diagnostic_period"] = 0.25;
  EXPECT_EQ(cloth_sim_ros::readNodeParams(t).diagnostic_period, 0.25);
  t["diagnostic_period"] = 2;  // an integer is a number too
  EXPECT_EQ(cloth_sim_ros::readNodeParams(t).diagnostic_period, 2.0);
  t["diagnostic_period"] = std::string("abc");
  expectParamError(t, "diagnostic_period: must be a finite number > 0 and <= 3600 (s), got \"abc\"");
  t["diagnostic_period"] = 0.0;
  expectParamError(t, "diagnostic_period:");
  t["diagnostic_period"] = std::numeric_limits<double>::quiet_NaN();
  expectParamError(t, "diagnostic_period:");
  t["diagnostic_period"] = 1e12;  // beyond ros::Duration's range: the updater would throw
  expectParamError(t, "diagnostic_period:");
  t["diagnostic_period"] = doubles({1, 2});
  expectParamError(t, "diagnostic_period:");
}

}  // namespace
