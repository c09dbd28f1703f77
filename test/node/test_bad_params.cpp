// rostest: cloth_sim_node started with bad parameters exits 1 with a message
// naming the parameter (bad_params.test). Each case runs the real binary.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdio>
#include <string>

#include <ros/ros.h>
#include <xmlrpcpp/XmlRpcValue.h>

namespace {

struct NodeRun {
  int exit_code = -1;  ///< -1: did not exit normally (a crash)
  std::string output;  ///< stdout and stderr
};

/// Runs cloth_sim_node as `name` (its parameters already on the master).
NodeRun runNode(const std::string& name, double timeout_s = 30.0) {
  const std::string command = "timeout --preserve-status -s INT " + std::to_string(timeout_s) + " " +
                              CLOTH_SIM_NODE_PATH + " __name:=" + name + " 2>&1";
  NodeRun run;
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) return run;
  char buf[512];
  while (fgets(buf, sizeof(buf), pipe)) run.output += buf;
  const int status = pclose(pipe);
  if (WIFEXITED(status)) run.exit_code = WEXITSTATUS(status);
  return run;
}

XmlRpc::XmlRpcValue list(std::initializer_list<double> values) {
  XmlRpc::XmlRpcValue v;
  v.setSize(static_cast<int>(values.size()));
  int k = 0;
  for (double x : values) v[k++] = x;
  return v;
}

/// Loads a valid small scene into /<name>/.
void setValidScene(const std::string& name) {
  const std::string ns = "/" + name + "/";
  ros::param::set(ns + "cloth/rows", 6);
  ros::param::set(ns + "cloth/cols", 6);
  ros::param::set(ns + "springs/stretch/stiffness", 500.0);
  XmlRpc::XmlRpcValue pins;  // integers, as rosparam loads them
  pins.setSize(2);
  pins[0] = 0;
  pins[1] = 5;
  ros::param::set(ns + "pins", pins);
}

void expectRefused(const std::string& name, const std::vector<std::string>& must_contain) {
  const NodeRun run = runNode(name);
  EXPECT_EQ(run.exit_code, 1) << name << " output:\n" << run.output;
  EXPECT_NE(run.output.find("FATAL"), std::string::npos) << run.output;
  for (const std::string& part : must_contain) {
    EXPECT_NE(run.output.find(part), std::string::npos)
        << name << ": output lacks '" << part << "':\n" << run.output;
  }
}

TEST(BadParams, ValidParametersKeepTheNodeRunning) {
  setValidScene("good");
  const NodeRun run = runNode("good", 4.0);
  EXPECT_EQ(run.exit_code, 0) << "a valid node should run until interrupted:\n" << run.output;
  EXPECT_EQ(run.output.find("FATAL"), std::string::npos) << run.output;
}

TEST(BadParams, BadSceneValueIsNamed) {
  setValidScene("bad_stiffness");
  ros::param::set("/bad_stiffness/springs/stretch/stiffness", -3.0);
  expectRefused("bad_stiffness", {"springs.stretch.stiffness", "-3"});
}

TEST(BadParams, MissingSceneIsNamed) {
  ros::param::set("/no_scene/rate", 30.0);
  expectRefused("no_scene", {"cloth", "/no_scene"});
}

TEST(BadParams, MisspeltSceneKeyIsNamed) {
  setValidScene("misspelt");
  ros::param::set("/misspelt/solvr/dt", 0.001);
  expectRefused("misspelt", {"solvr"});
}

TEST(BadParams, PinOutOfRangeIsNamed) {
  setValidScene("bad_pin");
  XmlRpc::XmlRpcValue pins;
  pins.setSize(1);
  pins[0] = 36;
  ros::param::set("/bad_pin/pins", pins);
  expectRefused("bad_pin", {"pins", "36"});
}

TEST(BadParams, NonPositiveRateIsNamed) {
  setValidScene("zero_rate");
  ros::param::set("/zero_rate/rate", 0.0);
  expectRefused("zero_rate", {"~rate", "0"});
  setValidScene("text_rate");
  ros::param::set("/text_rate/rate", std::string("fast"));
  expectRefused("text_rate", {"~rate", "fast"});
}

TEST(BadParams, BadColorIsNamed) {
  setValidScene("short_color");
  ros::param::set("/short_color/color", list({1.0, 0.0, 0.0}));
  expectRefused("short_color", {"~color", "[1, 0, 0]"});
  setValidScene("bright_color");
  ros::param::set("/bright_color/color", list({1.0, 2.0, 0.0, 1.0}));
  expectRefused("bright_color", {"~color", "2"});
}

TEST(BadParams, EmptyFrameIdIsNamed) {
  setValidScene("empty_frame");
  ros::param::set("/empty_frame/frame_id", std::string(""));
  expectRefused("empty_frame", {"~frame_id"});
}

TEST(BadParams, BadPublishStrainIsNamed) {
  setValidScene("strain_text");
  ros::param::set("/strain_text/publish_strain", std::string("yes"));
  expectRefused("strain_text", {"~publish_strain", "yes"});
}

TEST(BadParams, BadTfPinsAreNamed) {
  XmlRpc::XmlRpcValue pin;
  pin["frame_id"] = std::string("world");
  pin["indices"].setSize(1);
  pin["indices"][0] = 99;
  XmlRpc::XmlRpcValue pins;
  pins.setSize(1);
  pins[0] = pin;
  setValidScene("tf_pin_range");
  ros::param::set("/tf_pin_range/tf_pins", pins);
  expectRefused("tf_pin_range", {"~tf_pins[0]", "indices[0]", "99"});

  pins[0]["indices"][0] = 3;
  pins[0]["frame_id"] = std::string("nowhere");
  setValidScene("tf_pin_frame");
  ros::param::set("/tf_pin_frame/tf_pins", pins);
  ros::param::set("/tf_pin_frame/tf_wait", 0.5);
  expectRefused("tf_pin_frame", {"~tf_pins[0].frame_id", "nowhere"});
}

XmlRpc::XmlRpcValue sphere(double radius, const std::string& frame) {
  XmlRpc::XmlRpcValue c;
  c["name"] = std::string("ball");
  c["type"] = std::string("sphere");
  c["center"] = list({0.0, 0.0, 0.5});
  c["radius"] = radius;
  if (!frame.empty()) c["frame"] = frame;
  XmlRpc::XmlRpcValue colliders;
  colliders.setSize(1);
  colliders[0] = c;
  return colliders;
}

TEST(BadParams, BadColliderIsNamed) {
  setValidScene("collider_radius");
  ros::param::set("/collider_radius/colliders", sphere(-0.1, ""));
  expectRefused("collider_radius", {"colliders[0].radius", "-0.1"});

  // A collider on a tf frame nobody publishes: refused like a tf pin's frame.
  setValidScene("collider_frame");
  ros::param::set("/collider_frame/colliders", sphere(0.1, "nowhere"));
  ros::param::set("/collider_frame/tf_wait", 0.5);
  expectRefused("collider_frame", {"colliders[0].frame", "nowhere"});
}

TEST(BadParams, ValidColliderKeepsTheNodeRunning) {
  setValidScene("collider_ok");
  ros::param::set("/collider_ok/colliders", sphere(0.1, "world"));
  const NodeRun run = runNode("collider_ok", 4.0);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(run.output.find("FATAL"), std::string::npos) << run.output;
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bad_params");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
