// Collider geometry against brute force, and the swept first contact.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cloth_sim/collider.hpp"

namespace cloth_sim {
namespace {

ColliderParams shape(ColliderParams::Type type) {
  ColliderParams p;
  p.type = type;
  p.normal = Vec3(0.2, -0.3, 1.0);
  p.point = Vec3(0.1, 0.2, -0.1);
  p.center = Vec3(0.1, -0.2, 0.3);
  p.radius = 0.25;
  p.half_extents = Vec3(0.3, 0.2, 0.1);
  p.rpy = Vec3(0.3, -0.2, 0.7);
  p.a = Vec3(-0.2, 0.1, 0.0);
  p.b = Vec3(0.3, -0.1, 0.2);
  return p;
}

/// Points densely on the surface, in the collider's own frame.
std::vector<Vec3> surfaceSamples(const Collider& c) {
  std::vector<Vec3> out;
  const int n = 60;
  switch (c.type()) {
    case Collider::Type::Sphere:
    case Collider::Type::Capsule: {
      const Vec3 axis = c.segment();
      for (int k = 0; k <= (axis.norm() > 0 ? 40 : 0); ++k) {
        const Vec3 center = (k / 40.0) * axis;
        for (int i = 0; i <= n; ++i) {
          const double th = M_PI * i / n;
          for (int j = 0; j < 2 * n; ++j) {
            const double ph = M_PI * j / n;
            const Vec3 q = center + c.radius() * Vec3(std::sin(th) * std::cos(ph),
                                                      std::sin(th) * std::sin(ph), std::cos(th));
            // Keep the points of the union's boundary only (a capsule's
            // spheres overlap): those at distance r from the whole axis.
            double axis_distance = INFINITY;
            for (int m = 0; m <= 200; ++m) {
              axis_distance = std::min(axis_distance, (q - (m / 200.0) * axis).norm());
            }
            if (axis_distance >= c.radius() - 1e-3) out.push_back(q);
          }
        }
      }
      break;
    }
    case Collider::Type::Box: {
      const Vec3 h = c.halfExtents();
      for (int axis = 0; axis < 3; ++axis) {
        for (double side : {-1.0, 1.0}) {
          for (int i = 0; i <= n; ++i) {
            for (int j = 0; j <= n; ++j) {
              Vec3 p;
              p[axis] = side * h[axis];
              p[(axis + 1) % 3] = h[(axis + 1) % 3] * (2.0 * i / n - 1.0);
              p[(axis + 2) % 3] = h[(axis + 2) % 3] * (2.0 * j / n - 1.0);
              out.push_back(p);
            }
          }
        }
      }
      break;
    }
    case Collider::Type::Plane:
      break;
  }
  return out;
}

bool insideBrute(const Collider& c, const Vec3& p) {
  switch (c.type()) {
    case Collider::Type::Sphere: return p.norm() < c.radius();
    case Collider::Type::Box: return (p.cwiseAbs() - c.halfExtents()).maxCoeff() < 0.0;
    case Collider::Type::Capsule: {
      double best = INFINITY;
      for (int k = 0; k <= 2000; ++k) best = std::min(best, (p - (k / 2000.0) * c.segment()).norm());
      return best < c.radius();
    }
    case Collider::Type::Plane: return c.planeNormal().dot(p) < 0.0;
  }
  return false;
}

TEST(Collider, ClosestPointMatchesBruteForceForEveryShape) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.7, 0.7);
  for (auto type : {Collider::Type::Sphere, Collider::Type::Box, Collider::Type::Capsule}) {
    const Collider c = Collider::fromParams(shape(type), 0.3);
    const std::vector<Vec3> samples = surfaceSamples(c);
    for (int trial = 0; trial < 200; ++trial) {
      const Vec3 p(u(rng), u(rng), u(rng));
      const SurfacePoint s = c.closestLocal(p);
      double brute = INFINITY;
      for (const Vec3& q : samples) brute = std::min(brute, (p - q).norm());
      // Sampling spacing bounds the brute-force error.
      EXPECT_NEAR(std::abs(s.distance), brute, 0.01) << toString(type) << " trial " << trial;
      EXPECT_EQ(s.distance < 0.0, insideBrute(c, p)) << toString(type) << " trial " << trial;
      // The closest point lies on the surface at that distance, along the normal.
      EXPECT_NEAR(c.closestLocal(s.point).distance, 0.0, 1e-12);
      EXPECT_NEAR((p - s.point).norm(), std::abs(s.distance), 1e-12);
      EXPECT_NEAR(s.normal.norm(), 1.0, 1e-12);
      EXPECT_LE((p - (s.point + s.distance * s.normal)).norm(), 1e-12) << toString(type);
    }
  }
}

