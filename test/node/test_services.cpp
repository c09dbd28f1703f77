// rostest: the services of cloth_sim_node against a running node (services.test).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include <ros/ros.h>
#include <std_srvs/Trigger.h>

#include "cloth_messages.hpp"
#include "cloth_node.hpp"
#include "cloth_sim/PinNodes.h"
#include "cloth_sim/ReleaseNodes.h"
#include "cloth_sim/SetStiffness.h"
#include "node_test_helpers.hpp"

using cloth_sim::ClothState;
using cloth_sim::Vec3;
using cloth_sim_test::NodeClient;
using cloth_sim_test::markerPointOf;
using cloth_sim_test::toPoint;
using cloth_sim_test::toVec;
using visualization_msgs::Marker;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

class ServicesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    scene_ = cloth_sim_test::smallScene();
    model_ = cloth_sim::buildModel(scene_);
    ASSERT_TRUE(ros::service::waitForService("/cloth_sim/reset", ros::Duration(30)));
    ASSERT_TRUE(client_.reset(&initial_state_, &initial_marker_));
  }

  Vec3 nodeIn(const Marker& m, int node) const {
    return toVec(m.points.at(markerPointOf(model_, node)));
  }

  cloth_sim::PinNodes::Response pin(const std::vector<uint32_t>& indices,
                                    const std::vector<Vec3>& positions = {},
                                    const std::string& frame = "") {
    cloth_sim::PinNodes srv;
    srv.request.indices = indices;
    for (const Vec3& p : positions) srv.request.positions.push_back(toPoint(p));
    srv.request.frame_id = frame;
    EXPECT_TRUE(ros::service::call("/cloth_sim/pin_nodes", srv));
    return srv.response;
  }

  cloth_sim::ReleaseNodes::Response release(const std::vector<uint32_t>& indices,
                                            bool all = false) {
    cloth_sim::ReleaseNodes srv;
    srv.request.indices = indices;
    srv.request.all = all;
    EXPECT_TRUE(ros::service::call("/cloth_sim/release_nodes", srv));
    return srv.response;
  }

  cloth_sim::SetStiffness::Response setStiffness(const std::string& type, double k,
                                                 double damping = -1.0) {
    cloth_sim::SetStiffness srv;
    srv.request.spring_type = type;
    srv.request.stiffness = k;
    srv.request.damping = damping;
    EXPECT_TRUE(ros::service::call("/cloth_sim/set_stiffness", srv));
    return srv.response;
  }

  /// Largest max_strain over the states with sim_time in [from, to].
  double maxStrainBetween(double from, double to) {
    double worst = 0.0;
    ClothState s;
    EXPECT_TRUE(client_.waitSimTime(from, &s));
    worst = s.max_strain;
    while (s.sim_time < to) {
      if (!client_.waitState([](const ClothState&) { return true; }, 5.0, &s)) {
        ADD_FAILURE() << "no state";
        break;
      }
      worst = std::max(worst, s.max_strain);
    }
    return worst;
  }

  cloth_sim::Scene scene_;
  cloth_sim::Model model_;
  NodeClient client_;
  ClothState initial_state_;
  Marker initial_marker_;
};

/// What a refused request must not change: pins, time line, stiffness.
struct Snapshot {
  std::vector<uint32_t> pinned;
  double sim_time = 0.0;
  std::vector<Vec3> positions;
  std::map<std::string, std::string> stiffness;

  static Snapshot take(NodeClient& client) {
    Snapshot snap;
    ClothState s;
    EXPECT_TRUE(client.waitState([](const ClothState&) { return true; }, 5.0, &s));
    snap.pinned = s.pinned;
    snap.sim_time = s.sim_time;
    for (const auto& p : s.positions) snap.positions.push_back(toVec(p));
    diagnostic_msgs::DiagnosticStatus d;
    EXPECT_TRUE(client.waitDiagnostics(&d));
    for (const auto& kv : d.values) {
      if (kv.key.find("stiffness") != std::string::npos ||
          kv.key.find("damping") != std::string::npos) {
        snap.stiffness[kv.key] = kv.value;
      }
    }
    return snap;
  }

