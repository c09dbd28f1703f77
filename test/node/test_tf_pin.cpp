// rostest: a pin attached to a moving tf2 frame follows it within one tick
// (tf_pin.test). The test itself broadcasts the frame.
#include <gtest/gtest.h>

#include <cmath>

#include <ros/ros.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "cloth_sim/PinNodes.h"
#include "node_test_helpers.hpp"
#include "tf_test_helpers.hpp"

using cloth_sim::ClothState;
using cloth_sim::Vec3;
using cloth_sim_test::toPoint;
using cloth_sim_test::toVec;

namespace {

constexpr double kTick = 1.0 / 30.0;          // tf_pin.test rate
constexpr double kBroadcastPeriod = 0.005;    // 200 Hz
const Vec3 kStart(0.7, 0.0, 1.0);             // node 7's initial position
const Vec3 kVelocity(0.0, -0.15, 0.2);        // m/s

cloth_sim::PinNodes::Response pinToGripper(const std::vector<uint32_t>& indices,
                                           const std::vector<Vec3>& offsets) {
  cloth_sim::PinNodes srv;
  srv.request.indices = indices;
  for (const Vec3& p : offsets) srv.request.positions.push_back(toPoint(p));
  srv.request.frame_id = "test_gripper";
  EXPECT_TRUE(ros::service::call("/cloth_sim/pin_nodes", srv));
  return srv.response;
}

TEST(TfPin, PinnedNodesFollowAMovingFrameWithinOneTick) {
  cloth_sim_test::NodeClient client;
  ASSERT_TRUE(ros::service::waitForService("/cloth_sim/pin_nodes", ros::Duration(30)));
  ASSERT_TRUE(client.reset());
  cloth_sim_test::FrameBroadcaster gripper("test_gripper", kBroadcastPeriod);
  gripper.runPosition([](double) { return kStart; }, 1.0);  // the node's tf buffer fills

  // Node 7 at the frame's origin; node 6 grabbed where it is (empty positions).
  auto res = pinToGripper({7}, {Vec3::Zero()});
  ASSERT_TRUE(res.success) << res.message;
  ClothState s;
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &s));
  res = pinToGripper({6}, {});
  ASSERT_TRUE(res.success) << res.message;
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &s));
  const Vec3 grip6 = toVec(s.positions[6]) - kStart;  // node 6's offset in the frame

  // Move the frame along a line; record the states meanwhile.
  std::vector<ClothState::ConstPtr> states;
  ros::Subscriber sub = client.nh().subscribe<ClothState>(
      "/cloth_sim/state", 200,
      boost::function<void(const ClothState::ConstPtr&)>(
          [&](const ClothState::ConstPtr& m) { states.push_back(m); }));
  cloth_sim_test::spinUntil([] { return false; }, 0.3);
  states.clear();
  const ros::Time t0 = ros::Time::now();
  const double duration = 2.0;
  gripper.runPosition([](double t) -> Vec3 { return kStart + kVelocity * t; }, duration);
  gripper.runPosition([](double) -> Vec3 { return kStart + kVelocity * 2.0; }, 0.5);  // and rest

  int checked = 0;
  for (const auto& state : states) {
    const double age_start = (state->header.stamp - t0).toSec();
    if (age_start < 2 * kTick || age_start > duration) continue;  // moving, after the first ticks
    ASSERT_EQ(state->pinned, (std::vector<uint32_t>{0, 6, 7}));
    const Vec3 p7 = toVec(state->positions[7]);
    // Where on the frame's path is node 7, and when was the frame there?
    const double along = (p7 - kStart).dot(kVelocity) / kVelocity.squaredNorm();
    const Vec3 on_path = kStart + kVelocity * along;
    EXPECT_LT((p7 - on_path).norm(), 1e-9) << "node 7 left the frame's path";
    const double lag = age_start - along;
    EXPECT_LT(lag, kTick + 2 * kBroadcastPeriod + 0.01)
        << "node 7 is " << lag << " s behind the frame at t " << age_start;
    EXPECT_GT(lag, -0.005) << "node 7 ahead of the frame";
    // Node 6 keeps its offset in the frame.
    EXPECT_LT((toVec(state->positions[6]) - p7 - (grip6 - Vec3::Zero())).norm(), 1e-9);
    ++checked;
  }
  EXPECT_GT(checked, 40) << "too few states while moving";

  // At rest the nodes sit on the frame exactly.
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &s));
  const Vec3 end = kStart + kVelocity * 2.0;
  EXPECT_LT((toVec(s.positions[7]) - end).norm(), 1e-12);
  EXPECT_LT((toVec(s.positions[6]) - (end + grip6)).norm(), 1e-12);

  // A jump arrives within one tick (allow the tick already under way).
  const Vec3 jump = end + Vec3(0.1, 0.0, -0.1);
  const ros::WallTime jumped = ros::WallTime::now();
  bool arrived = false;
  double arrival = 0.0;
  states.clear();
  gripper.runPosition([&](double) { return jump; }, 2.0, [&] {
    for (const auto& st : states) {
      if ((toVec(st->positions[7]) - jump).norm() < 1e-12) {
        arrival = (ros::WallTime::now() - jumped).toSec();
        return arrived = true;
      }
    }
    return false;
  });
  ASSERT_TRUE(arrived);
  EXPECT_LT(arrival, 2 * kTick + 0.02);

  // The frame stops: after tf_timeout the pins hold their last position.
  cloth_sim_test::spinUntil([] { return false; }, 0.6);  // just wait
  ClothState a, b;
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &a));
  cloth_sim_test::spinUntil([] { return false; }, 0.5);  // just wait
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &b));
  EXPECT_EQ(toVec(a.positions[7]), toVec(b.positions[7]));
  EXPECT_LT((toVec(b.positions[7]) - jump).norm(), 1e-12);
  EXPECT_EQ(b.pinned, (std::vector<uint32_t>{0, 6, 7}));

  // A frame that is no longer broadcast cannot take new pins.
  res = pinToGripper({5}, {});
  EXPECT_FALSE(res.success);
  EXPECT_NE(res.message.find("test_gripper"), std::string::npos) << res.message;
  EXPECT_NE(res.message.find("old"), std::string::npos) << res.message;

  // Reset drops the attachment: the frame moves, node 7 stays at its scene pin.
  ASSERT_TRUE(client.reset(&s));
  gripper.runPosition([&](double t) -> Vec3 { return jump + kVelocity * t; }, 1.0);
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &s));
  EXPECT_EQ(toVec(s.positions[7]), kStart);
  EXPECT_EQ(s.pinned, (std::vector<uint32_t>{0, 7}));
}

