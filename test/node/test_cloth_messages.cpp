// The message builders: what ~cloth, ~strain and ~state contain for a given
// simulation, checked without ROS running.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "cloth_messages.hpp"
#include "cloth_sim/scene.hpp"
#include "node_params.hpp"

namespace {

cloth_sim::Scene scene(int rows, int cols) {
  return cloth_sim::parseScene("{cloth: {rows: " + std::to_string(rows) + ", cols: " +
                               std::to_string(cols) +
                               "}, springs: {stretch: {stiffness: 100}}, pins: [0]}");
}

TEST(ClothMessages, ClothMarkerHasTwoTrianglesPerCellWithConsistentWinding) {
  cloth_sim::Simulation sim(scene(4, 5));
  std_msgs::ColorRGBA color = cloth_sim_ros::defaultClothColor();
  auto m = cloth_sim_ros::triangleMarker("world", "cloth", color);
  cloth_sim_ros::setTrianglePoints(sim.model(), sim.positions(), &m);
  EXPECT_EQ(m.type, visualization_msgs::Marker::TRIANGLE_LIST);
  EXPECT_EQ(m.ns, "cloth");
  EXPECT_EQ(m.id, 0);
  EXPECT_EQ(m.pose.orientation.w, 1.0);
  EXPECT_EQ(m.scale.x, 1.0);
  EXPECT_EQ(m.color.r, color.r);
  ASSERT_EQ(m.points.size(), 6u * 3 * 4);
  // Flat horizontal cloth: every triangle's normal points the same way.
  for (size_t t = 0; t < m.points.size(); t += 3) {
    const cloth_sim::Vec3 a(m.points[t].x, m.points[t].y, m.points[t].z);
    const cloth_sim::Vec3 b(m.points[t + 1].x, m.points[t + 1].y, m.points[t + 1].z);
    const cloth_sim::Vec3 c(m.points[t + 2].x, m.points[t + 2].y, m.points[t + 2].z);
    const double nz = (b - a).cross(c - a).z();
    EXPECT_GT(std::abs(nz), 1e-6);
    if (t > 0) {
      const cloth_sim::Vec3 a0(m.points[0].x, m.points[0].y, m.points[0].z);
      const cloth_sim::Vec3 b0(m.points[1].x, m.points[1].y, m.points[1].z);
      const cloth_sim::Vec3 c0(m.points[2].x, m.points[2].y, m.points[2].z);
      EXPECT_GT(nz * (b0 - a0).cross(c0 - a0).z(), 0.0) << "triangle " << t / 3;
    }
  }
  // Every node of the grid appears.
  for (int node = 0; node < sim.numNodes(); ++node) {
    bool found = false;
    for (const auto& p : m.points) {
      found = found || (p.x == sim.position(node).x() && p.y == sim.position(node).y() &&
                        p.z == sim.position(node).z());
    }
    EXPECT_TRUE(found) << "node " << node;
  }
}

TEST(ClothMessages, UndersideIsEachTriangleTurnedOverJustBehindIt) {
  // RViz lights a triangle on its winding's side only: the underside marker
  // must face the other way and lie just behind the front, so that from
  // either side the nearer face is lit.
  cloth_sim::Simulation sim(scene(4, 5));
  cloth_sim::VecX x = sim.positions();
  for (int i = 0; i < sim.numNodes(); ++i) x[3 * i + 2] += 0.1 * std::sin(1.7 * i);  // not flat
  auto front = cloth_sim_ros::triangleMarker("world", "cloth", cloth_sim_ros::defaultClothColor());
  auto back = cloth_sim_ros::triangleMarker("world", "cloth_underside", cloth_sim_ros::defaultClothColor());
  cloth_sim_ros::setTrianglePoints(sim.model(), x, &front);
  cloth_sim_ros::setUndersidePoints(sim.model(), x, &back);
  ASSERT_EQ(back.points.size(), front.points.size());
  auto point = [](const geometry_msgs::Point& p) { return cloth_sim::Vec3(p.x, p.y, p.z); };
  for (size_t t = 0; t < front.points.size(); t += 3) {
    const cloth_sim::Vec3 a = point(front.points[t]), b = point(front.points[t + 1]),
                          c = point(front.points[t + 2]);
    const cloth_sim::Vec3 n = (b - a).cross(c - a).normalized();
    // Same corners, other order: a, c, b.
    const cloth_sim::Vec3 shift = point(back.points[t]) - a;
    EXPECT_NEAR((point(back.points[t + 1]) - c - shift).norm(), 0.0, 1e-12);
    EXPECT_NEAR((point(back.points[t + 2]) - b - shift).norm(), 0.0, 1e-12);
    // Moved kUndersideOffset along the back normal, facing it.
    EXPECT_NEAR((shift + cloth_sim_ros::kUndersideOffset * n).norm(), 0.0, 1e-12) << t / 3;
    const cloth_sim::Vec3 bn = (point(back.points[t + 1]) - point(back.points[t]))
                                   .cross(point(back.points[t + 2]) - point(back.points[t]));
    EXPECT_LT(bn.dot(n), 0.0) << t / 3;
  }
}

TEST(ClothMessages, ClothFrameSitsAtTheCentreOfMass) {
  // A heavy corner pulls the centre of mass towards it: the mean of the
  // positions would not.
  cloth_sim::Simulation sim(cloth_sim::parseScene(
      "{cloth: {rows: 3, cols: 3, width: 2.0, length: 2.0, origin: [1, 2, 3], mass: 0.9, "
      "node_mass: {8: 1.0}}, springs: {stretch: {stiffness: 100}}}"));
  const cloth_sim::Model& model = sim.model();
  cloth_sim::Vec3 expected = cloth_sim::Vec3::Zero();
  double mass = 0.0;
  for (int i = 0; i < model.numNodes(); ++i) {
    expected += model.mass[i] * sim.positions().segment<3>(3 * i);
    mass += model.mass[i];
  }
  expected /= mass;
  const auto t = cloth_sim_ros::clothFrame(model, sim.positions(), "world", "cloth");
  EXPECT_EQ(t.header.frame_id, "world");
  EXPECT_EQ(t.child_frame_id, "cloth");
  EXPECT_NEAR(t.transform.translation.x, expected.x(), 1e-12);
  EXPECT_NEAR(t.transform.translation.y, expected.y(), 1e-12);
  EXPECT_NEAR(t.transform.translation.z, expected.z(), 1e-12);
  EXPECT_EQ(t.transform.rotation.w, 1.0);
  EXPECT_EQ(t.transform.rotation.x, 0.0);
  // Node 8 (1 kg of 1.8) is the corner at the far row and column.
  cloth_sim::Vec3 mean = cloth_sim::Vec3::Zero();
  for (int i = 0; i < model.numNodes(); ++i) mean += sim.positions().segment<3>(3 * i) / 9.0;
  const cloth_sim::Vec3 corner = sim.positions().segment<3>(3 * 8);
  EXPECT_LT((expected - corner).norm(), (mean - corner).norm() - 0.3);
}

TEST(ClothMessages, AChainHasNoTriangles) {
  cloth_sim::Simulation sim(scene(5, 1));
  auto m = cloth_sim_ros::triangleMarker("world", "cloth", cloth_sim_ros::defaultClothColor());
  cloth_sim_ros::setTrianglePoints(sim.model(), sim.positions(), &m);
  EXPECT_TRUE(m.points.empty());
}

TEST(ClothMessages, StrainColourRunsFromBlueAtRestToRedAtTenPercent) {
  auto c = cloth_sim_ros::strainColor(0.0);
  EXPECT_EQ(c.r, 0.0f);
  EXPECT_EQ(c.b, 1.0f);
  c = cloth_sim_ros::strainColor(-0.3);  // compressed: still blue
  EXPECT_EQ(c.b, 1.0f);
  c = cloth_sim_ros::strainColor(0.05);
  EXPECT_FLOAT_EQ(c.r, 0.5f);
  EXPECT_FLOAT_EQ(c.b, 0.5f);
  c = cloth_sim_ros::strainColor(0.1);
  EXPECT_EQ(c.r, 1.0f);
  EXPECT_EQ(c.b, 0.0f);
  c = cloth_sim_ros::strainColor(3.0);
  EXPECT_EQ(c.r, 1.0f);
  EXPECT_EQ(c.a, 1.0f);
}

TEST(ClothMessages, StateCarriesPositionsVelocitiesPinsAndTime) {
  cloth_sim::Simulation sim(scene(3, 3));
  for (int k = 0; k < 5; ++k) sim.step(0.01);
  cloth_sim::ClothState msg;
  cloth_sim_ros::fillClothState(sim, &msg);
  EXPECT_EQ(msg.rows, 3u);
  EXPECT_EQ(msg.cols, 3u);
  ASSERT_EQ(msg.positions.size(), 9u);
  ASSERT_EQ(msg.velocities.size(), 9u);
  for (int i = 0; i < 9; ++i) {
    EXPECT_EQ(msg.positions[i].z, sim.position(i).z());
    EXPECT_EQ(msg.velocities[i].z, sim.velocities()[3 * i + 2]);
  }
  EXPECT_EQ(msg.pinned, std::vector<uint32_t>{0});
  EXPECT_DOUBLE_EQ(msg.sim_time, 0.05);
}

TEST(ClothMessages, ColliderMarkersShowEveryColliderWhereItIs) {
  cloth_sim::Simulation sim(cloth_sim::parseScene(R"({
    cloth: {rows: 3, cols: 3, origin: [0, 0, 2]},
    colliders: [
      {name: floor, type: plane, point: [0, 0, 0.5], normal: [1, 0, 0]},
      {name: ball, type: sphere, center: [1, 2, 3], radius: 0.25},
      {name: table, type: box, center: [0, 0, 0.4], half_extents: [0.5, 0.3, 0.4], rpy: [0, 0, 0.3]},
      {type: capsule, a: [0, 0, 1], b: [0.2, 0, 1], radius: 0.02}]})"));
  visualization_msgs::MarkerArray a;
  cloth_sim_ros::fillColliderMarkers(sim, "map", cloth_sim_ros::defaultColliderColor(), &a);
  using visualization_msgs::Marker;
  ASSERT_EQ(a.markers.size(), 6u);  // a capsule is a cylinder and two spheres
  for (const Marker& m : a.markers) EXPECT_EQ(m.header.frame_id, "map");
  // The plane: a thin CUBE whose top face is the plane, its z axis the normal.
  const Marker& plane = a.markers[0];
  EXPECT_EQ(plane.ns, "floor");
  EXPECT_EQ(plane.type, Marker::CUBE);
  EXPECT_NEAR(plane.pose.position.x, -0.5 * cloth_sim_ros::kPlaneMarkerThickness, 1e-15);
  EXPECT_NEAR(plane.pose.position.z, 0.5, 1e-15);
  const Eigen::Quaterniond qp(plane.pose.orientation.w, plane.pose.orientation.x,
                              plane.pose.orientation.y, plane.pose.orientation.z);
  EXPECT_LT((qp * cloth_sim::Vec3::UnitZ() - cloth_sim::Vec3::UnitX()).norm(), 1e-12);
  const Marker& ball = a.markers[1];
  EXPECT_EQ(ball.type, Marker::SPHERE);
  EXPECT_EQ(ball.scale.x, 0.5);
  EXPECT_EQ(ball.pose.position.y, 2.0);
  // The box keeps its yaw.
  const Marker& box = a.markers[2];
  EXPECT_EQ(box.type, Marker::CUBE);
  EXPECT_EQ(box.scale.y, 0.6);
  const Eigen::Quaterniond qb(box.pose.orientation.w, box.pose.orientation.x,
                              box.pose.orientation.y, box.pose.orientation.z);
  EXPECT_NEAR(qb.toRotationMatrix().eulerAngles(0, 1, 2).z(), 0.3, 1e-12);
  // The capsule (no name: named by its place in the list).
  EXPECT_EQ(a.markers[3].ns, "colliders[3]");
  EXPECT_EQ(a.markers[3].type, Marker::CYLINDER);
  EXPECT_NEAR(a.markers[3].scale.z, 0.2, 1e-15);
  EXPECT_NEAR(a.markers[3].pose.position.x, 0.1, 1e-15);
  EXPECT_EQ(a.markers[4].type, Marker::SPHERE);
  EXPECT_EQ(a.markers[5].pose.position.x, 0.2);
  EXPECT_EQ(a.markers[5].id, 2);

  // A moved collider is shown where it went.
  cloth_sim::Pose pose;
  pose.translation = cloth_sim::Vec3(-1, 0, 0);
  ASSERT_TRUE(sim.setColliderPose(1, pose));
  cloth_sim_ros::fillColliderMarkers(sim, "map", cloth_sim_ros::defaultColliderColor(), &a);
  EXPECT_EQ(a.markers[1].pose.position.x, -1.0);
  EXPECT_EQ(a.markers[1].pose.position.z, 0.0);
}

TEST(ClothMessages, TickStatsCombineTheSteps) {
  cloth_sim_ros::TickStats tick;
  cloth_sim::StepStats a, b;
  a.cg_iterations = 3;
  a.residual = 1e-7;
  a.energy = 5.0;
  b.cg_iterations = 4;
  b.residual = 1e-9;
  b.energy = 4.0;
  b.rejected = 1;
  b.substeps = 2;
  b.failure = "recovered from: energy jump";
  tick.add(a);
  tick.add(b);
  EXPECT_EQ(tick.steps, 3);
  EXPECT_EQ(tick.cg_iterations, 7);
  EXPECT_EQ(tick.residual, 1e-7);
  EXPECT_EQ(tick.energy, 4.0);
  EXPECT_EQ(tick.rejected, 1);
  EXPECT_TRUE(tick.ok);
  EXPECT_EQ(tick.failure, "recovered from: energy jump");
  cloth_sim::StepStats bad;
  bad.ok = false;
  bad.failure = "non-finite position or velocity";
  tick.add(bad);
  EXPECT_FALSE(tick.ok);
  EXPECT_EQ(tick.failure, "non-finite position or velocity");
}

}  // namespace
