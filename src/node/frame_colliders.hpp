// Colliders attached to tf2 frames (a robot's link or gripper): a collider
// whose scene entry has `frame: F` has its scene pose relative to F, and each
// tick follows it: world pose = T(F) * scenePose.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <tf2_ros/buffer.h>

#include "cloth_sim/simulation.hpp"

namespace cloth_sim_ros {

class FrameColliders {
 public:
  /// `fixed_frame` is the simulation's frame (a collider with that frame, or
  /// none, stays where the scene put it); a frame whose latest transform is
  /// older than `timeout` s is lost (static frames never are).
  FrameColliders(const tf2_ros::Buffer& buffer, std::string fixed_frame, double timeout);

  /// Finds the tf-attached colliders of `sim`, waits up to `wait_s` for each
  /// frame and places the colliders on them. Throws ParamError naming the
  /// field ("colliders[k].frame: ...") for a frame tf does not know.
  void start(cloth_sim::Simulation* sim, double wait_s);

  /// Puts every attached collider on its frame's latest pose at once, at rest
  /// (after start-up and ~reset, which put them back at their scene poses).
  void snap(cloth_sim::Simulation* sim);

  /// Before a tick of `tick_s`: every attached collider moves from where it is
  /// to T(frame) * scenePose over the tick (setColliderPose with that
  /// velocity, so the steps sweep the motion and friction sees it; a rotation
  /// is applied at the tick's start). A lost frame's colliders stop where they
  /// are. Returns the frames lost since the last call (frame -> why), each
  /// reported once until it comes back.
  std::map<std::string, std::string> update(cloth_sim::Simulation* sim, double tick_s);

  size_t size() const { return attached_.size(); }
  /// Frames lost now, with why.
  const std::map<std::string, std::string>& lost() const { return lost_; }

 private:
  struct Attached {
    int index;          ///< collider index in the simulation
    std::string frame;
  };
  bool lookup(const std::string& frame, cloth_sim::Pose* pose, std::string* error) const;

  const tf2_ros::Buffer& buffer_;
  std::string fixed_frame_;
  double timeout_;
  std::vector<Attached> attached_;
  std::map<std::string, std::string> lost_;
};

}  // namespace cloth_sim_ros
