// rostest: live tuning through real dynamic_reconfigure requests (tuning.test),
// as dynparam and rqt_reconfigure send them: ~tuning/set_parameters.
#include <gtest/gtest.h>

#include <cmath>

#include <dynamic_reconfigure/Config.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <ros/ros.h>

#include "cloth_sim/SetStiffness.h"
#include "node_test_helpers.hpp"

using cloth_sim::ClothState;
using dynamic_reconfigure::Config;

namespace {

const char* kService = "/cloth_sim/tuning/set_parameters";

/// Largest strain of the stretch springs (row and column neighbours, rest
/// length 0.1 m in small_scene.yaml).
double stretchStrain(const ClothState& s) {
  double strain = 0.0;
  for (int r = 0; r < 8; ++r) {
    for (int c = 0; c < 8; ++c) {
      const cloth_sim::Vec3 p = cloth_sim_test::toVec(s.positions[8 * r + c]);
      if (c + 1 < 8) strain = std::max(strain, (cloth_sim_test::toVec(s.positions[8 * r + c + 1]) - p).norm() / 0.1 - 1.0);
      if (r + 1 < 8) strain = std::max(strain, (cloth_sim_test::toVec(s.positions[8 * r + c + 8]) - p).norm() / 0.1 - 1.0);
    }
  }
  return strain;
}

double number(const Config& c, const std::string& name) {
  for (const auto& d : c.doubles) {
    if (d.name == name) return d.value;
  }
  ADD_FAILURE() << "no double " << name;
  return NAN;
}

std::string text(const Config& c, const std::string& name) {
  for (const auto& s : c.strs) {
    if (s.name == name) return s.value;
  }
  ADD_FAILURE() << "no string " << name;
  return "";
}

/// One reconfigure request; returns the config the node answers with.
Config request(const std::vector<std::pair<std::string, double>>& doubles,
               const std::vector<std::pair<std::string, std::string>>& strs = {}) {
  dynamic_reconfigure::Reconfigure srv;
  for (const auto& [name, value] : doubles) {
    dynamic_reconfigure::DoubleParameter p;
    p.name = name;
    p.value = value;
    srv.request.config.doubles.push_back(p);
  }
  for (const auto& [name, value] : strs) {
    dynamic_reconfigure::StrParameter p;
    p.name = name;
    p.value = value;
    srv.request.config.strs.push_back(p);
  }
  EXPECT_TRUE(ros::service::call(kService, srv));
  return srv.response.config;
}

class TuningTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(ros::service::waitForService(kService, ros::Duration(30)));
    updates_ = nh_.subscribe("/cloth_sim/tuning/parameter_updates", 20, &TuningTest::onUpdate, this);
    ASSERT_TRUE(client_.reset());
  }
  void onUpdate(const Config::ConstPtr& msg) { last_update_ = msg; }

  /// Waits for a published config satisfying pred.
  bool published(const std::function<bool(const Config&)>& pred) {
    return cloth_sim_test::spinUntil([&] { return last_update_ && pred(*last_update_); }, 5.0);
  }

  ros::NodeHandle nh_;
  cloth_sim_test::NodeClient client_;
  ros::Subscriber updates_;
  Config::ConstPtr last_update_;
};

TEST_F(TuningTest, ShowsTheSceneAndAStifferClothStretchesLess) {
  const Config now = request({});  // an empty request answers the current config
  EXPECT_EQ(number(now, "stretch_stiffness"), 500.0);
  EXPECT_EQ(number(now, "shear_damping"), 0.2);
  EXPECT_EQ(number(now, "bend_stiffness"), 0.0);  // not modelled
  EXPECT_EQ(number(now, "gravity_z"), -9.81);
  EXPECT_EQ(number(now, "dt"), 0.004);
  EXPECT_EQ(text(now, "method"), "implicit_euler");

  ClothState soft;
  ASSERT_TRUE(client_.waitSimTime(2.0, &soft));
  const Config c = request({{"stretch_stiffness", 5e4}});
  EXPECT_EQ(text(c, "result"), "applied");
  EXPECT_EQ(number(c, "stretch_stiffness"), 5e4);
  ClothState stiff;
  ASSERT_TRUE(client_.waitSimTime(soft.sim_time + 2.0, &stiff));
  EXPECT_LT(stretchStrain(stiff), 0.1 * stretchStrain(soft))
      << "soft " << stretchStrain(soft) << ", stiff " << stretchStrain(stiff);
  double k = 0.0;
  EXPECT_TRUE(ros::param::get("/cloth_sim/tuning/stretch_stiffness", k));
  EXPECT_EQ(k, 5e4);
}

