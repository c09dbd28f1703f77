// Pins attached to tf2 frames (a gripper, say): each attached node keeps a
// fixed offset in its frame, and its pin target follows the frame every tick.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <tf2_ros/buffer.h>

#include "cloth_sim/simulation.hpp"

namespace cloth_sim_ros {

/// Latest transform fixed_frame <- frame from `buffer`, refused when older
/// than `timeout` s (static frames never are); on failure `error` says why,
/// starting with the quoted frame. Shared by tf pins and tf colliders.
bool lookupFresh(const tf2_ros::Buffer& buffer, const std::string& fixed_frame,
                 const std::string& frame, double timeout, Eigen::Isometry3d* transform,
                 std::string* error);

class FramePins {
 public:
  /// `fixed_frame` is the simulation's frame; a frame whose latest transform
  /// is older than `timeout` seconds counts as lost (static frames never do).
  FramePins(const tf2_ros::Buffer& buffer, std::string fixed_frame, double timeout);

  /// Latest transform fixed_frame <- frame. On failure `error` says why,
  /// naming the field: "frame_id: 'x' ...".
  bool lookup(const std::string& frame, Eigen::Isometry3d* transform, std::string* error) const;

  /// Attaches a (pinned) node: target = transform(frame) * offset. `target`
  /// is where the node's pin is now.
  void attach(int node, const std::string& frame, const cloth_sim::Vec3& offset,
              const cloth_sim::Vec3& target);
  void detach(int node) { attachments_.erase(node); }
  void clear() { attachments_.clear(); }
  bool attached(int node) const { return attachments_.count(node) != 0; }
  size_t size() const { return attachments_.size(); }

  /// True if some node is attached to `frame`.
  bool hasFrame(const std::string& frame) const;

  /// Moves every attached pin toward its frame's latest pose: the target drifts
  /// from where it was to the new pose over the coming tick of `tick_s`
  /// seconds, so the node arrives there at the tick's end. Pins whose frame
  /// is lost hold their last target. Returns the lost frames with the lookup
  /// error of each.
  std::map<std::string, std::string> update(cloth_sim::Simulation* sim, double tick_s);

 private:
  struct Attachment {
    std::string frame;
    cloth_sim::Vec3 offset;  ///< in frame
    cloth_sim::Vec3 target;  ///< last target sent to the simulation, fixed frame
  };
  const tf2_ros::Buffer& buffer_;
  std::string fixed_frame_;
  double timeout_;
  std::map<int, Attachment> attachments_;
};

}  // namespace cloth_sim_ros
