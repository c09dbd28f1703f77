// rostest: ~cloth arrives at the configured rate, whole and finite (marker_rate.test).
#include <gtest/gtest.h>

#include <cmath>

#include <ros/ros.h>

#include "cloth_sim/ClothState.h"
#include "node_test_helpers.hpp"

using visualization_msgs::Marker;

namespace {

constexpr double kRate = 30.0;      // marker_rate.test
constexpr size_t kPoints = 6 * 7 * 7;  // 6 (rows - 1)(cols - 1), 8 x 8 cloth

bool finitePoints(const Marker& m) {
  for (const auto& p : m.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
  }
  return true;
}

TEST(MarkerRate, ClothMarkerArrivesAtRateWholeAndFinite) {
  ros::NodeHandle nh;
  std::vector<ros::WallTime> arrivals;
  std::vector<Marker::ConstPtr> markers;
  ros::Subscriber sub = nh.subscribe<Marker>(
      "/cloth_sim/cloth", 100, boost::function<void(const Marker::ConstPtr&)>([&](const Marker::ConstPtr& m) {
        arrivals.push_back(ros::WallTime::now());
        markers.push_back(m);
      }));
  ASSERT_TRUE(cloth_sim_test::spinUntil([&] { return !arrivals.empty(); }, 30.0));
  // Let the connection settle, then count over a fixed window.
  cloth_sim_test::spinUntil([] { return false; }, 1.0);
  arrivals.clear();
  markers.clear();
  const double window = 6.0;
  const ros::WallTime start = ros::WallTime::now();
  cloth_sim_test::spinUntil([] { return false; }, window);
  const double elapsed = (ros::WallTime::now() - start).toSec();
  const double rate = arrivals.size() / elapsed;
  EXPECT_NEAR(rate, kRate, 0.1 * kRate) << arrivals.size() << " markers in " << elapsed << " s";

  // Header stamps advance by one period on average, too.
  ASSERT_GE(markers.size(), 10u);
  const double stamp_span = (markers.back()->header.stamp - markers.front()->header.stamp).toSec();
  EXPECT_NEAR(stamp_span / (markers.size() - 1), 1.0 / kRate, 0.1 / kRate);

  for (const auto& m : markers) {
    ASSERT_EQ(m->points.size(), kPoints);
    ASSERT_TRUE(finitePoints(*m));
    EXPECT_EQ(m->type, Marker::TRIANGLE_LIST);
    EXPECT_EQ(m->action, Marker::ADD);
    EXPECT_EQ(m->ns, "cloth");
    EXPECT_EQ(m->id, 0);
    EXPECT_EQ(m->header.frame_id, "cloth_frame");
    EXPECT_EQ(m->pose.position.x, 0.0);
    EXPECT_EQ(m->pose.orientation.w, 1.0);
    EXPECT_EQ(m->pose.orientation.x, 0.0);
    EXPECT_EQ(m->scale.x, 1.0);
    EXPECT_EQ(m->scale.y, 1.0);
    EXPECT_EQ(m->scale.z, 1.0);
    EXPECT_FLOAT_EQ(m->color.r, 0.2f);
    EXPECT_FLOAT_EQ(m->color.g, 0.4f);
    EXPECT_FLOAT_EQ(m->color.b, 0.6f);
    EXPECT_FLOAT_EQ(m->color.a, 0.8f);
  }
}

TEST(MarkerRate, StateCarriesTheClothAndTheTickStatistics) {
  ros::NodeHandle nh;
  std::vector<cloth_sim::ClothState::ConstPtr> states;
  ros::Subscriber sub = nh.subscribe<cloth_sim::ClothState>(
      "/cloth_sim/state", 100,
      boost::function<void(const cloth_sim::ClothState::ConstPtr&)>(
          [&](const cloth_sim::ClothState::ConstPtr& s) { states.push_back(s); }));
  ASSERT_TRUE(cloth_sim_test::spinUntil([&] { return states.size() >= 20; }, 30.0));
  const int steps = static_cast<int>(std::ceil((1.0 / kRate) / 0.004));  // solver.dt 0.004
  for (size_t k = 1; k < states.size(); ++k) {
    const auto& s = *states[k];
    ASSERT_EQ(s.rows, 8u);
    ASSERT_EQ(s.cols, 8u);
    ASSERT_EQ(s.positions.size(), 64u);
    ASSERT_EQ(s.velocities.size(), 64u);
    EXPECT_EQ(s.header.frame_id, "cloth_frame");
    EXPECT_TRUE(s.ok) << s.failure;
    EXPECT_EQ(s.steps, static_cast<uint32_t>(steps));
    EXPECT_DOUBLE_EQ(s.dt, (1.0 / kRate) / steps);
    EXPECT_GT(s.cg_iterations, 0u);
    EXPECT_LE(s.residual, 1e-8);
    // Each tick advances simulated time by exactly one period.
    EXPECT_NEAR(s.sim_time - states[k - 1]->sim_time, 1.0 / kRate, 1e-9);
    for (const auto& p : s.positions) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));
  }
}

TEST(MarkerRate, StrainMarkerFollowsItsSubscriber) {
  ros::NodeHandle nh;
  std::vector<Marker::ConstPtr> markers;
  ros::Subscriber sub = nh.subscribe<Marker>(
      "/cloth_sim/strain", 10,
      boost::function<void(const Marker::ConstPtr&)>([&](const Marker::ConstPtr& m) { markers.push_back(m); }));
  ASSERT_TRUE(cloth_sim_test::spinUntil([&] { return markers.size() >= 5; }, 30.0));
  for (const auto& m : markers) {
    ASSERT_EQ(m->points.size(), kPoints);
    ASSERT_EQ(m->colors.size(), kPoints);
    EXPECT_EQ(m->ns, "strain");
    for (const auto& c : m->colors) {
      EXPECT_GE(c.r, 0.0f);
      EXPECT_LE(c.r, 1.0f);
      EXPECT_FLOAT_EQ(c.r + c.b, 1.0f);  // blue -> red
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_marker_rate");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
