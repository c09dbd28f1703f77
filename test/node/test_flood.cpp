// rostest (flood.test): the demo cloth at 60 Hz under a flood of service calls,
// 200 calls/s for 30 s, valid and invalid, on every service of the node
// (pin_nodes, release_nodes, set_stiffness, reset, grasp, release_grasp). Valid
// grasps take the nodes around a free node where the latest state shows it,
// in the node's own frame or in the moving `gripper` frame. Holds: every call is
// answered (valid ones succeed, invalid ones are refused with a message), the
// cloth marker keeps >= 95 % of its 60 Hz, and every marker and state is finite.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/Marker.h>

#include "cloth_sim/ClothState.h"
#include "cloth_sim/Grasp.h"
#include "cloth_sim/PinNodes.h"
#include "cloth_sim/ReleaseGrasp.h"
#include "cloth_sim/ReleaseNodes.h"
#include "cloth_sim/SetStiffness.h"

namespace {

constexpr double kRate = 60.0;         // flood.test
constexpr double kCallRate = 200.0;    // calls per second
constexpr double kFloodSeconds = 30.0;
constexpr int kNodes = 24 * 24;        // config/demo.yaml
const std::set<uint32_t> kScenePins = {0, 23};
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr int kSlots = 12;             // call kinds in one round of the schedule
constexpr double kGraspRadius = 0.15;  // m: about three grid spacings of the demo

struct Monitor {
  std::mutex mutex;
  std::vector<ros::WallTime> markers;  ///< arrival times
  long non_finite_markers = 0;
  long states = 0, non_finite_states = 0, failed_states = 0;
  std::string last_failure;
  cloth_sim::ClothState::ConstPtr latest;  ///< the latest state
  ros::WallTime latest_at;                 ///< when it arrived
  long resets_seen = 0;                    ///< states whose sim_time went back (a reset)
  double last_sim_time = -1.0;

  void onMarker(const visualization_msgs::Marker::ConstPtr& m) {
    bool finite = !m->points.empty();
    for (const auto& p : m->points) finite = finite && std::isfinite(p.x + p.y + p.z);
    std::lock_guard<std::mutex> lock(mutex);
    markers.push_back(ros::WallTime::now());
    if (!finite) ++non_finite_markers;
  }
  void onState(const cloth_sim::ClothState::ConstPtr& s) {
    bool finite = std::isfinite(s->energy) && std::isfinite(s->sim_time);
    for (const auto& p : s->positions) finite = finite && std::isfinite(p.x + p.y + p.z);
    for (const auto& v : s->velocities) finite = finite && std::isfinite(v.x + v.y + v.z);
    std::lock_guard<std::mutex> lock(mutex);
    ++states;
    latest = s;
    latest_at = ros::WallTime::now();
    if (s->sim_time < last_sim_time) ++resets_seen;
    last_sim_time = s->sim_time;
    if (!finite) ++non_finite_states;
    if (!s->ok) {
      ++failed_states;
      last_failure = s->failure;
    }
  }
  long markersBetween(ros::WallTime a, ros::WallTime b) {
    std::lock_guard<std::mutex> lock(mutex);
    return std::count_if(markers.begin(), markers.end(),
                         [&](const ros::WallTime& t) { return t >= a && t < b; });
  }
};

/// One call of the flood: what was asked, and whether it must succeed.
struct CallResult {
  bool answered = false;
  bool success = false;
  std::string message;
};

class Flood {
 public:
  Flood(ros::NodeHandle& nh, Monitor* monitor, tf2_ros::Buffer* tf)
      : pin_(nh.serviceClient<cloth_sim::PinNodes>("/cloth_sim/pin_nodes", true)),
        release_(nh.serviceClient<cloth_sim::ReleaseNodes>("/cloth_sim/release_nodes", true)),
        stiffness_(nh.serviceClient<cloth_sim::SetStiffness>("/cloth_sim/set_stiffness", true)),
        reset_(nh.serviceClient<std_srvs::Trigger>("/cloth_sim/reset", true)),
        grasp_(nh.serviceClient<cloth_sim::Grasp>("/cloth_sim/grasp", true)),
        release_grasp_(nh.serviceClient<cloth_sim::ReleaseGrasp>("/cloth_sim/release_grasp", true)),
        monitor_(monitor),
        tf_(tf),
        rng_(17) {}

