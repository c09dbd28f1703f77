// Shared by the rostest gtests: a client of one running cloth_sim_node that
// keeps its latest messages, calls its services and reads its diagnostics.
#pragma once

#include <deque>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>
#include <visualization_msgs/Marker.h>

#include "cloth_sim/ClothState.h"
#include "cloth_sim/model.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim_test {

/// The scene every node test loads (test/node/small_scene.yaml).
cloth_sim::Scene smallScene();

/// Where node `node` appears in a TRIANGLE_LIST built from `model` (first occurrence).
int markerPointOf(const cloth_sim::Model& model, int node);
cloth_sim::Vec3 toVec(const geometry_msgs::Point& p);
geometry_msgs::Point toPoint(const cloth_sim::Vec3& v);

/// Spins until `done()` or `timeout_s` of wall time; returns done().
bool spinUntil(const std::function<bool()>& done, double timeout_s);

class NodeClient {
 public:
  explicit NodeClient(const std::string& node = "/cloth_sim");

  /// Waits for a state satisfying `pred`, received after this call. The
  /// marker published with it (same stamp) goes to *marker if non-null.
  bool waitState(const std::function<bool(const cloth_sim::ClothState&)>& pred,
                 double timeout_s, cloth_sim::ClothState* state,
                 visualization_msgs::Marker* marker = nullptr);
  /// Next state whose simulated time is at least `sim_time`.
  bool waitSimTime(double sim_time, cloth_sim::ClothState* state,
                   visualization_msgs::Marker* marker = nullptr, double timeout_s = 20.0);
  /// Calls ~reset and waits for the state it publishes (sim_time 0).
  bool reset(cloth_sim::ClothState* state = nullptr, visualization_msgs::Marker* marker = nullptr);

  /// The next diagnostics status of this node whose stamp is after this call.
  bool waitDiagnostics(diagnostic_msgs::DiagnosticStatus* status, double timeout_s = 10.0);
  static std::string value(const diagnostic_msgs::DiagnosticStatus& status,
                           const std::string& key);

  const std::string& name() const { return node_; }
  ros::NodeHandle& nh() { return nh_; }

 private:
  void onMarker(const visualization_msgs::Marker::ConstPtr& msg);
  void onState(const cloth_sim::ClothState::ConstPtr& msg);
  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg);

  std::string node_;
  ros::NodeHandle nh_;
  ros::Subscriber marker_sub_, state_sub_, diag_sub_;
  std::deque<visualization_msgs::Marker::ConstPtr> markers_;  ///< recent, for stamp matching
  std::deque<cloth_sim::ClothState::ConstPtr> states_;        ///< not yet consumed
  std::deque<std::pair<ros::Time, diagnostic_msgs::DiagnosticStatus>> diagnostics_;
};

}  // namespace cloth_sim_test
