// rostest: dragging the cloth through an interactive-marker handle (drag.test).
// The test plays RViz: it publishes the clicked point and the
// InteractiveMarkerFeedback messages RViz sends while the user drags.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include <geometry_msgs/PointStamped.h>
#include <ros/ros.h>
#include <visualization_msgs/InteractiveMarkerFeedback.h>
#include <visualization_msgs/InteractiveMarkerInit.h>
#include <visualization_msgs/InteractiveMarkerUpdate.h>

#include "node_test_helpers.hpp"

using cloth_sim::ClothState;
using cloth_sim::Vec3;
using cloth_sim_test::NodeClient;
using cloth_sim_test::toVec;
using visualization_msgs::InteractiveMarkerFeedback;

namespace {

constexpr double kRadius = 0.12;  // drag.test's drag_radius
constexpr double kReturnTime = 0.5;

bool isPinned(const ClothState& s, uint32_t node) {
  return std::find(s.pinned.begin(), s.pinned.end(), node) != s.pinned.end();
}

class DragTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(ros::service::waitForService("/cloth_sim/reset", ros::Duration(30)));
    click_pub_ = nh_.advertise<geometry_msgs::PointStamped>("/clicked_point", 1);
    feedback_pub_ = nh_.advertise<InteractiveMarkerFeedback>("/cloth_sim/drag/feedback", 100);
    init_sub_ = nh_.subscribe("/cloth_sim/drag/update_full", 5,
                              &DragTest::onInit, this);
    update_sub_ = nh_.subscribe("/cloth_sim/drag/update", 100, &DragTest::onUpdate, this);
    states_sub_ = nh_.subscribe("/cloth_sim/state", 500, &DragTest::onState, this);
    ASSERT_TRUE(cloth_sim_test::spinUntil(
        [&] { return click_pub_.getNumSubscribers() > 0 && feedback_pub_.getNumSubscribers() > 0; },
        20.0));
    ASSERT_TRUE(client_.reset(&state_));
    // The cloth hangs and settles a little before anything is clicked.
    ASSERT_TRUE(client_.waitSimTime(1.0, &state_));
  }

  void onInit(const visualization_msgs::InteractiveMarkerInit::ConstPtr& msg) {
    for (const auto& m : msg->markers) markers_.insert(m.name);
  }
  void onUpdate(const visualization_msgs::InteractiveMarkerUpdate::ConstPtr& msg) {
    for (const auto& m : msg->markers) markers_.insert(m.name);
    for (const auto& name : msg->erases) markers_.erase(name);
  }
  void onState(const ClothState::ConstPtr& msg) { recorded_.push_back(msg); }

  /// Clicks (RViz's Publish Point) just beside `node` and waits for its handle.
  bool handleOn(int node) {
    const Vec3 p = toVec(state_.positions[node]) + Vec3(0.01, 0.0, 0.0);
    geometry_msgs::PointStamped msg;
    msg.header.frame_id = "world";
    msg.header.stamp = ros::Time::now();
    msg.point.x = p.x();
    msg.point.y = p.y();
    msg.point.z = p.z();
    click_pub_.publish(msg);
    const std::string name = "node_" + std::to_string(node);
    return cloth_sim_test::spinUntil([&] { return markers_.count(name) != 0; }, 5.0);
  }

  void feedback(int node, uint8_t event, const Vec3& p, uint32_t menu_entry = 0) {
    InteractiveMarkerFeedback f;
    f.header.frame_id = "world";
    f.header.stamp = ros::Time::now();
    f.client_id = "/rviz/InteractiveMarkers";
    f.marker_name = "node_" + std::to_string(node);
    f.control_name = "move";
    f.event_type = event;
    f.pose.position.x = p.x();
    f.pose.position.y = p.y();
    f.pose.position.z = p.z();
    f.pose.orientation.w = 1.0;
    f.menu_entry_id = menu_entry;
    feedback_pub_.publish(f);
  }

  /// Drags node's handle from `from` at `velocity` for `duration` s (100 Hz
  /// pose updates, as RViz sends while the mouse moves); returns the end.
  Vec3 drag(int node, const Vec3& from, const Vec3& velocity, double duration) {
    feedback(node, InteractiveMarkerFeedback::MOUSE_DOWN, from);
    const ros::WallTime start = ros::WallTime::now();
    Vec3 p = from;
    while (ros::ok()) {
      const double t = (ros::WallTime::now() - start).toSec();
      if (t > duration) break;
      p = from + velocity * t;
      feedback(node, InteractiveMarkerFeedback::POSE_UPDATE, p);
      cloth_sim_test::spinUntil([] { return false; }, 0.01);
    }
    return p;
  }

  ClothState next() {
    ClothState s;
    EXPECT_TRUE(client_.waitState([](const ClothState&) { return true; }, 5.0, &s));
    return s;
  }

  ros::NodeHandle nh_;
  NodeClient client_;
  ros::Publisher click_pub_, feedback_pub_;
  ros::Subscriber init_sub_, update_sub_, states_sub_;
  std::set<std::string> markers_;
  std::vector<ClothState::ConstPtr> recorded_;
  ClothState state_;
};

