#include "frame_pins.hpp"

#include <cstdio>

#include <tf2/exceptions.h>
#include <tf2_eigen/tf2_eigen.h>

namespace cloth_sim_ros {

FramePins::FramePins(const tf2_ros::Buffer& buffer, std::string fixed_frame, double timeout)
    : buffer_(buffer), fixed_frame_(std::move(fixed_frame)), timeout_(timeout) {}

bool lookupFresh(const tf2_ros::Buffer& buffer, const std::string& fixed_frame,
                 const std::string& frame, double timeout, Eigen::Isometry3d* transform,
                 std::string* error) {
  geometry_msgs::TransformStamped msg;
  try {
    msg = buffer.lookupTransform(fixed_frame, frame, ros::Time(0));
  } catch (const tf2::TransformException& e) {
    *error = "'" + frame + "' has no transform to '" + fixed_frame + "': " + e.what();
    return false;
  }
  // Stamp zero: a static transform, valid forever.
  if (!msg.header.stamp.isZero()) {
    const double age = (ros::Time::now() - msg.header.stamp).toSec();
    if (age > timeout) {
      char buf[160];
      std::snprintf(buf, sizeof(buf), "' last transform is %.2f s old (tf_timeout %.2f s)", age,
                    timeout);
      *error = "'" + frame + buf;
      return false;
    }
  }
  *transform = tf2::transformToEigen(msg);
  return true;
}

bool FramePins::lookup(const std::string& frame, Eigen::Isometry3d* transform,
                       std::string* error) const {
  if (lookupFresh(buffer_, fixed_frame_, frame, timeout_, transform, error)) return true;
  *error = "frame_id: " + *error;
  return false;
}

void FramePins::attach(int node, const std::string& frame, const cloth_sim::Vec3& offset,
                       const cloth_sim::Vec3& target) {
  attachments_[node] = Attachment{frame, offset, target};
}

bool FramePins::hasFrame(const std::string& frame) const {
  for (const auto& entry : attachments_) {
    if (entry.second.frame == frame) return true;
  }
  return false;
}

std::map<std::string, std::string> FramePins::update(cloth_sim::Simulation* sim,
                                                     double tick_s) {
  std::map<std::string, Eigen::Isometry3d> poses;  // one lookup per frame
  std::map<std::string, std::string> lost;
  for (auto it = attachments_.begin(); it != attachments_.end();) {
    const int node = it->first;
    Attachment& a = it->second;
    if (!sim->isPinned(node)) {  // released by a scene event: nothing to follow
      it = attachments_.erase(it);
      continue;
    }
    ++it;
    if (!poses.count(a.frame) && !lost.count(a.frame)) {
      Eigen::Isometry3d transform;
      std::string error;
      if (lookup(a.frame, &transform, &error)) {
        poses[a.frame] = transform;
      } else {
        lost[a.frame] = error;
      }
    }
    if (lost.count(a.frame)) {
      sim->movePin(node, a.target);  // hold where it was last seen
      continue;
    }
    const cloth_sim::Vec3 goal = poses[a.frame] * a.offset;
    const cloth_sim::Vec3 velocity = (goal - a.target) / tick_s;
    if (sim->movePin(node, a.target, velocity, tick_s)) a.target = goal;
  }
  return lost;
}

}  // namespace cloth_sim_ros
