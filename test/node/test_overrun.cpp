// rostest: a node that cannot keep its rate counts overruns and reports WARN,
// still advancing one period of simulated time per tick (overrun.test).
#include <gtest/gtest.h>

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include "node_test_helpers.hpp"

using diagnostic_msgs::DiagnosticStatus;
using cloth_sim_test::NodeClient;

namespace {

TEST(Overrun, SlowTicksAreCountedAndReportedAsWarn) {
  NodeClient client("/cloth_heavy");
  DiagnosticStatus d;
  ASSERT_TRUE(client.waitDiagnostics(&d, 60.0));
  ASSERT_TRUE(client.waitDiagnostics(&d, 20.0));
  EXPECT_EQ(d.level, DiagnosticStatus::WARN) << d.message;
  EXPECT_NE(d.message.find("overran"), std::string::npos) << d.message;
  EXPECT_GT(std::stod(NodeClient::value(d, "overruns")), 0.0);
  EXPECT_GT(std::stod(NodeClient::value(d, "overruns total")), 0.0);
  EXPECT_LT(std::stod(NodeClient::value(d, "achieved rate (Hz)")), 60.0);
  EXPECT_LT(std::stod(NodeClient::value(d, "real-time factor")), 1.0);
  EXPECT_EQ(std::stod(NodeClient::value(d, "steps per tick")), 167.0);

  // Every tick is still exactly one period of simulated time, no catching up.
  cloth_sim::ClothState a, b;
  ASSERT_TRUE(client.waitState([](const cloth_sim::ClothState&) { return true; }, 10.0, &a));
  ASSERT_TRUE(client.waitState([](const cloth_sim::ClothState&) { return true; }, 10.0, &b));
  EXPECT_NEAR(b.sim_time - a.sim_time, 1.0 / 60.0, 1e-9);
  EXPECT_EQ(b.steps, 167u);
  EXPECT_TRUE(b.ok) << b.failure;

  // Work does not pile up: a service call is answered within a few ticks.
  std_srvs::Trigger srv;
  const ros::WallTime start = ros::WallTime::now();
  ASSERT_TRUE(ros::service::call("/cloth_heavy/reset", srv));
  EXPECT_TRUE(srv.response.success);
  EXPECT_LT((ros::WallTime::now() - start).toSec(), 5.0);
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_overrun");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