  /// Call number k of the schedule; checks its answer against what it asked.
  void call(long k) {
    const int slot = static_cast<int>(k % kSlots);
    const long round = k / kSlots;
    const bool reset_now = k % 400 == 399;  // a reset every 2 s of the flood
    CallResult r;
    bool must_succeed = true;
    std::string what;
    if (reset_now) {
      what = "reset";
      std_srvs::Trigger srv;
      r.answered = call(reset_, srv);
      r.success = srv.response.success;
      r.message = srv.response.message;
      if (r.success) {
        pinned_.clear();
        grasps_.clear();  // a reset ends every grasp
        ++resets_done_;
      }
    } else if (slot == 0) {
      const uint32_t node = freeNode();
      what = "pin " + std::to_string(node);
      cloth_sim::PinNodes srv;
      srv.request.indices = {node};
      r.answered = call(pin_, srv);
      r.success = srv.response.success;
      r.message = srv.response.message;
      if (r.success) pinned_.insert(node);
    } else if (slot == 1) {
      must_succeed = false;
      what = "pin out of range";
      cloth_sim::PinNodes srv;
      srv.request.indices = {static_cast<uint32_t>(kNodes + k % 1000)};
      r.answered = call(pin_, srv);
      r.success = srv.response.success;
      r.message = srv.response.message;
    } else if (slot == 2) {
      std::uniform_real_distribution<double> k_of(2000.0, 8000.0);
      const double stiffness = k_of(rng_);
      what = "set_stiffness stretch " + std::to_string(stiffness);
      cloth_sim::SetStiffness srv;
      srv.request.spring_type = round % 2 == 0 ? "all" : "stretch";
      srv.request.stiffness = stiffness;
      srv.request.damping = -1.0;
      r.answered = call(stiffness_, srv);
      r.success = srv.response.success;
      r.message = srv.response.message;
    } else if (slot == 3) {
      must_succeed = false;
      cloth_sim::SetStiffness srv;
      switch (round % 4) {
        case 0: srv.request.spring_type = "wool"; srv.request.stiffness = 1e3; break;
        case 1: srv.request.spring_type = "stretch"; srv.request.stiffness = kNaN; break;
        case 2: srv.request.spring_type = "stretch"; srv.request.stiffness = -5.0; break;
        default:
          srv.request.spring_type = "shear";
          srv.request.stiffness = 1e3;
          srv.request.damping = kNaN;
      }
      what = "set_stiffness invalid " + srv.request.spring_type;
      r.answered = call(stiffness_, srv);
      r.success = srv.response.success;
      r.message = srv.response.message;
    } else if (slot == 4) {
      cloth_sim::ReleaseNodes srv;
      if (!pinned_.empty()) {
        const uint32_t node = *pinned_.begin();
        srv.request.indices = {node};
        what = "release " + std::to_string(node);
      } else {
        must_succeed = false;  // nothing of ours pinned: an empty list is refused
        what = "release nothing";
      }
      r.answered = call(release_, srv);
      r.success = srv.response.success;
      r.message = srv.response.message;
      if (r.success && !srv.request.indices.empty()) pinned_.erase(srv.request.indices[0]);
    } else if (slot == 5) {
      must_succeed = false;
      cloth_sim::ReleaseNodes srv;
      if (round % 2 == 0) {
        srv.request.indices = {freeNode()};
        what = "release a free node";
      } else {
        srv.request.indices = {1};
        srv.request.all = true;
        what = "release all with indices";
      }
      r.answered = call(release_, srv);
      r.success = srv.response.success;
      r.message = srv.response.message;
    } else if (slot == 10) {
      // Valid: grasp around a free node (in the node's frame, then in `gripper`),
      // then let go of that frame's grasp. A let-go after a reset ended the grasp
      // must be refused.
      const std::string frame = round % 4 < 2 ? "" : "gripper";
      if (round % 2 == 0) {
        what = "grasp in '" + frame + "'";
        cloth_sim::Grasp srv;
        srv.request.frame_id = frame;
        srv.request.radius = kGraspRadius;
        if (!graspPoint(frame, &srv.request.point)) {
          ++wrong_answers;
          ADD_FAILURE() << "call " << k << ": no state or no transform to aim a grasp";
          return;
        }
        r.answered = call(grasp_, srv);
        r.success = srv.response.success;
        r.message = srv.response.message;
        if (r.success) {
          grasps_[frame].insert(srv.response.indices.begin(), srv.response.indices.end());
          ++grasps_taken;
        }
        if (r.success && srv.response.indices.empty()) {
          r.success = false;  // a grasp that took nothing did not succeed
          r.message += " (no indices)";
        }
      } else {
        must_succeed = grasps_.count(frame) > 0;
        what = "release_grasp '" + frame + "'";
        cloth_sim::ReleaseGrasp srv;
        srv.request.frame_id = frame;
        r.answered = call(release_grasp_, srv);
        r.success = srv.response.success;
        r.message = srv.response.message;
        if (r.success) {
          grasps_.erase(frame);
          ++grasps_let_go;
        }
      }
    } else if (slot == 11) {
      must_succeed = false;
      cloth_sim::Grasp srv;
      srv.request.radius = 0.1;
      switch (round % 5) {
        case 0: srv.request.point.x = kNaN; what = "grasp at NaN"; break;
        case 1:
          srv.request.frame_id = "gripper";
          srv.request.radius = -0.1;
          what = "grasp with a negative radius";
          break;
        case 2: srv.request.frame_id = "no_such_frame"; what = "grasp on a missing frame"; break;
        case 3:
          srv.request.point.x = srv.request.point.y = srv.request.point.z = 100.0;
          srv.request.radius = 0.01;
          what = "grasp far from the cloth";
          break;
        default: what = "release_grasp of a frame that holds nothing";
      }
      if (round % 5 == 4) {
        cloth_sim::ReleaseGrasp release;
        release.request.frame_id = "no_grasp_frame";
        r.answered = call(release_grasp_, release);
        r.success = release.response.success;
        r.message = release.response.message;
      } else {
        r.answered = call(grasp_, srv);
        r.success = srv.response.success;
        r.message = srv.response.message;
      }
    } else {
      must_succeed = false;
      cloth_sim::PinNodes srv;
      const uint32_t node = freeNode();
      srv.request.indices = {node};
      geometry_msgs::Point p;
      switch (slot) {
        case 6: p.x = kNaN; srv.request.positions = {p}; what = "pin at NaN"; break;
        case 7: srv.request.positions = {p, p}; what = "pin with two positions"; break;
        case 8: srv.request.frame_id = "no_such_frame"; what = "pin to a missing frame"; break;
        default: srv.request.indices = {node, node}; what = "pin a node twice";
      }
      r.answered = call(pin_, srv);
      r.success = srv.response.success;
      r.message = srv.response.message;
    }
    ++calls;
    if (!r.answered) {
      ++unanswered;
      return;
    }
    if (r.message.empty()) ++empty_messages;
    if (r.success != must_succeed) {
      ++wrong_answers;
      if (wrong_answers <= 5) {
        ADD_FAILURE() << "call " << k << " (" << what << "): expected "
                      << (must_succeed ? "success" : "a refusal") << ", got '" << r.message << "'";
      }
    }
  }

