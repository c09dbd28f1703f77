// rostest: /diagnostics of a healthy node and of one whose solver fails
// (diagnostics.test).
#include <gtest/gtest.h>

#include <cmath>

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <ros/ros.h>

#include "node_test_helpers.hpp"

using diagnostic_msgs::DiagnosticStatus;
using cloth_sim_test::NodeClient;
using visualization_msgs::Marker;

namespace {

double number(const DiagnosticStatus& d, const std::string& key) {
  const std::string text = NodeClient::value(d, key);
  try {
    return std::stod(text);
  } catch (const std::exception&) {
    ADD_FAILURE() << key << ": not a number: " << text;
    return std::nan("");
  }
}

/// A status from after the node's first full diagnostics period.
DiagnosticStatus settledStatus(NodeClient& client) {
  DiagnosticStatus d;
  EXPECT_TRUE(client.waitDiagnostics(&d, 30.0));
  EXPECT_TRUE(client.waitDiagnostics(&d, 10.0));
  EXPECT_TRUE(client.waitDiagnostics(&d, 10.0));
  return d;
}

TEST(Diagnostics, HealthyNodeReportsOkWithItsFigures) {
  NodeClient client("/cloth_sim");
  const DiagnosticStatus d = settledStatus(client);
  EXPECT_EQ(d.level, DiagnosticStatus::OK) << d.message;
  EXPECT_EQ(d.message, "running");
  EXPECT_EQ(number(d, "rate (Hz)"), 30.0);
  EXPECT_NEAR(number(d, "achieved rate (Hz)"), 30.0, 6.0);
  EXPECT_EQ(number(d, "overruns"), 0.0);
  EXPECT_EQ(number(d, "steps per tick"), 9.0);  // ceil((1/30) / 0.004)
  EXPECT_NEAR(number(d, "dt (s)"), 1.0 / 270.0, 1e-9);
  EXPECT_GT(number(d, "CG iterations (per tick)"), 0.0);
  EXPECT_LE(number(d, "residual max"), 1e-8);
  EXPECT_GT(number(d, "step time (ms per tick)"), 0.0);
  EXPECT_TRUE(std::isfinite(number(d, "energy (J)")));
  EXPECT_GE(number(d, "max strain"), 0.0);
  EXPECT_NEAR(number(d, "real-time factor"), 1.0, 0.2);
  EXPECT_EQ(number(d, "failures total"), 0.0);
  EXPECT_EQ(number(d, "pinned nodes"), 2.0);
  EXPECT_EQ(number(d, "stretch stiffness (N/m)"), 500.0);
  EXPECT_EQ(NodeClient::value(d, "bend stiffness (N/m)"), "<missing bend stiffness (N/m)>");
}

TEST(Diagnostics, ErrorControlledNodeReportsItsStepSizes) {
  NodeClient client("/cloth_adaptive");
  const DiagnosticStatus d = settledStatus(client);
  EXPECT_EQ(d.level, DiagnosticStatus::OK) << d.message;
  EXPECT_EQ(number(d, "error tolerance"), 1e-3);
  const double h_min = number(d, "step size min (s)"), h_max = number(d, "step size max (s)");
  EXPECT_GT(h_min, 0.0);
  EXPECT_GE(h_max, h_min);
  EXPECT_LE(h_max, 1.0 / 30.0 + 1e-9);  // never past a tick's end
  EXPECT_GE(number(d, "error-rejected steps"), 0.0);
  EXPECT_NEAR(number(d, "real-time factor"), 1.0, 0.2);
  EXPECT_EQ(number(d, "failures total"), 0.0);
  // The fixed-step node has no error control to report.
  NodeClient fixed("/cloth_sim");
  DiagnosticStatus f;
  ASSERT_TRUE(fixed.waitDiagnostics(&f, 10.0));
  EXPECT_EQ(NodeClient::value(f, "error tolerance"), "<missing error tolerance>");
  EXPECT_NEAR(number(f, "step size max (s)"), 1.0 / 270.0, 1e-8);  // printed to 6 digits
}

TEST(Diagnostics, FailingSolverReportsErrorAndPublishesOnlyFinitePoints) {
  NodeClient client("/cloth_fail");
  ros::NodeHandle nh;
  std::vector<Marker::ConstPtr> markers;
  ros::Subscriber sub = nh.subscribe<Marker>(
      "/cloth_fail/cloth", 100,
      boost::function<void(const Marker::ConstPtr&)>(
          [&](const Marker::ConstPtr& m) { markers.push_back(m); }));
  const DiagnosticStatus d = settledStatus(client);
  EXPECT_EQ(d.level, DiagnosticStatus::ERROR) << d.message;
  EXPECT_NE(d.message.find("solver failed"), std::string::npos) << d.message;
  EXPECT_NE(d.message.find("non-finite"), std::string::npos) << d.message;
  EXPECT_GT(number(d, "failures total"), 0.0);

  cloth_sim::ClothState s;
  ASSERT_TRUE(client.waitState([](const cloth_sim::ClothState&) { return true; }, 5.0, &s));
  EXPECT_FALSE(s.ok);
  EXPECT_FALSE(s.failure.empty());
  for (const auto& p : s.positions) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));

  ASSERT_GT(markers.size(), 20u) << "the node must keep publishing the last good state";
  for (const auto& m : markers) {
    ASSERT_EQ(m->points.size(), 6u * 5 * 5);
    for (const auto& p : m->points) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));
  }
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_diagnostics");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
