#include "drag_handles.hpp"

#include <limits>

#include <ros/ros.h>
#include <tf2/exceptions.h>
#include <tf2_eigen/tf2_eigen.h>

namespace cloth_sim_ros {
namespace {

using cloth_sim::Vec3;
using visualization_msgs::InteractiveMarkerFeedback;
using visualization_msgs::InteractiveMarkerFeedbackConstPtr;

constexpr double kHandleSize = 0.04;  ///< sphere diameter, m
constexpr double kShowTolerance = 1e-4;  ///< handles closer than this to their node are not re-sent, m

geometry_msgs::Pose poseAt(const Vec3& p) {
  geometry_msgs::Pose pose;
  pose.position.x = p.x();
  pose.position.y = p.y();
  pose.position.z = p.z();
  pose.orientation.w = 1.0;
  return pose;
}

visualization_msgs::InteractiveMarker handleMarker(const std::string& frame_id,
                                                   const std::string& name, int node,
                                                   const Vec3& at) {
  visualization_msgs::InteractiveMarker m;
  m.header.frame_id = frame_id;  // stamp 0: always the latest transform
  m.name = name;
  m.description = "node " + std::to_string(node);
  m.pose = poseAt(at);
  m.scale = 2.5 * kHandleSize;

  visualization_msgs::Marker sphere;
  sphere.type = visualization_msgs::Marker::SPHERE;
  sphere.scale.x = sphere.scale.y = sphere.scale.z = kHandleSize;
  sphere.color.r = 0.1f;
  sphere.color.g = 0.8f;
  sphere.color.b = 0.9f;
  sphere.color.a = 0.9f;
  sphere.pose.orientation.w = 1.0;

  // Drag the sphere: left button moves it in the view plane, shift + left in depth.
  visualization_msgs::InteractiveMarkerControl move;
  move.name = "move";
  move.interaction_mode = visualization_msgs::InteractiveMarkerControl::MOVE_3D;
  move.always_visible = true;
  move.orientation.w = 1.0;
  move.markers.push_back(sphere);
  m.controls.push_back(move);
  return m;
}

}  // namespace

DragHandles::DragHandles(const std::string& topic_ns, const Options& options,
                         cloth_sim::Simulation* sim, const tf2_ros::Buffer& tf,
                         std::function<bool(int)> grabbable)
    : options_(options),
      sim_(sim),
      tf_(tf),
      grabbable_(std::move(grabbable)),
      server_(topic_ns, "", false) {}  // no thread of its own: feedback runs between ticks

bool DragHandles::transformToFixed(const std::string& frame, const ros::Time& /*stamp*/,
                                   const Vec3& in, Vec3* out, std::string* error) const {
  if (frame.empty() || frame == options_.frame_id) {
    *out = in;
    return true;
  }
  try {
    const Eigen::Isometry3d t =
        tf2::transformToEigen(tf_.lookupTransform(options_.frame_id, frame, ros::Time(0)));
    *out = t * in;
    return true;
  } catch (const tf2::TransformException& e) {
    *error = "frame '" + frame + "' has no transform to '" + options_.frame_id + "': " + e.what();
    return false;
  }
}

int DragHandles::addHandle(const geometry_msgs::PointStamped& point, std::string* error) {
  Vec3 p;
  if (!transformToFixed(point.header.frame_id, point.header.stamp,
                        Vec3(point.point.x, point.point.y, point.point.z), &p, error)) {
    return -1;
  }
  if (!p.allFinite()) {
    *error = "the point is not finite";
    return -1;
  }
  int best = -1;
  double best_d = std::numeric_limits<double>::infinity();
  for (int i = 0; i < sim_->numNodes(); ++i) {
    const double d = (sim_->position(i) - p).norm();
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  if (best < 0 || best_d > options_.pick_distance) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "no node within %g m of [%g, %g, %g] (nearest: %g m)",
                  options_.pick_distance, p.x(), p.y(), p.z(), best_d);
    *error = buf;
    return -1;
  }
  const std::string name = handleName(best);
  if (Handle* existing = find(name)) {
    existing->remove = false;
    return best;
  }
  Handle& h = handles_[name];
  h.node = best;
  h.position = h.shown = sim_->position(best);
  server_.insert(handleMarker(options_.frame_id, name, best, h.position),
                 [this](const InteractiveMarkerFeedbackConstPtr& f) { onFeedback(f); });
  h.menu = std::make_unique<interactive_markers::MenuHandler>();
  h.hold_entry = h.menu->insert("Hold after letting go",
                                [this](const InteractiveMarkerFeedbackConstPtr& f) { onHoldToggled(f); });
  h.menu->setCheckState(h.hold_entry, interactive_markers::MenuHandler::UNCHECKED);
  h.menu->insert("Release", [this](const InteractiveMarkerFeedbackConstPtr& f) { onRelease(f); });
  h.menu->insert("Remove handle",
                 [this](const InteractiveMarkerFeedbackConstPtr& f) { onRemove(f); });
  h.menu->apply(server_, name);
  server_.applyChanges();
  return best;
}