TEST(Collider, PlaneDistanceIsSignedAlongItsUnitNormal) {
  const Collider c = Collider::fromParams(shape(Collider::Type::Plane), 0.3);
  const Vec3 n = Vec3(0.2, -0.3, 1.0).normalized();
  const Pose pose = c.scenePose();
  const Vec3 p(0.4, -1.0, 2.0);
  const SurfacePoint s = c.closest(p, pose);
  EXPECT_NEAR(s.distance, n.dot(p - Vec3(0.1, 0.2, -0.1)), 1e-15);
  EXPECT_LE((s.normal - n).norm(), 1e-15);
}

TEST(Collider, WorldQueryFollowsThePose) {
  // A rotated box: a point just above its rotated top face.
  const Collider c = Collider::fromParams(shape(Collider::Type::Box), 0.3);
  const Pose pose = c.scenePose();
  const Vec3 top = pose.rotation * Vec3(0, 0, 1);
  const Vec3 p = pose.translation + (0.1 + 0.05) * top;
  const SurfacePoint s = c.closest(p, pose);
  EXPECT_NEAR(s.distance, 0.05, 1e-12);
  EXPECT_LE((s.normal - top).norm(), 1e-12);
}

TEST(Collider, RpyIsRep103) {
  const Mat3 R = rotationFromRpy(Vec3(0.0, 0.0, M_PI / 2));  // yaw: x -> y
  EXPECT_LE((R * Vec3::UnitX() - Vec3::UnitY()).norm(), 1e-15);
  const Mat3 P = rotationFromRpy(Vec3(0.0, M_PI / 2, 0.0));  // pitch: z -> x
  EXPECT_LE((P * Vec3::UnitZ() - Vec3::UnitX()).norm(), 1e-15);
}

TEST(SweptContact, FastPointDoesNotTunnelThroughAThinBox) {
  // 30 m/s at dt 1/30: 1 m in a step, through a 1 cm thick box; both ends are
  // well outside it, so only the swept test sees the crossing.
  ColliderParams p;
  p.type = ColliderParams::Type::Box;
  p.center = Vec3(0, 0, 0);
  p.half_extents = Vec3(0.5, 0.5, 0.005);
  const Collider box = Collider::fromParams(p, 0.3);
  const Pose pose = box.scenePose();
  const Vec3 p0(0.1, 0.0, 0.5), p1(0.1, 0.0, -0.5);
  EXPECT_GT(box.closest(p0, pose).distance, 0.4);
  EXPECT_GT(box.closest(p1, pose).distance, 0.4);
  const auto hit = firstContact(box, pose, pose, p0, p1, 0.002, 1e-10);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->t, (0.5 - 0.007) / 1.0, 1e-9);  // first touch of the top face + thickness
  EXPECT_LE((hit->local.normal - Vec3::UnitZ()).norm(), 1e-12);
  // A path beside the box touches nothing.
  EXPECT_FALSE(firstContact(box, pose, pose, Vec3(0.6, 0, 0.5), Vec3(0.6, 0, -0.5), 0.002, 1e-10));
}

TEST(SweptContact, MovingColliderSweepsThroughAStillPoint) {
  ColliderParams p;
  p.type = ColliderParams::Type::Sphere;
  p.center = Vec3::Zero();
  p.radius = 0.05;
  const Collider ball = Collider::fromParams(p, 0.3);
  Pose start, end;
  start.translation = Vec3(-1, 0, 0);
  end.translation = Vec3(1, 0, 0);
  const auto hit = firstContact(ball, start, end, Vec3::Zero(), Vec3::Zero(), 0.0, 1e-10);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(hit->t, (1.0 - 0.05) / 2.0, 1e-9);
  EXPECT_LE((hit->local.normal - Vec3::UnitX()).norm(), 1e-9);  // hit on its leading side
}

}  // namespace
}  // namespace cloth_sim