  void expectUnchanged(NodeClient& client, const std::string& what) const {
    const Snapshot now = take(client);
    EXPECT_EQ(pinned, now.pinned) << what << " changed the pins";
    // The whole cloth, pinned nodes (their targets) included, is where an
    // untouched simulation of the scene is after the same time: the tests
    // start from ~reset, and the node steps ticks of 1/30 s (services.test).
    cloth_sim::Simulation reference(cloth_sim_test::smallScene());
    const double tick = 1.0 / 30.0;
    const int n = cloth_sim_ros::ClothNode::stepsPerTick(tick, reference.dt());
    while (reference.time() < now.sim_time - 1e-9) {
      for (int k = 0; k < n; ++k) ASSERT_TRUE(reference.step(tick / n).ok);
    }
    ASSERT_NEAR(reference.time(), now.sim_time, 1e-9);
    ASSERT_EQ(now.positions.size(), static_cast<size_t>(reference.numNodes()));
    double worst = 0.0;
    for (int i = 0; i < reference.numNodes(); ++i) {
      worst = std::max(worst, (now.positions[i] - reference.position(i)).norm());
    }
    EXPECT_LT(worst, 1e-9) << what << " moved the cloth or a pin target";
    EXPECT_GT(now.sim_time, sim_time) << what << " reset or stopped the simulation";
    EXPECT_EQ(stiffness, now.stiffness) << what << " changed stiffness or damping";
    EXPECT_FALSE(stiffness.empty());
  }
};

void expectRefused(bool success, const std::string& message,
                   const std::vector<std::string>& must_contain) {
  EXPECT_FALSE(success) << "accepted; message: " << message;
  for (const std::string& part : must_contain) {
    EXPECT_NE(message.find(part), std::string::npos)
        << "message '" << message << "' lacks '" << part << "'";
  }
}

// ------------------------------------------------------------ marker ----

TEST_F(ServicesTest, InitialMarkerIsTheWholeClothInTriangles) {
  const Marker& m = initial_marker_;
  EXPECT_EQ(m.type, Marker::TRIANGLE_LIST);
  EXPECT_EQ(m.ns, "cloth");
  EXPECT_EQ(m.id, 0);
  EXPECT_EQ(m.header.frame_id, "world");
  EXPECT_EQ(m.pose.orientation.w, 1.0);
  EXPECT_EQ(m.scale.x, 1.0);
  EXPECT_TRUE(m.colors.empty());  // one colour keeps RViz's lighting
  ASSERT_EQ(m.points.size(), 6u * (8 - 1) * (8 - 1));
  EXPECT_EQ(initial_state_.rows, 8u);
  EXPECT_EQ(initial_state_.cols, 8u);
  EXPECT_EQ(initial_state_.pinned, (std::vector<uint32_t>{0, 7}));
}

// --------------------------------------------------------------- reset ----

TEST_F(ServicesTest, ResetRestoresTheInitialPointsExactly) {
  // Expected: the scene's initial layout, as triangles.
  cloth_sim::Simulation reference(scene_);
  Marker expected;
  cloth_sim_ros::setTrianglePoints(model_, reference.positions(), &expected);

  // Disturb everything reset must undo: pins, stiffness, time.
  ASSERT_TRUE(pin({60}).success);
  ASSERT_TRUE(release({0}).success);
  ASSERT_TRUE(setStiffness("stretch", 50.0, 3.0).success);
  ClothState later;
  Marker later_marker;
  ASSERT_TRUE(client_.waitSimTime(0.5, &later, &later_marker));
  EXPECT_NE(later_marker.points, expected.points);

  ClothState state;
  Marker marker;
  ASSERT_TRUE(client_.reset(&state, &marker));
  ASSERT_EQ(marker.points.size(), expected.points.size());
  for (size_t k = 0; k < expected.points.size(); ++k) {
    ASSERT_EQ(marker.points[k].x, expected.points[k].x) << "point " << k;
    ASSERT_EQ(marker.points[k].y, expected.points[k].y) << "point " << k;
    ASSERT_EQ(marker.points[k].z, expected.points[k].z) << "point " << k;
  }
  EXPECT_EQ(state.pinned, (std::vector<uint32_t>{0, 7}));
  diagnostic_msgs::DiagnosticStatus d;
  ASSERT_TRUE(client_.waitDiagnostics(&d));
  EXPECT_EQ(std::stod(NodeClient::value(d, "stretch stiffness (N/m)")), 500.0);
  EXPECT_EQ(std::stod(NodeClient::value(d, "stretch damping (N*s/m)")), 1.0);
}

