#include "node_test_helpers.hpp"

#include <std_srvs/Trigger.h>

namespace cloth_sim_test {

cloth_sim::Scene smallScene() {
  return cloth_sim::loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/test/node/small_scene.yaml");
}

int markerPointOf(const cloth_sim::Model& model, int node) {
  for (size_t t = 0; t < model.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      if (model.triangles[t][c] == node) return static_cast<int>(3 * t + c);
    }
  }
  return -1;
}

cloth_sim::Vec3 toVec(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }

geometry_msgs::Point toPoint(const cloth_sim::Vec3& v) {
  geometry_msgs::Point p;
  p.x = v.x();
  p.y = v.y();
  p.z = v.z();
  return p;
}

bool spinUntil(const std::function<bool()>& done, double timeout_s) {
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::ok() && !done() && ros::WallTime::now() < deadline) {
    ros::spinOnce();
    ros::WallDuration(0.001).sleep();
  }
  return done();
}

NodeClient::NodeClient(const std::string& node) : node_(node) {
  marker_sub_ = nh_.subscribe(node_ + "/cloth", 50, &NodeClient::onMarker, this);
  state_sub_ = nh_.subscribe(node_ + "/state", 50, &NodeClient::onState, this);
  diag_sub_ = nh_.subscribe("/diagnostics", 20, &NodeClient::onDiagnostics, this);
}

void NodeClient::onMarker(const visualization_msgs::Marker::ConstPtr& msg) {
  markers_.push_back(msg);
  if (markers_.size() > 100) markers_.pop_front();
}

void NodeClient::onState(const cloth_sim::ClothState::ConstPtr& msg) {
  states_.push_back(msg);
  if (states_.size() > 1000) states_.pop_front();
}

void NodeClient::onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
  // The updater names its status "<node name without leading slash>: simulation".
  const std::string prefix = node_.substr(1) + ":";
  for (const auto& status : msg->status) {
    if (status.name.rfind(prefix, 0) == 0) diagnostics_.emplace_back(msg->header.stamp, status);
  }
}

bool NodeClient::waitState(const std::function<bool(const cloth_sim::ClothState&)>& pred,
                           double timeout_s, cloth_sim::ClothState* state,
                           visualization_msgs::Marker* marker) {
  states_.clear();
  cloth_sim::ClothState::ConstPtr found;
  spinUntil(
      [&] {
        while (!states_.empty() && !found) {
          if (pred(*states_.front())) found = states_.front();
          states_.pop_front();
        }
        return found != nullptr;
      },
      timeout_s);
  if (!found) return false;
  if (state) *state = *found;
  if (marker) {
    // The marker of a tick is published just before its state.
    const bool matched = spinUntil(
        [&] {
          for (const auto& m : markers_) {
            if (m->header.stamp == found->header.stamp) {
              *marker = *m;
              return true;
            }
          }
          return false;
        },
        2.0);
    if (!matched) return false;
  }
  return true;
}

bool NodeClient::waitSimTime(double sim_time, cloth_sim::ClothState* state,
                             visualization_msgs::Marker* marker, double timeout_s) {
  return waitState([&](const cloth_sim::ClothState& s) { return s.sim_time >= sim_time; },
                   timeout_s, state, marker);
}

bool NodeClient::reset(cloth_sim::ClothState* state, visualization_msgs::Marker* marker) {
  // Connected first, or the state the reset publishes could be missed.
  if (!waitState([](const cloth_sim::ClothState&) { return true; }, 20.0, nullptr)) return false;
  if (!spinUntil([&] { return !markers_.empty(); }, 5.0)) return false;
  std_srvs::Trigger srv;
  states_.clear();
  if (!ros::service::call(node_ + "/reset", srv) || !srv.response.success) return false;
  // The reset publishes the initial state at once; queued older states are skipped
  // by requiring sim_time 0.
  return waitState([](const cloth_sim::ClothState& s) { return s.sim_time == 0.0; }, 5.0, state,
                   marker);
}

bool NodeClient::waitDiagnostics(diagnostic_msgs::DiagnosticStatus* status, double timeout_s) {
  // Stamped after this call: one already queued (published before a service
  // call just answered) would show the state before it (a flake under load).
  const ros::Time after = ros::Time::now();
  diagnostics_.clear();
  const bool got = spinUntil(
      [&] {
        while (!diagnostics_.empty() && !(diagnostics_.front().first > after)) {
          diagnostics_.pop_front();
        }
        return !diagnostics_.empty();
      },
      timeout_s);
  if (got) *status = diagnostics_.front().second;
  return got;
}

std::string NodeClient::value(const diagnostic_msgs::DiagnosticStatus& status,
                              const std::string& key) {
  for (const auto& kv : status.values) {
    if (kv.key == key) return kv.value;
  }
  return "<missing " + key + ">";
}

}  // namespace cloth_sim_test