TEST_F(TuningTest, BadRequestsAreRefusedNamingTheFieldAndChangeNothing) {
  ASSERT_EQ(text(request({{"stretch_stiffness", 800.0}}), "result"), "applied");
  ClothState before;
  ASSERT_TRUE(client_.waitState([](const ClothState&) { return true; }, 5.0, &before));
  struct Bad {
    std::vector<std::pair<std::string, double>> doubles;
    std::vector<std::pair<std::string, std::string>> strs;
    std::string fragment;
  };
  const Bad bad[] = {
      {{{"stretch_stiffness", -3.0}}, {}, "springs.stretch.stiffness: must be > 0, got -3"},
      {{{"stretch_stiffness", 0.0}}, {}, "springs.stretch.stiffness: must stay > 0"},
      {{{"bend_stiffness", 5.0}}, {}, "springs.bend: the scene does not model"},
      {{{"shear_damping", -1.0}}, {}, "springs.shear.damping"},
      {{{"dt", 0.0}}, {}, "solver.dt"},
      {{{"tolerance", 1.5}}, {}, "solver.tolerance"},
      {{{"air_drag", -0.1}}, {}, "air_drag"},
      {{}, {{"method", "rk4"}}, "solver.method: unknown method 'rk4'"},
      {{}, {{"preconditioner", "ilu"}}, "solver.preconditioner"},
      {{{"stretch_stiffness", 9000.0}, {"dt", -1.0}}, {}, "solver.dt"},  // all or nothing
  };
  for (const Bad& b : bad) {
    const Config c = request(b.doubles, b.strs);
    const std::string result = text(c, "result");
    EXPECT_EQ(result.rfind("refused: ", 0), 0u) << result;
    EXPECT_NE(result.find(b.fragment), std::string::npos) << result;
    // The answer, the published config and the parameters show what runs.
    EXPECT_EQ(number(c, "stretch_stiffness"), 800.0) << b.fragment;
    EXPECT_EQ(number(c, "dt"), 0.004);
    EXPECT_EQ(text(c, "method"), "implicit_euler");
  }
  EXPECT_TRUE(published([](const Config& c) {
    return number(c, "stretch_stiffness") == 800.0 && number(c, "bend_stiffness") == 0.0;
  }));
  double k = 0.0;
  EXPECT_TRUE(ros::param::get("/cloth_sim/tuning/stretch_stiffness", k));
  EXPECT_EQ(k, 800.0);
  // The simulation ran on untouched: same step size, no failure.
  ClothState after;
  ASSERT_TRUE(client_.waitState([](const ClothState&) { return true; }, 5.0, &after));
  EXPECT_EQ(after.dt, before.dt);
  EXPECT_TRUE(after.ok) << after.failure;
  EXPECT_GT(after.sim_time, before.sim_time);
}

TEST_F(TuningTest, GravitySolverAndOtherChangesShowUp) {
  // Gravity along +x: the hanging cloth swings towards +x.
  ClothState s0;
  ASSERT_TRUE(client_.waitSimTime(1.0, &s0));
  Config c = request({{"gravity_x", 9.81}, {"gravity_z", 0.0}});
  ASSERT_EQ(text(c, "result"), "applied");
  ClothState s1;
  ASSERT_TRUE(client_.waitSimTime(s0.sim_time + 1.5, &s1));
  EXPECT_GT(s1.positions[60].x, s0.positions[60].x + 0.2);

  // Solver: bdf2 at dt 0.01 -> the node divides its 1/30 s tick into 4 steps.
  c = request({{"dt", 0.01}}, {{"method", "bdf2"}, {"preconditioner", "cholesky"}});
  ASSERT_EQ(text(c, "result"), "applied");
  EXPECT_EQ(text(c, "method"), "bdf2");
  ClothState s2;
  ASSERT_TRUE(client_.waitState([](const ClothState& s) { return s.steps > 0; }, 5.0, &s2));
  EXPECT_NEAR(s2.dt, 1.0 / 120.0, 1e-15);
  EXPECT_TRUE(s2.ok) << s2.failure;

  // A change by another way (~set_stiffness) is published too.
  cloth_sim::SetStiffness srv;
  srv.request.spring_type = "shear";
  srv.request.stiffness = 123.0;
  srv.request.damping = -1.0;
  ASSERT_TRUE(ros::service::call("/cloth_sim/set_stiffness", srv));
  ASSERT_TRUE(srv.response.success);
  EXPECT_TRUE(published([](const Config& cfg) { return number(cfg, "shear_stiffness") == 123.0; }));

  // ~reset goes back to the scene, and the published config with it.
  ASSERT_TRUE(client_.reset());
  EXPECT_TRUE(published([](const Config& cfg) {
    return number(cfg, "shear_stiffness") == 50.0 && number(cfg, "gravity_z") == -9.81 &&
           text(cfg, "method") == "implicit_euler";
  }));
  ClothState s3;
  ASSERT_TRUE(client_.waitState([](const ClothState& s) { return s.steps > 0; }, 5.0, &s3));
  EXPECT_NEAR(s3.dt, 1.0 / 270.0, 1e-15);  // the scene's 0.004 s: 9 steps per tick
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_tuning");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