DragHandles::Handle* DragHandles::find(const std::string& name) {
  auto it = handles_.find(name);
  return it == handles_.end() ? nullptr : &it->second;
}

bool DragHandles::controls(int node) const {
  for (const auto& entry : handles_) {
    for (const Grabbed& g : entry.second.grabbed) {
      if (g.node == node) return true;
    }
  }
  return false;
}

bool DragHandles::toFixed(const InteractiveMarkerFeedback& feedback, Vec3* p) const {
  std::string error;
  const geometry_msgs::Point& q = feedback.pose.position;
  if (!transformToFixed(feedback.header.frame_id, feedback.header.stamp, Vec3(q.x, q.y, q.z), p,
                        &error)) {
    ROS_WARN_THROTTLE(2.0, "drag handle %s: %s", feedback.marker_name.c_str(), error.c_str());
    return false;
  }
  if (!p->allFinite()) {
    ROS_WARN_THROTTLE(2.0, "drag handle %s: pose not finite, ignored", feedback.marker_name.c_str());
    return false;
  }
  return true;
}

void DragHandles::onFeedback(const InteractiveMarkerFeedbackConstPtr& feedback) {
  Handle* h = find(feedback->marker_name);
  if (!h || h->remove) return;
  Vec3 p;
  switch (feedback->event_type) {
    case InteractiveMarkerFeedback::MOUSE_DOWN:
    case InteractiveMarkerFeedback::POSE_UPDATE:
      if (!toFixed(*feedback, &p)) return;
      // The grab starts where the handle was: a pose update without a mouse
      // down (a scripted client) still moves the nodes, it does not teleport them.
      if (!h->dragging) {
        h->dragging = true;
        if (h->grabbed.empty()) grab(*h, h->position);
        else {  // held: take the held nodes again, offsets from here
          for (Grabbed& g : h->grabbed) g.offset = g.target - h->position;
        }
      }
      h->position = p;
      break;
    case InteractiveMarkerFeedback::MOUSE_UP:
      if (toFixed(*feedback, &p)) h->position = p;
      h->dragging = false;
      if (!h->hold) letGo(*h);
      break;
    default:
      break;
  }
}

void DragHandles::grab(Handle& h, const Vec3& from) {
  const Vec3 centre = sim_->position(h.node);
  std::vector<int> nodes;
  std::vector<Vec3> targets;
  h.grabbed.clear();
  for (int i = 0; i < sim_->numNodes(); ++i) {
    if (i != h.node && (options_.radius <= 0.0 ||
                        (sim_->position(i) - centre).norm() > options_.radius)) {
      continue;
    }
    if (!grabbable_(i) || controls(i)) continue;
    Grabbed g;
    g.node = i;
    g.was_pinned = sim_->isPinned(i);
    g.previous = g.was_pinned ? sim_->pins().at(i).position : Vec3::Zero();
    g.target = g.was_pinned ? g.previous : sim_->position(i);
    g.offset = g.target - from;
    nodes.push_back(i);
    targets.push_back(g.target);
    h.grabbed.push_back(g);
  }
  if (nodes.empty()) {
    ROS_WARN("drag handle %s: no node to take (tf-attached pins follow their frame)",
             handleName(h.node).c_str());
    return;
  }
  const cloth_sim::Status status = sim_->pin(nodes, targets);
  if (!status) {
    ROS_WARN("drag handle %s: %s", handleName(h.node).c_str(), status.message.c_str());
    h.grabbed.clear();
    return;
  }
  ROS_INFO("drag: %s takes %zu node(s)", handleName(h.node).c_str(), nodes.size());
}