// ~cloth_frame: the node puts `cloth` into tf at the cloth's centre of mass,
// stamped like the state it was computed from, so the fixed frame `world`
// exists in tf (RViz's "Fixed Frame" status) even with no gripper running.
TEST(TfPin, ClothFrameIsTheCentreOfMassOfEachState) {
  cloth_sim_test::NodeClient client;
  ASSERT_TRUE(ros::service::waitForService("/cloth_sim/pin_nodes", ros::Duration(30)));
  ASSERT_TRUE(client.reset());
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  cloth_sim_test::spinUntil([] { return false; }, 0.5);  // the buffer fills
  const cloth_sim::Model model = cloth_sim::buildModel(cloth_sim_test::smallScene());
  int checked = 0;
  for (int k = 0; k < 5; ++k) {
    ClothState s;
    ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &s));
    std::string error;
    ASSERT_TRUE(buffer.canTransform("world", "cloth", s.header.stamp, ros::Duration(2.0), &error))
        << error;
    const auto t = buffer.lookupTransform("world", "cloth", s.header.stamp);
    Vec3 centre = Vec3::Zero();
    double mass = 0.0;
    for (int i = 0; i < model.numNodes(); ++i) {
      centre += model.mass[i] * toVec(s.positions[i]);
      mass += model.mass[i];
    }
    centre /= mass;
    EXPECT_LT((Vec3(t.transform.translation.x, t.transform.translation.y,
                    t.transform.translation.z) - centre).norm(), 1e-9);
    EXPECT_EQ(t.transform.rotation.w, 1.0);
    ++checked;
  }
  EXPECT_EQ(checked, 5);
  // The cloth's own frame cannot hold a pin: it would follow what it holds.
  cloth_sim::PinNodes srv;
  srv.request.indices = {3};
  srv.request.frame_id = "cloth";
  ASSERT_TRUE(ros::service::call("/cloth_sim/pin_nodes", srv));
  EXPECT_FALSE(srv.response.success);
  EXPECT_EQ(srv.response.message.rfind("frame_id: 'cloth' is the node's own ~cloth_frame", 0), 0u)
      << srv.response.message;
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_tf_pin");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