TEST_F(DragTest, TheClothFollowsTheHandleAndSwingsWhenLetGo) {
  const int node = 27;  // row 3, col 3: free, mid-cloth
  ASSERT_TRUE(handleOn(node));
  const Vec3 start = toVec(state_.positions[node]);
  const Vec3 velocity(0.0, 0.4, 0.3);  // m/s, up and sideways
  const double duration = 1.2;

  recorded_.clear();
  const Vec3 end = drag(node, start, velocity, duration);
  cloth_sim_test::spinUntil([] { return false; }, 0.3);  // the last pose arrives
  const ClothState held = next();

  // The handle's node sits on the handle, pinned, with the nodes around it.
  ASSERT_TRUE(isPinned(held, node));
  EXPECT_LT((toVec(held.positions[node]) - end).norm(), 1e-9);
  std::vector<uint32_t> taken;
  for (uint32_t i : held.pinned) {
    if (i != 0 && i != 7) taken.push_back(i);
  }
  EXPECT_GE(taken.size(), 2u) << "drag_radius 0.12 takes the neighbours too";
  for (uint32_t i : taken) {
    EXPECT_LE((toVec(state_.positions[i]) - start).norm(), kRadius + 0.05) << "node " << i;
  }
  // The cloth follows: a free node two rows down has been pulled up and sideways.
  const int below = node + 16;
  EXPECT_GT(held.positions[below].y - state_.positions[below].y, 0.15);
  EXPECT_GT(held.positions[below].z - state_.positions[below].z, 0.05);

  // While dragged, the node moves as a pin with the handle's velocity: along
  // the handle's path, never jumping.
  int moving = 0;
  for (size_t k = 1; k < recorded_.size(); ++k) {
    const ClothState& a = *recorded_[k - 1];
    const ClothState& b = *recorded_[k];
    if (!isPinned(a, node) || !isPinned(b, node)) continue;
    const Vec3 pa = toVec(a.positions[node]), pb = toVec(b.positions[node]);
    const double along = (pb - start).dot(velocity) / velocity.squaredNorm();
    EXPECT_LT((pb - (start + velocity * along)).norm(), 1e-9) << "left the handle's path";
    const double dt = b.sim_time - a.sim_time;
    EXPECT_LE((pb - pa).norm(), 4.0 * velocity.norm() * dt + 1e-12) << "jumped at t " << b.sim_time;
    const Vec3 v(b.velocities[node].x, b.velocities[node].y, b.velocities[node].z);
    if (v.norm() > 0.0 && along > 0.2 && along < duration - 0.2) {
      ++moving;
      EXPECT_GT(v.dot(velocity) / (v.norm() * velocity.norm()), 0.999);
    }
  }
  EXPECT_GT(moving, 15) << "too few ticks saw the node moving with the handle";

  // Let go while moving: the nodes are free again and carry on (a fling).
  const Vec3 fling(0.0, 0.8, 0.0);
  recorded_.clear();
  const Vec3 last = drag(node, end, fling, 0.3);
  feedback(node, InteractiveMarkerFeedback::MOUSE_UP, last);
  ClothState released;
  ASSERT_TRUE(client_.waitState([&](const ClothState& s) { return !isPinned(s, node); }, 5.0,
                                &released));
  EXPECT_EQ(released.pinned, (std::vector<uint32_t>{0, 7}));
  // The last tick under the handle moved the node at the handle's velocity:
  // that is the velocity the cloth is let go with.
  ClothState::ConstPtr last_held;
  for (const auto& st : recorded_) {
    if (isPinned(*st, node)) last_held = st;
  }
  ASSERT_TRUE(last_held);
  EXPECT_GT(last_held->velocities[node].y, 0.5 * fling.y()) << "moving with the handle when let go";
  EXPECT_NEAR(last_held->velocities[node].z, 0.0, 1e-9);
  const ClothState later = next();
  EXPECT_NE(toVec(later.positions[node]), toVec(released.positions[node]));
  // The handle goes back to its node once let go.
  EXPECT_TRUE(markers_.count("node_27"));
}