void DragHandles::letGo(Handle& h) {
  std::vector<int> to_free;
  for (const Grabbed& g : h.grabbed) {
    if (!sim_->isPinned(g.node)) continue;
    if (g.was_pinned) {
      // Back to the pin it had, gliding (a jump of a pin would jerk the cloth).
      const Vec3 from = sim_->pins().at(g.node).position;
      sim_->movePin(g.node, from, (g.previous - from) / options_.return_time,
                    options_.return_time);
    } else {
      to_free.push_back(g.node);
    }
  }
  if (!to_free.empty()) sim_->release(to_free);
  h.grabbed.clear();
  h.dragging = false;
}

void DragHandles::update(double tick_s) {
  for (auto& entry : handles_) {
    Handle& h = entry.second;
    for (auto it = h.grabbed.begin(); it != h.grabbed.end();) {
      if (!sim_->isPinned(it->node)) {  // released by a scene event
        it = h.grabbed.erase(it);
        continue;
      }
      const Vec3 goal = h.position + it->offset;
      const Vec3 velocity = (goal - it->target) / tick_s;
      if (sim_->movePin(it->node, it->target, velocity, tick_s)) it->target = goal;
      ++it;
    }
  }
}

void DragHandles::publishPoses() {
  bool changed = false;
  for (auto it = handles_.begin(); it != handles_.end();) {
    Handle& h = it->second;
    if (h.remove) {
      letGo(h);
      server_.erase(it->first);
      it = handles_.erase(it);
      changed = true;
      continue;
    }
    if (!h.dragging) {
      // A free handle sits on its node; a holding one where it was dropped.
      if (h.grabbed.empty()) h.position = sim_->position(h.node);
      if ((h.position - h.shown).norm() > kShowTolerance) {
        server_.setPose(it->first, poseAt(h.position));
        h.shown = h.position;
        changed = true;
      }
    }
    ++it;
  }
  if (changed) server_.applyChanges();
}

void DragHandles::forget(int node) {
  for (auto& entry : handles_) {
    auto& grabbed = entry.second.grabbed;
    for (auto it = grabbed.begin(); it != grabbed.end();) {
      it = it->node == node ? grabbed.erase(it) : it + 1;
    }
  }
}

void DragHandles::clearDrags() {
  for (auto& entry : handles_) {
    entry.second.grabbed.clear();
    entry.second.dragging = false;
  }
}

void DragHandles::onHoldToggled(const InteractiveMarkerFeedbackConstPtr& feedback) {
  Handle* h = find(feedback->marker_name);
  if (!h) return;
  h->hold = !h->hold;
  h->menu->setCheckState(h->hold_entry, h->hold ? interactive_markers::MenuHandler::CHECKED
                                                : interactive_markers::MenuHandler::UNCHECKED);
  h->menu->reApply(server_);
  if (!h->hold && !h->dragging) letGo(*h);  // unchecked while holding: let go now
  server_.applyChanges();
}

void DragHandles::onRelease(const InteractiveMarkerFeedbackConstPtr& feedback) {
  Handle* h = find(feedback->marker_name);
  if (h) letGo(*h);
}

void DragHandles::onRemove(const InteractiveMarkerFeedbackConstPtr& feedback) {
  // Erased at the next publishPoses: not from inside the server's own callback.
  Handle* h = find(feedback->marker_name);
  if (h) h->remove = true;
}

}  // namespace cloth_sim_ros