// ----------------------------------------------------------- pin_nodes ----

TEST_F(ServicesTest, PinnedNodeStaysPutWhileOthersFall) {
  const int pinned = 63, free = 56;  // the two corners of the last row
  const auto res = pin({pinned});
  ASSERT_TRUE(res.success) << res.message;
  ClothState s1, s2;
  Marker m1, m2;
  ASSERT_TRUE(client_.waitSimTime(0.3, &s1, &m1));
  ASSERT_TRUE(client_.waitSimTime(0.8, &s2, &m2));
  EXPECT_EQ(s2.pinned, (std::vector<uint32_t>{0, 7, 63}));
  EXPECT_EQ(nodeIn(m1, pinned), nodeIn(m2, pinned));
  // Pinned where it was at the call, a tick or two after the reset.
  EXPECT_NEAR(nodeIn(m2, pinned).z(), nodeIn(initial_marker_, pinned).z(), 0.02);
  EXPECT_LT(nodeIn(m2, free).z(), nodeIn(initial_marker_, free).z() - 0.1);
}

TEST_F(ServicesTest, PinAtGivenPositionsPutsTheNodesThere) {
  const Vec3 a(0.1, -0.6, 0.8), b(0.6, -0.6, 0.9);
  const auto res = pin({56, 63}, {a, b});
  ASSERT_TRUE(res.success) << res.message;
  ClothState s;
  Marker m;
  ASSERT_TRUE(client_.waitSimTime(0.2, &s, &m));
  EXPECT_EQ(nodeIn(m, 56), a);
  EXPECT_EQ(nodeIn(m, 63), b);
  EXPECT_EQ(toVec(s.positions[56]), a);
}

// -------------------------------------------------------- release_nodes ----

TEST_F(ServicesTest, ReleasedNodeFalls) {
  const auto res = release({0});
  ASSERT_TRUE(res.success) << res.message;
  ClothState s;
  Marker m;
  ASSERT_TRUE(client_.waitSimTime(0.6, &s, &m));
  EXPECT_EQ(s.pinned, (std::vector<uint32_t>{7}));
  EXPECT_LT(nodeIn(m, 0).z(), nodeIn(initial_marker_, 0).z() - 0.1);
  EXPECT_EQ(nodeIn(m, 7), nodeIn(initial_marker_, 7));
}

TEST_F(ServicesTest, ReleaseAllDropsTheWholeCloth) {
  const auto res = release({}, true);
  ASSERT_TRUE(res.success) << res.message;
  ClothState s;
  Marker m;
  ASSERT_TRUE(client_.waitSimTime(0.4, &s, &m));
  EXPECT_TRUE(s.pinned.empty());
  // Free fall for ~0.4 s: every node about g t^2 / 2 = 0.78 m lower.
  for (int node : {0, 7, 56, 63}) {
    EXPECT_LT(nodeIn(m, node).z(), nodeIn(initial_marker_, node).z() - 0.5) << node;
  }
}

// -------------------------------------------------------- set_stiffness ----

