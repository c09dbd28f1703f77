// rostest (colliders.test): a sphere collider attached to a tf2 frame that the
// test broadcasts pushes the cloth up: the nodes near it move away and none
// is ever inside it; ~colliders carries one marker per collider (a capsule's
// cylinder and two end spheres) and moves with the frame; ~state and the
// diagnostics report the contact; a frame that stops keeps its collider's
// last pose and is reported.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include "node_test_helpers.hpp"
#include "tf_test_helpers.hpp"

using cloth_sim::ClothState;
using cloth_sim::Vec3;
using cloth_sim_test::toVec;
using visualization_msgs::Marker;
using visualization_msgs::MarkerArray;

namespace {

constexpr double kTick = 1.0 / 30.0;        // colliders.test rate
constexpr double kRadius = 0.12;            // contact_scene.yaml
constexpr double kThickness = 0.002;
const Vec3 kStart(0.35, -0.35, 0.8);        // under the cloth's middle, clear of it
const Vec3 kVelocity(0.0, 0.0, 0.2);        // m/s, up through the cloth's plane
constexpr double kPushTime = 1.5;           // to z = 1.1: the cloth is pushed 0.22 m up
const std::vector<int> kMiddle = {27, 28, 35, 36};  // within 0.071 m of the sphere's axis

const Marker* find(const MarkerArray& array, const std::string& ns, int id) {
  for (const Marker& m : array.markers) {
    if (m.ns == ns && m.id == id) return &m;
  }
  return nullptr;
}

/// The latched ~colliders message, through a fresh subscriber.
MarkerArray latestColliders(ros::NodeHandle& nh) {
  MarkerArray::ConstPtr got;
  ros::Subscriber sub = nh.subscribe<MarkerArray>(
      "/cloth_sim/colliders", 1,
      boost::function<void(const MarkerArray::ConstPtr&)>(
          [&](const MarkerArray::ConstPtr& m) { got = m; }));
  cloth_sim_test::spinUntil([&] { return got != nullptr; }, 5.0);
  return got ? *got : MarkerArray();
}

Vec3 position(const Marker& m) { return {m.pose.position.x, m.pose.position.y, m.pose.position.z}; }

TEST(Colliders, ATfAttachedSpherePushesTheClothAndShowsOnColliders) {
  cloth_sim_test::FrameBroadcaster pusher("test_pusher", 0.005);
  cloth_sim_test::NodeClient client;
  std::vector<ClothState::ConstPtr> states;
  std::vector<MarkerArray::ConstPtr> arrays;
  ros::Subscriber state_sub = client.nh().subscribe<ClothState>(
      "/cloth_sim/state", 500,
      boost::function<void(const ClothState::ConstPtr&)>(
          [&](const ClothState::ConstPtr& m) { states.push_back(m); }));
  ros::Subscriber marker_sub = client.nh().subscribe<MarkerArray>(
      "/cloth_sim/colliders", 500,
      boost::function<void(const MarkerArray::ConstPtr&)>(
          [&](const MarkerArray::ConstPtr& m) { arrays.push_back(m); }));
  // The node waits for the frame at start-up: broadcast until it runs.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::ok() && states.empty() && ros::WallTime::now() < deadline) {
    pusher.runPosition([](double) { return kStart; }, 0.1);
  }
  ASSERT_FALSE(states.empty()) << "no ~state: the node did not start";
  pusher.runPosition([](double) { return kStart; }, 0.5);

  // ~colliders (latched): one marker per collider, a capsule as three.
  ASSERT_FALSE(arrays.empty()) << "nothing on ~colliders";
  {
    const MarkerArray& a = *arrays.back();
    std::set<std::string> namespaces;
    for (const Marker& m : a.markers) {
      namespaces.insert(m.ns);
      EXPECT_EQ(m.header.frame_id, "world");
      EXPECT_EQ(m.action, Marker::ADD);
    }
    EXPECT_EQ(namespaces, (std::set<std::string>{"pusher", "floor", "post"}));
    ASSERT_EQ(a.markers.size(), 5u);
    const Marker* sphere = find(a, "pusher", 0);
    ASSERT_NE(sphere, nullptr);
    EXPECT_EQ(sphere->type, Marker::SPHERE);
    EXPECT_NEAR(sphere->scale.x, 2 * kRadius, 1e-12);
    EXPECT_LT((position(*sphere) - kStart).norm(), 1e-9) << "the sphere is not on its frame";
    const Marker* floor = find(a, "floor", 0);
    ASSERT_NE(floor, nullptr);
    EXPECT_EQ(floor->type, Marker::CUBE);
    EXPECT_NEAR(floor->pose.position.z + 0.5 * floor->scale.z, 0.0, 1e-12);  // top face = plane
    const Marker* cylinder = find(a, "post", 0);
    ASSERT_NE(cylinder, nullptr);
    EXPECT_EQ(cylinder->type, Marker::CYLINDER);
    EXPECT_NEAR(cylinder->scale.z, 0.5, 1e-12);
    EXPECT_LT((position(*cylinder) - Vec3(2, 0, 0.25)).norm(), 1e-12);
    ASSERT_NE(find(a, "post", 1), nullptr);
    ASSERT_NE(find(a, "post", 2), nullptr);
    EXPECT_EQ(find(a, "post", 2)->type, Marker::SPHERE);
    EXPECT_LT((position(*find(a, "post", 2)) - Vec3(2, 0, 0.5)).norm(), 1e-12);
  }

