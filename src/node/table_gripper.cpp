// table_gripper: the table demo's robot hand (demo.launch scene:=table). It
// broadcasts a tf frame (default `gripper`) that waits above one node of the
// cloth while the cloth drops onto the table, comes down on that node, grasps
// it through the node's ~grasp service, drags it across the table, lifts it,
// lets go (~release_grasp), and after a pause resets the cloth (~reset) and
// starts over (~loop). Where the node is comes from ~state. With ~park: true
// it only holds the frame at ~park_position (the scene's finger stays there).
#include <cmath>
#include <string>
#include <vector>

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/transform_broadcaster.h>

#include "cloth_sim/ClothState.h"
#include "cloth_sim/Grasp.h"
#include "cloth_sim/ReleaseGrasp.h"

namespace {

using Vec = std::vector<double>;

bool readVec3(ros::NodeHandle& nh, const std::string& name, Vec* v) {
  nh.param(name, *v, *v);
  if (v->size() != 3 || !std::isfinite((*v)[0]) || !std::isfinite((*v)[1]) ||
      !std::isfinite((*v)[2])) {
    ROS_FATAL("bad parameter ~%s: must be 3 finite numbers [x, y, z]", name.c_str());
    return false;
  }
  return true;
}

bool readPositive(ros::NodeHandle& nh, const std::string& name, double* value) {
  nh.param(name, *value, *value);
  if (!std::isfinite(*value) || *value <= 0.0) {
    ROS_FATAL("bad parameter ~%s: must be a finite number > 0, got %g", name.c_str(), *value);
    return false;
  }
  return true;
}

Vec lerp(const Vec& a, const Vec& b, double s) {
  s = std::min(1.0, std::max(0.0, s));
  s = s * s * (3.0 - 2.0 * s);  // smooth start and stop
  return {a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2])};
}

Vec add(const Vec& a, const Vec& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }

class Hand {
 public:
  Hand(std::string parent, std::string child) {
    tf_.header.frame_id = std::move(parent);
    tf_.child_frame_id = std::move(child);
    tf_.transform.rotation.w = 1.0;
  }
  void send(const Vec& p) {
    position_ = p;
    tf_.header.stamp = ros::Time::now();
    tf_.transform.translation.x = p[0];
    tf_.transform.translation.y = p[1];
    tf_.transform.translation.z = p[2];
    broadcaster_.sendTransform(tf_);
  }
  /// Moves from where it is to `to` in `duration` s, broadcasting at `rate`.
  bool move(const Vec& to, double duration, double rate) {
    const Vec from = position_;
    const ros::WallTime start = ros::WallTime::now();
    ros::WallRate loop(rate);
    while (ros::ok()) {
      const double t = (ros::WallTime::now() - start).toSec();
      send(lerp(from, to, t / duration));
      ros::spinOnce();
      if (t >= duration) return true;
      loop.sleep();
    }
    return false;
  }
  bool hold(double duration, double rate) { return move(position_, duration, rate); }
  const Vec& position() const { return position_; }
  const std::string& child() const { return tf_.child_frame_id; }

