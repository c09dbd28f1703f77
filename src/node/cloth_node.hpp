// The ROS face of one Simulation: a timer that steps it and publishes the
// cloth, services that map onto its runtime requests, diagnostics. No physics
// here. Single-threaded spinning makes every service act between steps.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PointStamped.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include "cloth_messages.hpp"
#include "cloth_sim/ClothState.h"
#include "cloth_sim/Grasp.h"
#include "cloth_sim/PinNodes.h"
#include "cloth_sim/ReleaseGrasp.h"
#include "cloth_sim/ReleaseNodes.h"
#include "cloth_sim/SetStiffness.h"
#include "cloth_sim/simulation.hpp"
#include "drag_handles.hpp"
#include "frame_colliders.hpp"
#include "frame_pins.hpp"
#include "grasp.hpp"
#include "live_tuning.hpp"
#include "node_params.hpp"

namespace cloth_sim_ros {

class ClothNode {
 public:
  /// Builds the simulation, waits for the tf_pins frames (params.tf_wait),
  /// advertises, and starts the timer. `scene_yaml` is the scene's text (live
  /// tuning re-parses it with overrides). Throws cloth_sim::SceneError for a
  /// bad scene and ParamError for bad tf_pins.
  ClothNode(ros::NodeHandle nh, ros::NodeHandle private_nh, const NodeParams& params,
            const cloth_sim::Scene& scene, const std::string& scene_yaml);

  /// Solver steps per tick and their size: n = ceil(tick / solver.dt), h = tick / n.
  static int stepsPerTick(double tick_s, double dt);

 private:
  /// Counters for one diagnostics period.
  struct Window {
    ros::SteadyTime start;
    int ticks = 0;
    int overruns = 0;
    int failures = 0;
    int rejected = 0;
    int error_rejected = 0;           ///< error control's redone steps
    double h_min = 0.0, h_max = 0.0;  ///< step sizes taken, s
    double busy_s = 0.0;      ///< wall time of the ticks' work
    double busy_max_s = 0.0;
    double step_s = 0.0;      ///< wall time inside Simulation::step
    double publish_s = 0.0;   ///< wall time of publish() (marker, strain, state)
    double publish_max_s = 0.0;
    long cg_iterations = 0;
    int cg_max = 0;           ///< per tick
    double residual_max = 0.0;
    double sim_time_s = 0.0;  ///< simulated time advanced
    std::string failure;      ///< latest failure or recovery note
    int refused = 0;          ///< service requests refused (logged at most 5 per second)
    int tf_lost = 0;          ///< ticks in which a tf pin frame had no recent transform
    std::string tf_error;     ///< the latest of those
  };

  const cloth_sim::Model& model() const;
  void onTick(const ros::SteadyTimerEvent& event);
  /// Publishes the current state, or the last finite one if it is not finite.
  void publish(const ros::Time& stamp, TickStats tick);
  /// Publishes ~colliders if a collider moved since the last time (or `force`).
  void publishColliders(const ros::Time& stamp, bool force);
  /// Tf-attached colliders follow their frames; lost frames are reported once.
  void updateFrameColliders();

  bool onPinNodes(cloth_sim::PinNodes::Request& req, cloth_sim::PinNodes::Response& res);
  bool onReleaseNodes(cloth_sim::ReleaseNodes::Request& req,
                      cloth_sim::ReleaseNodes::Response& res);
  bool onSetStiffness(cloth_sim::SetStiffness::Request& req,
                      cloth_sim::SetStiffness::Response& res);
  bool onReset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  // grasp.cpp's services
  bool onGrasp(cloth_sim::Grasp::Request& req, cloth_sim::Grasp::Response& res);
  bool onReleaseGrasp(cloth_sim::ReleaseGrasp::Request& req,
                      cloth_sim::ReleaseGrasp::Response& res);
  /// Grasps on lost frames let go (their nodes fall), with a warning.
  void releaseLostGrasps(const std::map<std::string, std::string>& lost);
  /// RViz's Publish Point on the cloth: a drag handle at the nearest node.
  void onClickedPoint(const geometry_msgs::PointStamped::ConstPtr& msg);
  /// A node pinned or released by a request: tf attachment, grasp and drag end.
  void forgetNode(int node);
  /// n steps of h per tick from the simulation's dt (again after a dt change).
  void divideTick();

  /// Pins nodes, fixed or attached to `frame` (see PinNodes.srv). Validates
  /// everything first; changes nothing unless it succeeds.
  cloth_sim::Status pinNodes(const std::vector<long>& indices,
                             const std::vector<cloth_sim::Vec3>& positions,
                             const std::string& frame);
  /// Applies the tf_pins parameter; errors name the tf_pins entry.
  cloth_sim::Status applyTfPinParams();
  /// Re-reads the one parameter the node reads while running, ~diagnostic_period
  /// (cached: the master pushes changes). A bad value is refused with a warning
  /// naming it and shown in diagnostics; the last good period stays.
  void rereadParams();
  /// Publishes diagnostics every diag_period_ (the node's schedule, not the updater's).
  void updateDiagnostics(const ros::SteadyTime& now);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  NodeParams params_;
  ros::NodeHandle private_nh_;
  cloth_sim::Simulation sim_;
  double tick_s_;
  int steps_per_tick_ = 1;
  double step_h_ = 0.0;
  double divided_dt_ = 0.0;  ///< the solver dt steps_per_tick_ was computed from

  tf2_ros::Buffer tf_buffer_;
  tf2_ros::TransformListener tf_listener_;
  FramePins frame_pins_;
  FrameColliders frame_colliders_;
  Grasps grasps_;
  std::unique_ptr<DragHandles> drag_;
  std::unique_ptr<LiveTuning> tuning_;
  ros::Subscriber clicked_sub_;

  ros::Publisher cloth_pub_, underside_pub_, strain_pub_, state_pub_, colliders_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> cloth_frame_pub_;  ///< ~cloth_frame; null: none
  ros::Time cloth_frame_stamp_;  ///< last one sent: tf2 refuses a stamp twice (a paused /clock)
  std::vector<ros::ServiceServer> services_;
  ros::SteadyTimer timer_;
  diagnostic_updater::Updater updater_;

  visualization_msgs::Marker cloth_marker_;   ///< reused: points rewritten in place
  visualization_msgs::Marker underside_marker_;  ///< the cloth's back (setUndersidePoints)
  visualization_msgs::Marker strain_marker_;
  cloth_sim::ClothState state_msg_;
  visualization_msgs::MarkerArray collider_markers_;
  std::vector<cloth_sim::Pose> published_collider_poses_;  ///< as last on ~colliders
  bool strain_valid_ = false;  ///< strain_marker_ holds a finite state
  bool underside_valid_ = false;  ///< underside_marker_ holds a finite state

  double diag_period_;                     ///< s; ~diagnostic_period as last accepted
  ros::SteadyTime next_diagnostics_;
  std::string diag_period_seen_;           ///< the value last read (XML), good or bad
  std::string refused_param_;              ///< why the value on the server is not used; empty: none

  Window window_;
  long overruns_total_ = 0;
  long failures_total_ = 0;
  TickStats last_tick_;
};

}  // namespace cloth_sim_ros
