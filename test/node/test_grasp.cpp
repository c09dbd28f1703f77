// rostest: ~grasp and ~release_grasp against a running node (grasp.test).
// The test broadcasts the gripper frame itself, moving and turning.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <Eigen/Geometry>
#include <ros/ros.h>

#include "cloth_sim/Grasp.h"
#include "cloth_sim/ReleaseGrasp.h"
#include "node_test_helpers.hpp"
#include "tf_test_helpers.hpp"

using cloth_sim::ClothState;
using cloth_sim::Vec3;
using cloth_sim_test::toVec;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const std::vector<uint32_t> kScenePins = {0, 7};

Eigen::Isometry3d pose(const Vec3& at, double yaw) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translate(at);
  t.rotate(Eigen::AngleAxisd(yaw, Vec3::UnitZ()));
  return t;
}

cloth_sim::Grasp::Response grasp(const std::string& frame, const Vec3& point, double radius) {
  cloth_sim::Grasp srv;
  srv.request.frame_id = frame;
  srv.request.point = cloth_sim_test::toPoint(point);
  srv.request.radius = radius;
  EXPECT_TRUE(ros::service::call("/cloth_sim/grasp", srv));
  return srv.response;
}

cloth_sim::ReleaseGrasp::Response releaseGrasp(const std::string& frame) {
  cloth_sim::ReleaseGrasp srv;
  srv.request.frame_id = frame;
  EXPECT_TRUE(ros::service::call("/cloth_sim/release_grasp", srv));
  return srv.response;
}

TEST(Grasp, CarriesTheGraspedNodesWithTheFrameAndDropsThemOnRelease) {
  cloth_sim_test::NodeClient client;
  ASSERT_TRUE(ros::service::waitForService("/cloth_sim/grasp", ros::Duration(30)));
  ASSERT_TRUE(client.reset());
  ClothState s;
  ASSERT_TRUE(client.waitSimTime(1.0, &s));  // hanging
  const Eigen::Isometry3d start = pose(toVec(s.positions[27]) + Vec3(0.0, 0.0, 0.03), 0.0);
  cloth_sim_test::FrameBroadcaster gripper("test_gripper", 0.005);
  gripper.run([&](double) { return start; }, 1.0);  // the node's tf buffer fills

  // Refused requests name the field and change nothing.
  auto refused = [&](const cloth_sim::Grasp::Response& res, const std::string& fragment) {
    EXPECT_FALSE(res.success);
    EXPECT_NE(res.message.find(fragment), std::string::npos) << res.message;
    EXPECT_TRUE(res.indices.empty());
    ClothState now;
    ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &now));
    EXPECT_EQ(now.pinned, kScenePins);
  };
  refused(grasp("ghost", Vec3::Zero(), 0.1), "frame_id: 'ghost' has no transform");
  refused(grasp("test_gripper", Vec3::Zero(), -0.1), "radius: must be >= 0");
  refused(grasp("test_gripper", Vec3::Zero(), kNaN), "radius: must be >= 0 and finite");
  refused(grasp("test_gripper", Vec3(kNaN, 0, 0), 0.1), "point: must be finite");
  refused(grasp("test_gripper", Vec3(0.0, 0.0, 2.0), 0.05), "no free node within 0.05 m");
  const auto no_grasp = releaseGrasp("test_gripper");
  EXPECT_FALSE(no_grasp.success);
  EXPECT_NE(no_grasp.message.find("no grasp on 'test_gripper'"), std::string::npos)
      << no_grasp.message;

  // Grasp around node 27: it and its neighbours within 0.12 m.
  gripper.run([&](double) { return start; }, 0.2);
  const auto res = grasp("test_gripper", Vec3(0.0, 0.0, -0.03), 0.12);
  ASSERT_TRUE(res.success) << res.message;
  ASSERT_GE(res.indices.size(), 2u);
  EXPECT_NE(std::find(res.indices.begin(), res.indices.end(), 27u), res.indices.end());
  gripper.run([&](double) { return start; }, 0.2);
  ClothState grasped;
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &grasped));
  std::vector<uint32_t> expected_pins = kScenePins;
  expected_pins.insert(expected_pins.end(), res.indices.begin(), res.indices.end());
  std::sort(expected_pins.begin(), expected_pins.end());
  EXPECT_EQ(grasped.pinned, expected_pins);
  for (uint32_t i : res.indices) {  // all within reach when grasped
    EXPECT_LE((toVec(grasped.positions[i]) - toVec(s.positions[27])).norm(), 0.12 + 0.05);
  }

  // The frame moves up and sideways and turns; the nodes go with it.
  const Vec3 velocity(0.0, 0.2, 0.25);
  const double yaw_rate = 0.5, duration = 1.5;
  auto moving = [&](double t) {
    return pose(start.translation() + velocity * std::min(t, duration), yaw_rate * std::min(t, duration));
  };
  gripper.run(moving, duration + 0.5);
  const Eigen::Isometry3d end = moving(duration);
  ClothState carried;
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &carried));
  for (uint32_t i : res.indices) {
    const Vec3 want = end * (start.inverse() * toVec(grasped.positions[i]));
    EXPECT_LT((toVec(carried.positions[i]) - want).norm(), 1e-9) << "node " << i;
  }
  EXPECT_GT(carried.positions[27].z - grasped.positions[27].z, 0.3);

  // Release: they are free again and fall.
  const auto released = releaseGrasp("test_gripper");
  ASSERT_TRUE(released.success) << released.message;
  EXPECT_EQ(released.indices, res.indices);
  ClothState after;
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &after));
  EXPECT_EQ(after.pinned, kScenePins);
  ASSERT_TRUE(client.waitSimTime(after.sim_time + 0.3, &s));
  EXPECT_LT(s.positions[27].z, carried.positions[27].z - 0.05) << "dropped";
}

TEST(Grasp, ALostFrameLetsGo) {
  cloth_sim_test::NodeClient client;
  ASSERT_TRUE(ros::service::waitForService("/cloth_sim/grasp", ros::Duration(30)));
  ASSERT_TRUE(client.reset());
  ClothState s;
  ASSERT_TRUE(client.waitSimTime(0.5, &s));
  const Eigen::Isometry3d at = pose(toVec(s.positions[36]), 0.0);
  cloth_sim_test::FrameBroadcaster gripper("test_gripper", 0.005);
  gripper.run([&](double) { return at; }, 0.8);
  const auto res = grasp("test_gripper", Vec3::Zero(), 0.3);  // the cloth swings meanwhile
  ASSERT_TRUE(res.success) << res.message;
  gripper.run([&](double) { return at; }, 0.3);
  ASSERT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &s));
  EXPECT_GT(s.pinned.size(), kScenePins.size());
  // The frame stops (tf_timeout 0.3 s): the grasp lets go, the scene pins stay.
  ASSERT_TRUE(client.waitState([](const ClothState& st) { return st.pinned == kScenePins; }, 5.0,
                               &s));
  EXPECT_FALSE(releaseGrasp("test_gripper").success) << "nothing left to release";
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_grasp");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
