#include "frame_colliders.hpp"

#include <set>

#include "frame_pins.hpp"
#include "node_params.hpp"

namespace cloth_sim_ros {

using cloth_sim::Pose;
using cloth_sim::Vec3;

FrameColliders::FrameColliders(const tf2_ros::Buffer& buffer, std::string fixed_frame,
                               double timeout)
    : buffer_(buffer), fixed_frame_(std::move(fixed_frame)), timeout_(timeout) {}

bool FrameColliders::lookup(const std::string& frame, Pose* pose, std::string* error) const {
  Eigen::Isometry3d t;
  if (!lookupFresh(buffer_, fixed_frame_, frame, timeout_, &t, error)) return false;
  pose->rotation = t.rotation();
  pose->translation = t.translation();
  return true;
}

void FrameColliders::start(cloth_sim::Simulation* sim, double wait_s) {
  attached_.clear();
  lost_.clear();
  const std::vector<cloth_sim::Collider>& colliders = sim->colliders();
  for (size_t k = 0; k < colliders.size(); ++k) {
    const std::string& frame = colliders[k].frame();
    if (frame.empty() || frame == fixed_frame_) continue;
    std::string error;
    if (!buffer_.canTransform(fixed_frame_, frame, ros::Time(0), ros::Duration(wait_s),
                              &error)) {
      char wait[64];
      std::snprintf(wait, sizeof(wait), "%g", wait_s);
      throw ParamError("colliders[" + std::to_string(k) + "].frame: no transform from '" + frame +
                       "' to '" + fixed_frame_ + "' within tf_wait " + wait + " s" +
                       (error.empty() ? "" : " (" + error + ")"));
    }
    attached_.push_back(Attached{static_cast<int>(k), frame});
  }
  snap(sim);
}

void FrameColliders::snap(cloth_sim::Simulation* sim) {
  for (const Attached& a : attached_) {
    Pose frame_pose;
    std::string error;
    if (!lookup(a.frame, &frame_pose, &error)) continue;  // update() reports it
    sim->setColliderPose(a.index, frame_pose * sim->colliders()[a.index].scenePose());
  }
}

std::map<std::string, std::string> FrameColliders::update(cloth_sim::Simulation* sim,
                                                          double tick_s) {
  std::map<std::string, Pose> poses;  // one lookup per frame
  std::map<std::string, std::string> now_lost, newly_lost;
  for (const Attached& a : attached_) {
    if (!poses.count(a.frame) && !now_lost.count(a.frame)) {
      Pose pose;
      std::string error;
      if (lookup(a.frame, &pose, &error)) {
        poses[a.frame] = pose;
      } else {
        now_lost[a.frame] = error;
      }
    }
    const Pose& current = sim->colliderState(a.index).pose;
    if (now_lost.count(a.frame)) {
      sim->setColliderPose(a.index, current);  // hold the last pose, at rest
      continue;
    }
    const Pose goal = poses[a.frame] * sim->colliders()[a.index].scenePose();
    const Vec3 travel = goal.translation - current.translation;
    if (travel.norm() <= 1e-12) {
      sim->setColliderPose(a.index, goal);  // at rest on the frame, exactly
    } else {
      sim->setColliderPose(a.index, Pose{goal.rotation, current.translation}, travel / tick_s);
    }
  }
  for (const auto& [frame, why] : now_lost) {
    if (!lost_.count(frame)) newly_lost[frame] = why;
  }
  lost_ = now_lost;
  return newly_lost;
}

}  // namespace cloth_sim_ros
