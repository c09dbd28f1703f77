// gripper_circle: broadcasts a tf frame (default `gripper`) that moves slowly
// on a vertical circle, so the demo can show a cloth corner pinned to a moving
// frame. The circle starts at `center + radius * y` (the demo cloth's corner
// [1, 0, 1.5] with the defaults) and turns in the y-z plane.
#include <cmath>
#include <string>
#include <vector>

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <tf2_ros/transform_broadcaster.h>

namespace {

bool readPositive(ros::NodeHandle& nh, const std::string& name, double* value) {
  nh.param(name, *value, *value);
  if (!std::isfinite(*value) || *value <= 0.0) {
    ROS_FATAL("bad parameter ~%s: must be a finite number > 0, got %g", name.c_str(), *value);
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "gripper_circle");
  ros::NodeHandle private_nh("~");
  std::string parent = "world", child = "gripper";
  std::vector<double> center = {1.0, -0.15, 1.5};
  double radius = 0.15, period = 12.0, rate = 50.0;
  private_nh.param("parent_frame", parent, parent);
  private_nh.param("child_frame", child, child);
  private_nh.param("center", center, center);
  if (center.size() != 3 || !std::isfinite(center[0]) || !std::isfinite(center[1]) ||
      !std::isfinite(center[2])) {
    ROS_FATAL("bad parameter ~center: must be 3 finite numbers [x, y, z]");
    return 1;
  }
  if (!readPositive(private_nh, "radius", &radius) ||
      !readPositive(private_nh, "period", &period) || !readPositive(private_nh, "rate", &rate)) {
    return 1;
  }
  if (parent.empty() || child.empty() || parent == child) {
    ROS_FATAL("bad parameter ~parent_frame/~child_frame: must be two different frame names");
    return 1;
  }

  tf2_ros::TransformBroadcaster broadcaster;
  geometry_msgs::TransformStamped tf;
  tf.header.frame_id = parent;
  tf.child_frame_id = child;
  tf.transform.rotation.w = 1.0;
  const ros::WallTime start = ros::WallTime::now();
  ros::WallRate loop(rate);
  while (ros::ok()) {
    const double angle = 2.0 * M_PI * (ros::WallTime::now() - start).toSec() / period;
    tf.header.stamp = ros::Time::now();
    tf.transform.translation.x = center[0];
    tf.transform.translation.y = center[1] + radius * std::cos(angle);
    tf.transform.translation.z = center[2] + radius * std::sin(angle);
    broadcaster.sendTransform(tf);
    ros::spinOnce();
    loop.sleep();
  }
  return 0;
}