  long calls = 0, unanswered = 0, wrong_answers = 0, empty_messages = 0;
  long grasps_taken = 0, grasps_let_go = 0;
  double worst_call_s = 0.0;

 private:
  template <typename Srv>
  bool call(ros::ServiceClient& client, Srv& srv) {
    const ros::WallTime start = ros::WallTime::now();
    const bool ok = client.call(srv);
    worst_call_s = std::max(worst_call_s, (ros::WallTime::now() - start).toSec());
    return ok;
  }

  bool grasped(uint32_t node) const {
    for (const auto& entry : grasps_) {
      if (entry.second.count(node)) return true;
    }
    return false;
  }

  uint32_t freeNode() {
    std::uniform_int_distribution<uint32_t> any(0, kNodes - 1);
    while (true) {
      const uint32_t node = any(rng_);
      if (!kScenePins.count(node) && !pinned_.count(node) && !grasped(node)) return node;
    }
  }

  /// Where a free node will be when the grasp arrives (the latest state moved on
  /// by its velocity), in `frame` ("" = the node's frame, world).
  bool graspPoint(const std::string& frame, geometry_msgs::Point* point) {
    const uint32_t node = freeNode();
    // After a reset, aim at the reset cloth: wait for its state (a few ms).
    const ros::WallTime give_up = ros::WallTime::now() + ros::WallDuration(1.0);
    while (true) {
      {
        std::lock_guard<std::mutex> lock(monitor_->mutex);
        if (monitor_->resets_seen >= resets_done_) break;
      }
      if (ros::WallTime::now() > give_up) return false;
      ros::WallDuration(0.001).sleep();
    }
    Eigen::Vector3d p;
    {
      std::lock_guard<std::mutex> lock(monitor_->mutex);
      if (!monitor_->latest || monitor_->latest->positions.size() != kNodes) return false;
      const auto& x = monitor_->latest->positions[node];
      const auto& v = monitor_->latest->velocities[node];
      const double ahead = (ros::WallTime::now() - monitor_->latest_at).toSec() + 1.0 / kRate;
      p = Eigen::Vector3d(x.x, x.y, x.z) + ahead * Eigen::Vector3d(v.x, v.y, v.z);
    }
    if (!frame.empty()) {
      geometry_msgs::TransformStamped t;
      try {
        t = tf_->lookupTransform(frame, "world", ros::Time(0));
      } catch (const std::exception&) {
        return false;
      }
      const auto& q = t.transform.rotation;
      const auto& d = t.transform.translation;
      p = Eigen::Quaterniond(q.w, q.x, q.y, q.z) * p + Eigen::Vector3d(d.x, d.y, d.z);
    }
    point->x = p.x();
    point->y = p.y();
    point->z = p.z();
    return true;
  }