TEST_F(ServicesTest, HigherStiffnessGivesSmallerStrain) {
  const double soft = maxStrainBetween(0.5, 1.5);

  Marker strain_marker;
  bool got_strain = false;
  double soft_red = 0.0, stiff_red = 0.0;
  double* red = &soft_red;
  ros::Subscriber sub = client_.nh().subscribe<Marker>(
      "/cloth_sim/strain", 5, boost::function<void(const Marker::ConstPtr&)>([&](const Marker::ConstPtr& m) {
        got_strain = true;
        strain_marker = *m;
        for (const auto& c : m->colors) *red = std::max<double>(*red, c.r);
      }));
  ASSERT_TRUE(client_.reset());
  maxStrainBetween(0.5, 1.5);
  ASSERT_TRUE(got_strain) << "no ~strain while subscribed";
  EXPECT_EQ(strain_marker.colors.size(), strain_marker.points.size());
  EXPECT_EQ(strain_marker.ns, "strain");

  ASSERT_TRUE(client_.reset());
  // Both modelled groups 100x stiffer (the shear springs stretch too).
  auto res = setStiffness("stretch", 100.0 * 500.0);
  ASSERT_TRUE(res.success) << res.message;
  res = setStiffness("shear", 100.0 * 50.0);
  ASSERT_TRUE(res.success) << res.message;
  red = &stiff_red;
  const double stiff = maxStrainBetween(0.5, 1.5);
  sub.shutdown();

  EXPECT_GT(soft, 0.005);  // soft springs stretch visibly
  EXPECT_LT(stiff, soft / 10.0) << "soft " << soft << ", stiff " << stiff;
  EXPECT_LT(stiff_red, soft_red / 5.0) << "strain colours: soft " << soft_red << ", stiff "
                                       << stiff_red;
  diagnostic_msgs::DiagnosticStatus d;
  ASSERT_TRUE(client_.waitDiagnostics(&d));
  EXPECT_EQ(std::stod(NodeClient::value(d, "stretch stiffness (N/m)")), 50000.0);
  EXPECT_EQ(std::stod(NodeClient::value(d, "stretch damping (N*s/m)")), 1.0);  // -1 keeps it
  EXPECT_LT(std::stod(NodeClient::value(d, "max strain")), soft);
}

TEST_F(ServicesTest, SetStiffnessAllChangesEveryModelledGroup) {
  const auto res = setStiffness("all", 800.0, 0.5);
  ASSERT_TRUE(res.success) << res.message;
  diagnostic_msgs::DiagnosticStatus d;
  ASSERT_TRUE(client_.waitDiagnostics(&d));
  for (const char* group : {"stretch", "shear"}) {
    EXPECT_EQ(std::stod(NodeClient::value(d, std::string(group) + " stiffness (N/m)")), 800.0);
    EXPECT_EQ(std::stod(NodeClient::value(d, std::string(group) + " damping (N*s/m)")), 0.5);
  }
}

// ------------------------------------------------------ stability in use ----

TEST_F(ServicesTest, StiffnessSwingsJumpsAndReleasesKeepTheClothFinite) {
  std::vector<ClothState::ConstPtr> states;
  std::vector<Marker::ConstPtr> markers;
  ros::Subscriber state_sub = client_.nh().subscribe<ClothState>(
      "/cloth_sim/state", 500,
      boost::function<void(const ClothState::ConstPtr&)>(
          [&](const ClothState::ConstPtr& s) { states.push_back(s); }));
  ros::Subscriber marker_sub = client_.nh().subscribe<Marker>(
      "/cloth_sim/cloth", 500,
      boost::function<void(const Marker::ConstPtr&)>(
          [&](const Marker::ConstPtr& m) { markers.push_back(m); }));
  ClothState s;
  auto wait = [&](double dt) {
    ASSERT_TRUE(client_.waitState([](const ClothState&) { return true; }, 5.0, &s));
    ASSERT_TRUE(client_.waitSimTime(s.sim_time + dt, &s));
  };
  ASSERT_TRUE(setStiffness("all", 100.0 * 500.0).success);  // 100x
  wait(0.3);
  ASSERT_TRUE(setStiffness("all", 500.0 / 100.0).success);  // then 10000x softer
  wait(0.3);
  ASSERT_TRUE(pin({63}, {Vec3(1.5, 0.5, 2.0)}).success);   // a pin target that jumps
  wait(0.3);
  ASSERT_TRUE(pin({63}, {Vec3(-1.0, -1.0, 0.0)}).success);
  wait(0.3);
  ASSERT_TRUE(setStiffness("all", 500.0 * 100.0).success);  // stiff while stretched far
  wait(0.3);
  ASSERT_TRUE(release({63, 7}).success);
  wait(0.3);

  ASSERT_GT(markers.size(), 40u);
  for (const auto& m : markers) {
    ASSERT_EQ(m->points.size(), 6u * 7 * 7);
    for (const auto& p : m->points) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));
  }
  for (const auto& st : states) {
    for (const auto& p : st->positions) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));
    EXPECT_TRUE(st->ok) << "t " << st->sim_time << ": " << st->failure;
  }
}