TEST_F(DragTest, AScenePinnedNodeGlidesBackToItsPin) {
  const int corner = 7;  // pinned by the scene
  ASSERT_TRUE(handleOn(corner));
  const Vec3 pin = toVec(state_.positions[corner]);
  const Vec3 end = drag(corner, pin, Vec3(-0.3, 0.0, 0.2), 0.8);
  cloth_sim_test::spinUntil([] { return false; }, 0.2);
  ClothState s = next();
  EXPECT_LT((toVec(s.positions[corner]) - end).norm(), 1e-9);
  feedback(corner, InteractiveMarkerFeedback::MOUSE_UP, end);
  cloth_sim_test::spinUntil([] { return false; }, 0.2);
  s = next();
  EXPECT_TRUE(isPinned(s, corner));
  EXPECT_GT((toVec(s.positions[corner]) - pin).norm(), 1e-3) << "glides, does not jump back";
  ASSERT_TRUE(client_.waitSimTime(s.sim_time + kReturnTime + 0.1, &s));
  EXPECT_LT((toVec(s.positions[corner]) - pin).norm(), 1e-9);
  EXPECT_EQ(s.pinned, (std::vector<uint32_t>{0, 7}));
}

TEST_F(DragTest, MenuHoldsAndReleases) {
  const int node = 36;
  ASSERT_TRUE(handleOn(node));
  const Vec3 start = toVec(state_.positions[node]);
  // Menu entries in order: 1 "Hold after letting go", 2 "Release", 3 "Remove handle".
  feedback(node, InteractiveMarkerFeedback::MENU_SELECT, start, 1);
  const Vec3 end = drag(node, start, Vec3(0.2, 0.0, 0.2), 0.6);
  feedback(node, InteractiveMarkerFeedback::MOUSE_UP, end);
  cloth_sim_test::spinUntil([] { return false; }, 0.5);
  ClothState s = next();
  EXPECT_TRUE(isPinned(s, node)) << "held after letting go";
  EXPECT_LT((toVec(s.positions[node]) - end).norm(), 1e-9);

  feedback(node, InteractiveMarkerFeedback::MENU_SELECT, end, 2);  // Release
  ASSERT_TRUE(client_.waitState([&](const ClothState& st) { return !isPinned(st, node); }, 5.0,
                                &s));
  EXPECT_EQ(s.pinned, (std::vector<uint32_t>{0, 7}));

  feedback(node, InteractiveMarkerFeedback::MENU_SELECT, end, 3);  // Remove handle
  EXPECT_TRUE(cloth_sim_test::spinUntil([&] { return markers_.count("node_36") == 0; }, 5.0));
}

TEST_F(DragTest, AClickAwayFromTheClothMakesNoHandle) {
  geometry_msgs::PointStamped msg;
  msg.header.frame_id = "world";
  msg.point.x = 5.0;
  msg.point.z = 5.0;
  const size_t before = markers_.size();
  click_pub_.publish(msg);
  cloth_sim_test::spinUntil([] { return false; }, 1.0);
  EXPECT_EQ(markers_.size(), before);
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_drag");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
