// ClothNode's grasp services (~grasp, ~release_grasp) and the let-go of
// grasps whose frame is lost. The selection and bookkeeping are in grasp.cpp;
// the pins are FramePins attachments made by ClothNode::pinNodes.
#include <cmath>
#include <cstdio>

#include "cloth_node.hpp"

namespace cloth_sim_ros {
namespace {

using cloth_sim::Status;
using cloth_sim::Vec3;

std::string number(double x) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%g", x);
  return buf;
}

std::string point(const Vec3& p) {
  return "[" + number(p.x()) + ", " + number(p.y()) + ", " + number(p.z()) + "]";
}

}  // namespace

bool ClothNode::onGrasp(cloth_sim::Grasp::Request& req, cloth_sim::Grasp::Response& res) {
  const std::string frame = req.frame_id.empty() ? params_.frame_id : req.frame_id;
  const Vec3 at(req.point.x, req.point.y, req.point.z);
  Status status;
  std::vector<int> nodes;
  if (!at.allFinite()) {
    status = Status::error("point: must be finite, got " + point(at));
  } else if (!(req.radius >= 0.0) || !std::isfinite(req.radius)) {
    status = Status::error("radius: must be >= 0 and finite (m), got " + number(req.radius));
  } else {
    Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
    std::string error;
    if (frame != params_.frame_id && !frame_pins_.lookup(frame, &transform, &error)) {
      status = Status::error(error);
    } else {
      const Vec3 centre = transform * at;
      nodes = freeNodesWithin(sim_, centre, req.radius);
      if (nodes.empty()) {
        double distance = 0.0;
        const int nearest = nearestFreeNode(sim_, centre, &distance);
        status = Status::error(
            "radius: no free node within " + number(req.radius) + " m of " + point(at) +
            " in '" + frame + "'" +
            (nearest < 0 ? std::string(" (every node is pinned)")
                         : " (the nearest free node, " + std::to_string(nearest) + ", is " +
                               number(distance) + " m away)"));
      } else {
        status = pinNodes(std::vector<long>(nodes.begin(), nodes.end()), {}, frame);
        if (status) {
          grasps_.add(frame, nodes);
          status = Status::success("grasped " + std::to_string(nodes.size()) +
                                   " node(s) on '" + frame + "'");
        }
      }
    }
  }
  res.success = status.ok;
  res.message = status.message;
  if (status) {
    res.indices.assign(nodes.begin(), nodes.end());
    ROS_INFO("grasp: %s", status.message.c_str());
  } else {  // at most 5 lines a second: a flood of bad calls must not flood /rosout
    window_.refused += 1;
    ROS_WARN_THROTTLE(0.2, "grasp refused: %s", status.message.c_str());
  }
  return true;
}

bool ClothNode::onReleaseGrasp(cloth_sim::ReleaseGrasp::Request& req,
                               cloth_sim::ReleaseGrasp::Response& res) {
  const std::string frame = req.frame_id.empty() ? params_.frame_id : req.frame_id;
  Status status;
  if (!grasps_.has(frame)) {
    const std::string frames = grasps_.frameList();
    status = Status::error("frame_id: no grasp on '" + frame + "' (" +
                           (frames.empty() ? std::string("nothing is grasped")
                                           : "grasps: " + frames) +
                           ")");
  } else {
    std::vector<int> nodes;
    for (int node : grasps_.take(frame)) {
      if (sim_.isPinned(node)) nodes.push_back(node);
    }
    if (!nodes.empty()) status = sim_.release(nodes);
    for (int node : nodes) forgetNode(node);
    res.indices.assign(nodes.begin(), nodes.end());
    status = Status::success("released " + std::to_string(nodes.size()) + " node(s) from '" +
                             frame + "'");
  }
  res.success = status.ok;
  res.message = status.message;
  if (!status) {  // at most 5 lines a second, as above
    window_.refused += 1;
    ROS_WARN_THROTTLE(0.2, "release_grasp refused: %s", status.message.c_str());
  }
  return true;
}

void ClothNode::releaseLostGrasps(const std::map<std::string, std::string>& lost) {
  for (const auto& [frame, error] : lost) {
    if (!grasps_.has(frame)) continue;
    std::vector<int> nodes;
    for (int node : grasps_.take(frame)) {
      if (sim_.isPinned(node)) nodes.push_back(node);
    }
    if (!nodes.empty()) sim_.release(nodes);
    for (int node : nodes) forgetNode(node);
    ROS_WARN("grasp on '%s' let go of %zu node(s): %s", frame.c_str(), nodes.size(),
             error.c_str());
  }
}

}  // namespace cloth_sim_ros