// --------------------------------------------------------- bad requests ----

TEST_F(ServicesTest, BadPinRequestsAreRefusedAndChangeNothing) {
  const Snapshot before = Snapshot::take(client_);
  struct Case {
    std::vector<uint32_t> indices;
    std::vector<Vec3> positions;
    std::string frame;
    std::vector<std::string> expect;
  };
  const std::vector<Case> cases = {
      {{}, {}, "", {"indices", "empty"}},
      {{64}, {}, "", {"indices[0]", "64", "out of range"}},
      {{10, 4000000000u}, {}, "", {"indices[1]", "4000000000"}},
      {{10, 11, 10}, {}, "", {"indices[2]", "10", "twice"}},
      {{10, 11}, {Vec3(0, 0, 1)}, "", {"positions", "2", "1"}},
      {{10}, {Vec3(kNaN, 0, 1)}, "", {"positions[0]", "nan"}},
      {{10}, {Vec3(0, kInf, 1)}, "", {"positions[0]", "inf"}},
      {{10}, {}, "no_such_frame", {"frame_id", "no_such_frame"}},
      // A pinned node's target must not move when the request is refused.
      {{7, 64}, {Vec3(0.3, 0.3, 0.3), Vec3(0, 0, 1)}, "", {"indices[1]", "64"}},
      {{7, 10}, {Vec3(0.3, 0.3, 0.3), Vec3(kNaN, 0, 1)}, "", {"positions[1]", "nan"}},
      {{7}, {Vec3(0.3, 0.3, 0.3)}, "no_such_frame", {"frame_id", "no_such_frame"}},
  };
  for (const Case& c : cases) {
    const auto res = pin(c.indices, c.positions, c.frame);
    expectRefused(res.success, res.message, c.expect);
  }
  before.expectUnchanged(client_, "a refused pin_nodes");
}

TEST_F(ServicesTest, BadReleaseRequestsAreRefusedAndChangeNothing) {
  const Snapshot before = Snapshot::take(client_);
  struct Case {
    std::vector<uint32_t> indices;
    bool all;
    std::vector<std::string> expect;
  };
  const std::vector<Case> cases = {
      {{}, false, {"indices", "empty"}},
      {{64}, false, {"indices[0]", "64"}},
      {{7, 7}, false, {"indices[1]", "7"}},
      {{7, 20}, false, {"indices[1]", "20", "not pinned"}},
      {{0}, true, {"indices", "all"}},
  };
  for (const Case& c : cases) {
    const auto res = release(c.indices, c.all);
    expectRefused(res.success, res.message, c.expect);
  }
  before.expectUnchanged(client_, "a refused release_nodes");
}

TEST_F(ServicesTest, BadStiffnessRequestsAreRefusedAndChangeNothing) {
  const Snapshot before = Snapshot::take(client_);
  struct Case {
    std::string type;
    double k, damping;
    std::vector<std::string> expect;
  };
  const std::vector<Case> cases = {
      {"wool", 100.0, -1.0, {"spring_type", "wool"}},
      {"", 100.0, -1.0, {"spring_type"}},
      {"bend", 100.0, -1.0, {"bend", "scene"}},  // the small scene models no bend springs
      {"stretch", kNaN, -1.0, {"stiffness", "nan"}},
      {"stretch", kInf, -1.0, {"stiffness", "inf"}},
      {"stretch", -5.0, -1.0, {"stiffness", "-5"}},
      {"stretch", 0.0, -1.0, {"stiffness", "0"}},
      {"shear", 100.0, -0.5, {"damping", "-0.5"}},
      {"shear", 100.0, kNaN, {"damping", "nan"}},
      {"all", 100.0, kInf, {"damping", "inf"}},
  };
  for (const Case& c : cases) {
    const auto res = setStiffness(c.type, c.k, c.damping);
    expectRefused(res.success, res.message, c.expect);
  }
  before.expectUnchanged(client_, "a refused set_stiffness");
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_services");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
