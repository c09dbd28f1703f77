// Shared by the rostest gtests that move a tf2 frame (a gripper, a hand, a
// pusher): broadcasts one frame while the test spins. Header-only.
#pragma once

#include <functional>
#include <string>
#include <utility>

#include <Eigen/Geometry>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_broadcaster.h>

#include "cloth_sim/types.hpp"

namespace cloth_sim_test {

class FrameBroadcaster {
 public:
  /// Broadcasts `child` in `parent`; run() sends every `period_s` of wall time.
  FrameBroadcaster(std::string child, double period_s, std::string parent = "world")
      : child_(std::move(child)), parent_(std::move(parent)), period_s_(period_s) {}

  /// One transform of `pose`, stamped now.
  void send(const Eigen::Isometry3d& pose) {
    geometry_msgs::TransformStamped tf = tf2::eigenToTransform(pose);
    tf.header.stamp = ros::Time::now();
    tf.header.frame_id = parent_;
    tf.child_frame_id = child_;
    broadcaster_.sendTransform(tf);
  }
  /// One transform, a translation only.
  void send(const cloth_sim::Vec3& position) {
    send(Eigen::Isometry3d(Eigen::Translation3d(position)));
  }

  /// Sends pose(t) (t in s from now) every period for `duration` s, spinning
  /// between; stops early once done() (if given) is true.
  void run(const std::function<Eigen::Isometry3d(double)>& pose, double duration,
           const std::function<bool()>& done = {}) {
    const ros::WallTime start = ros::WallTime::now();
    while (ros::ok()) {
      const double t = (ros::WallTime::now() - start).toSec();
      if (t > duration || (done && done())) break;
      send(pose(t));
      ros::spinOnce();
      ros::WallDuration(period_s_).sleep();
    }
  }
  /// run() for a frame that only translates: position(t), no rotation.
  void runPosition(const std::function<cloth_sim::Vec3(double)>& position, double duration,
                   const std::function<bool()>& done = {}) {
    run([&](double t) { return Eigen::Isometry3d(Eigen::Translation3d(position(t))); }, duration,
        done);
  }

 private:
  std::string child_, parent_;
  double period_s_;
  tf2_ros::TransformBroadcaster broadcaster_;
};

}  // namespace cloth_sim_test