  ros::ServiceClient pin_, release_, stiffness_, reset_, grasp_, release_grasp_;
  Monitor* monitor_;
  tf2_ros::Buffer* tf_;
  std::mt19937 rng_;
  std::set<uint32_t> pinned_;
  long resets_done_ = 0;
  std::map<std::string, std::set<uint32_t>> grasps_;  ///< frame ("" = the node's) -> nodes
};

TEST(Flood, ServicesAnsweredWhileTheClothKeepsItsRate) {
  ros::NodeHandle nh;
  Monitor monitor;
  ros::Subscriber markers = nh.subscribe("/cloth_sim/cloth", 200, &Monitor::onMarker, &monitor);
  ros::Subscriber states = nh.subscribe("/cloth_sim/state", 200, &Monitor::onState, &monitor);
  ros::AsyncSpinner spinner(1);
  spinner.start();
  for (const char* service : {"/cloth_sim/pin_nodes", "/cloth_sim/release_nodes",
                              "/cloth_sim/set_stiffness", "/cloth_sim/reset", "/cloth_sim/grasp",
                              "/cloth_sim/release_grasp"}) {
    ASSERT_TRUE(ros::service::waitForService(service, ros::Duration(30))) << service;
  }
  tf2_ros::Buffer tf;
  tf2_ros::TransformListener listener(tf);  // its own spinning thread
  std::string tf_error;
  ASSERT_TRUE(tf.canTransform("gripper", "world", ros::Time(0), ros::Duration(10.0), &tf_error))
      << tf_error;
  ros::WallDuration(2.0).sleep();  // subscriptions settle

  const ros::WallTime quiet_start = ros::WallTime::now();
  ros::WallDuration(3.0).sleep();
  const double quiet_rate =
      monitor.markersBetween(quiet_start, ros::WallTime::now()) /
      (ros::WallTime::now() - quiet_start).toSec();

  Flood flood(nh, &monitor, &tf);
  // Call k is due at start + k / 200 s; a late call is made at once (catch-up).
  const ros::WallTime start = ros::WallTime::now();
  for (long k = 0; (ros::WallTime::now() - start).toSec() < kFloodSeconds; ++k) {
    const ros::WallTime due = start + ros::WallDuration(k / kCallRate);
    const ros::WallTime now = ros::WallTime::now();
    if (due > now) (due - now).sleep();
    flood.call(k);
  }
  const ros::WallTime end = ros::WallTime::now();
  const double elapsed = (end - start).toSec();
  const double marker_rate = monitor.markersBetween(start, end) / elapsed;
  const double call_rate = flood.calls / elapsed;
  std::printf("[ flood    ] %ld calls in %.1f s (%.1f calls/s), worst call %.1f ms; markers "
              "%.2f Hz under the flood (%.1f %% of %g Hz), %.2f Hz before it; %ld states\n",
              flood.calls, elapsed, call_rate, 1e3 * flood.worst_call_s, marker_rate,
              100.0 * marker_rate / kRate, kRate, quiet_rate, monitor.states);
  std::printf("[ flood    ] %ld grasps taken, %ld let go\n", flood.grasps_taken,
              flood.grasps_let_go);

  EXPECT_GE(call_rate, 0.95 * kCallRate) << "the flood itself fell behind";
  EXPECT_EQ(flood.unanswered, 0) << "calls not answered";
  EXPECT_EQ(flood.wrong_answers, 0);
  EXPECT_EQ(flood.empty_messages, 0) << "every answer says what happened";
  EXPECT_GT(flood.grasps_taken, 0) << "no valid grasp was made";
  EXPECT_GT(flood.grasps_let_go, 0) << "no grasp was let go";
  EXPECT_GE(marker_rate, 0.95 * kRate);
  std::lock_guard<std::mutex> lock(monitor.mutex);
  EXPECT_EQ(monitor.non_finite_markers, 0);
  EXPECT_EQ(monitor.non_finite_states, 0);
  EXPECT_EQ(monitor.failed_states, 0) << monitor.last_failure;
  EXPECT_GT(monitor.states, 0.9 * kRate * kFloodSeconds);
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_flood");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
