// Drag handles: RViz interactive markers (server at ~drag) that pull the
// cloth. A point published on `clicked_point` (RViz's Publish Point tool,
// clicking the cloth) puts a handle on the nearest node. Dragging the handle
// pins that node (and the nodes within ~drag_radius of it) to the handle with
// their offsets; each tick their pin targets move to the handle's latest pose
// over the tick, so the drag enters the simulation as moving pins with the
// handle's velocity (a flung cloth keeps swinging), never as a jump of a free
// node. Letting go releases them: free nodes go free, nodes that were pinned
// before the drag glide back to their pins. The handle's menu: "Hold after
// letting go" (a checkbox: the nodes stay where they were dropped), "Release",
// "Remove handle". No physics here: only Simulation::pin/movePin/release.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <geometry_msgs/PointStamped.h>
#include <interactive_markers/interactive_marker_server.h>
#include <interactive_markers/menu_handler.h>
#include <tf2_ros/buffer.h>
#include <visualization_msgs/InteractiveMarkerFeedback.h>

#include "cloth_sim/simulation.hpp"

namespace cloth_sim_ros {

class DragHandles {
 public:
  struct Options {
    std::string frame_id = "world";  ///< the simulation's frame
    double pick_distance = 0.1;      ///< a click farther from every node makes no handle, m
    double radius = 0.0;             ///< a drag takes the nodes this close to the handle's node, m
    double return_time = 0.5;        ///< a node pinned before the drag glides back in this time, s
  };

  /// Serves interactive markers on `topic_ns` (absolute, e.g. /cloth_sim/drag).
  /// `grabbable(node)` says whether a drag may take a node (tf-attached pins
  /// belong to their frame).
  DragHandles(const std::string& topic_ns, const Options& options, cloth_sim::Simulation* sim,
              const tf2_ros::Buffer& tf, std::function<bool(int)> grabbable);

  /// A handle on the node nearest to `point`. Returns the node, or -1 with
  /// *error saying why (no node within pick_distance, unknown frame).
  int addHandle(const geometry_msgs::PointStamped& point, std::string* error);

  /// Before a tick's steps: the pins of dragged (and held) nodes move from
  /// where they are to their handle's latest pose over the tick of `tick_s`.
  void update(double tick_s);
  /// After a tick's steps: handles nobody drags sit on their nodes; pending
  /// removals happen. One update message at most.
  void publishPoses();

  /// Another request released or re-pinned `node`: no handle controls it any more.
  void forget(int node);
  /// ~reset: every drag and hold ends (the nodes keep what reset gave them).
  void clearDrags();
  bool controls(int node) const;
  size_t numHandles() const { return handles_.size(); }

  static std::string handleName(int node) { return "node_" + std::to_string(node); }

 private:
  struct Grabbed {
    int node = 0;
    cloth_sim::Vec3 offset;        ///< from the handle, fixed frame
    cloth_sim::Vec3 target;        ///< pin target at the end of the current tick
    bool was_pinned = false;       ///< pinned before the drag ...
    cloth_sim::Vec3 previous;      ///< ... at this target
  };
  struct Handle {
    int node = 0;
    cloth_sim::Vec3 position;      ///< the handle's latest pose, fixed frame
    cloth_sim::Vec3 shown;         ///< last pose sent to the clients
    bool dragging = false;         ///< the mouse holds it
    bool hold = false;             ///< menu checkbox: keep the nodes pinned on letting go
    std::vector<Grabbed> grabbed;  ///< while dragging or holding
    bool remove = false;           ///< erase at the next publishPoses
    std::unique_ptr<interactive_markers::MenuHandler> menu;
    interactive_markers::MenuHandler::EntryHandle hold_entry = 0;
  };

  void onFeedback(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback);
  void onHoldToggled(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback);
  void onRelease(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback);
  void onRemove(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback);
  Handle* find(const std::string& name);
  /// Pins the handle's node (and those within radius) to the handle at `from`.
  void grab(Handle& handle, const cloth_sim::Vec3& from);
  /// Ends the handle's drag or hold: free nodes go free, pinned ones glide back.
  void letGo(Handle& handle);
  /// The feedback's pose in the fixed frame; false if its frame is unknown.
  bool toFixed(const visualization_msgs::InteractiveMarkerFeedback& feedback,
               cloth_sim::Vec3* p) const;
  /// Looks up fixed <- frame; false with *error if tf cannot.
  bool transformToFixed(const std::string& frame, const ros::Time& stamp,
                        const cloth_sim::Vec3& in, cloth_sim::Vec3* out,
                        std::string* error) const;

  Options options_;
  cloth_sim::Simulation* sim_;
  const tf2_ros::Buffer& tf_;
  std::function<bool(int)> grabbable_;
  interactive_markers::InteractiveMarkerServer server_;
  std::map<std::string, Handle> handles_;
};

}  // namespace cloth_sim_ros