 private:
  tf2_ros::TransformBroadcaster broadcaster_;
  geometry_msgs::TransformStamped tf_;
  Vec position_ = {0, 0, 0};
};

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "table_gripper");
  ros::NodeHandle nh, private_nh("~");
  std::string parent = "world", child = "gripper", cloth = "/cloth_sim";
  int node = 0;
  Vec drag = {0.55, -0.45, 0.0};
  double hover = 0.25, lift = 0.3, settle = 2.5, descend = 1.0, drag_time = 3.0,
         lift_time = 1.5, hold = 1.0, pause = 3.0, radius = 0.03, rate = 50.0;
  bool loop = true, park = false;
  Vec park_position = {0.0, 0.55, 1.3};
  private_nh.param("parent_frame", parent, parent);
  private_nh.param("child_frame", child, child);
  private_nh.param("cloth_node", cloth, cloth);
  private_nh.param("node", node, node);
  private_nh.param("loop", loop, loop);
  private_nh.param("park", park, park);
  if (!readVec3(private_nh, "park_position", &park_position)) return 1;
  if (!readVec3(private_nh, "drag", &drag) || !readPositive(private_nh, "hover", &hover) ||
      !readPositive(private_nh, "lift", &lift) || !readPositive(private_nh, "settle", &settle) ||
      !readPositive(private_nh, "descend", &descend) ||
      !readPositive(private_nh, "drag_time", &drag_time) ||
      !readPositive(private_nh, "lift_time", &lift_time) ||
      !readPositive(private_nh, "hold", &hold) || !readPositive(private_nh, "pause", &pause) ||
      !readPositive(private_nh, "radius", &radius) || !readPositive(private_nh, "rate", &rate)) {
    return 1;
  }
  if (node < 0) {
    ROS_FATAL("bad parameter ~node: must be a node index >= 0, got %d", node);
    return 1;
  }

  if (park) {
    Hand parked(parent, child);
    ros::WallRate loop_rate(rate);
    while (ros::ok()) {
      parked.send(park_position);
      ros::spinOnce();
      loop_rate.sleep();
    }
    return 0;
  }

  cloth_sim::ClothState::ConstPtr state;
  ros::Subscriber sub = nh.subscribe<cloth_sim::ClothState>(
      cloth + "/state", 1,
      boost::function<void(const cloth_sim::ClothState::ConstPtr&)>(
          [&](const cloth_sim::ClothState::ConstPtr& m) { state = m; }));
  Hand hand(parent, child);
  auto nodePosition = [&]() -> Vec {
    const geometry_msgs::Point& p = state->positions[node];
    return {p.x, p.y, p.z};
  };
  // Broadcast from the start (the cloth node waits for the frame), above the origin.
  ros::WallRate wait(rate);
  while (ros::ok() && !state) {
    hand.send({0.0, 0.0, 2.0});
    ros::spinOnce();
    wait.sleep();
  }
  if (!ros::ok()) return 0;
  if (node >= static_cast<int>(state->positions.size())) {
    ROS_FATAL("bad parameter ~node: the cloth has %zu nodes, got %d", state->positions.size(),
              node);
    return 1;
  }

  ros::ServiceClient grasp = nh.serviceClient<cloth_sim::Grasp>(cloth + "/grasp");
  ros::ServiceClient release = nh.serviceClient<cloth_sim::ReleaseGrasp>(cloth + "/release_grasp");
  ros::ServiceClient reset = nh.serviceClient<std_srvs::Trigger>(cloth + "/reset");
  while (ros::ok()) {
    // Wait above where the node is while the cloth drops and settles.
    hand.move(add(nodePosition(), {0.0, 0.0, hover}), 0.5, rate);
    const ros::WallTime settle_start = ros::WallTime::now();
    while (ros::ok() && (ros::WallTime::now() - settle_start).toSec() < settle) {
      hand.send(add(nodePosition(), {0.0, 0.0, hover}));  // follows the node from above
      ros::spinOnce();
      wait.sleep();
    }
    // Down onto the node, grasp what lies within `radius`.
    if (!hand.move(add(nodePosition(), {0.0, 0.0, hover * 0.3}), descend * 0.6, rate)) break;
    if (!hand.move(nodePosition(), descend * 0.4, rate)) break;
    hand.hold(0.3, rate);  // the cloth node has seen the frame here
    cloth_sim::Grasp g;
    g.request.frame_id = hand.child();
    g.request.radius = radius;
    if (!grasp.call(g) || !g.response.success) {
      ROS_WARN("table_gripper: grasp failed: %s", g.response.message.c_str());
    } else {
      ROS_INFO("table_gripper: grasped %zu node(s)", g.response.indices.size());
    }
    // Across the table, up, and let go.
    if (!hand.move(add(hand.position(), drag), drag_time, rate)) break;
    if (!hand.move(add(hand.position(), {0.0, 0.0, lift}), lift_time, rate)) break;
    hand.hold(hold, rate);
    cloth_sim::ReleaseGrasp r;
    r.request.frame_id = hand.child();
    if (!release.call(r) || !r.response.success) {
      ROS_WARN("table_gripper: release failed: %s", r.response.message.c_str());
    }
    hand.hold(pause, rate);
    if (!loop) {
      while (ros::ok()) hand.hold(1.0, rate);
      break;
    }
    std_srvs::Trigger t;
    if (!reset.call(t)) ROS_WARN("table_gripper: ~reset failed");
    ros::spinOnce();
    hand.hold(0.1, rate);  // the state after the reset arrives
  }
  return 0;
}