  // Push: the sphere rises through the cloth's plane.
  states.clear();
  arrays.clear();
  const ros::Time t0 = ros::Time::now();
  pusher.runPosition([](double t) { return kStart + kVelocity * t; }, kPushTime);
  const Vec3 end = kStart + kVelocity * kPushTime;
  pusher.runPosition([&](double) { return end; }, 1.0);
  ASSERT_GT(states.size(), 50u);

  // No node ever inside the sphere (where ~colliders showed it at that tick).
  std::map<double, Vec3> sphere_at;  // stamp -> centre
  for (const auto& a : arrays) {
    const Marker* s = find(*a, "pusher", 0);
    ASSERT_NE(s, nullptr);
    sphere_at[s->header.stamp.toSec()] = position(*s);
  }
  ASSERT_GT(sphere_at.size(), 20u) << "~colliders not published each tick while the frame moves";
  int checked = 0;
  for (const auto& state : states) {
    const auto it = sphere_at.find(state->header.stamp.toSec());
    if (it == sphere_at.end()) continue;
    const Vec3 centre = it->second;
    for (size_t i = 0; i < state->positions.size(); ++i) {
      const double gap = (toVec(state->positions[i]) - centre).norm() - kRadius - kThickness;
      ASSERT_GE(gap, -1e-6) << "node " << i << " inside the sphere at t "
                            << (state->header.stamp - t0).toSec();
    }
    EXPECT_LE(state->max_penetration, 1e-6);
    ++checked;
  }
  EXPECT_GT(checked, 20);

  // The sphere followed its frame: within one tick of the frame while moving
  // (the collider reaches the frame's pose at the end of each tick), on it at rest.
  for (const auto& [stamp, centre] : sphere_at) {
    const double t = stamp - t0.toSec();
    if (t < 2 * kTick || t > kPushTime) continue;
    const double along = (centre - kStart).dot(kVelocity) / kVelocity.squaredNorm();
    EXPECT_LT((centre - (kStart + kVelocity * along)).norm(), 1e-9);
    EXPECT_LT(t - along, kTick + 0.05) << "the sphere lags its frame at t " << t;
    EXPECT_GT(t - along, -0.01) << "the sphere is ahead of its frame at t " << t;
  }
  EXPECT_LT((sphere_at.rbegin()->second - end).norm(), 1e-9);

  // The middle of the cloth was pushed up and away, onto the sphere's top.
  const ClothState& last = *states.back();
  for (int i : kMiddle) {
    const Vec3 p = toVec(last.positions[i]);
    EXPECT_GT(p.z(), 1.0 + 0.15) << "node " << i << " was not pushed up";
    EXPECT_GE((p - end).norm(), kRadius + kThickness - 1e-6) << "node " << i;
  }
  EXPECT_GT(last.contacts, 0u);
  EXPECT_GT(last.contact_normal_force, 0.0);
  EXPECT_LE(last.max_penetration, 1e-6);
  diagnostic_msgs::DiagnosticStatus diag;
  ASSERT_TRUE(client.waitDiagnostics(&diag));
  EXPECT_EQ(client.value(diag, "tf colliders"), "1");
  EXPECT_GT(std::stoi(client.value(diag, "contacts")), 0);
  EXPECT_GT(std::stod(client.value(diag, "contact normal force (N)")), 0.0);
  EXPECT_LE(std::stod(client.value(diag, "max penetration (m)")), 1e-6);

  // The frame stops: after tf_timeout the sphere keeps its last pose, the
  // diagnostics say why, the cloth stays outside it.
  cloth_sim_test::spinUntil([] { return false; }, 1.0);
  ASSERT_TRUE(client.waitDiagnostics(&diag));
  EXPECT_EQ(diag.level, diagnostic_msgs::DiagnosticStatus::WARN) << diag.message;
  EXPECT_NE(diag.message.find("test_pusher"), std::string::npos) << diag.message;
  EXPECT_EQ(client.value(diag, "tf colliders lost frames"), "1");
  states.clear();
  cloth_sim_test::spinUntil([&] { return states.size() > 10; }, 5.0);
  ASSERT_FALSE(states.empty());
  for (int i : kMiddle) {
    EXPECT_GE((toVec(states.back()->positions[i]) - end).norm(), kRadius + kThickness - 1e-6);
    EXPECT_GT(states.back()->positions[i].z, 1.15);
  }
  const MarkerArray held = latestColliders(client.nh());
  ASSERT_NE(find(held, "pusher", 0), nullptr);
  EXPECT_LT((position(*find(held, "pusher", 0)) - end).norm(), 1e-9);

  // Back: the sphere follows again; ~reset puts it on the frame, the cloth flat.
  pusher.runPosition([](double) { return kStart; }, 1.0);
  ClothState s;
  ASSERT_TRUE(client.reset(&s));
  for (int i : kMiddle) EXPECT_NEAR(s.positions[i].z, 1.0, 1e-12);
  EXPECT_EQ(s.max_penetration, 0.0);
  const MarkerArray after_reset = latestColliders(client.nh());
  ASSERT_NE(find(after_reset, "pusher", 0), nullptr);
  EXPECT_LT((position(*find(after_reset, "pusher", 0)) - kStart).norm(), 1e-9);
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_colliders");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
