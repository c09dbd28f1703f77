// Self-collision geometry against brute force (dense sampling, a second
// intersection algorithm) and hand cases, degenerate and parallel included.
#include <gtest/gtest.h>

#include <random>

#include "cloth_sim/collision_geometry.hpp"

namespace cloth_sim {
namespace {

Vec3 randomVec(std::mt19937& rng, double scale = 1.0) {
  std::uniform_real_distribution<double> u(-scale, scale);
  return Vec3(u(rng), u(rng), u(rng));
}

/// Smallest distance from p to sampled points of triangle abc (n per side).
double sampledPointTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, int n) {
  double best = 1e300;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; i + j <= n; ++j) {
      const double u = double(i) / n, v = double(j) / n;
      best = std::min(best, (p - ((1 - u - v) * a + u * b + v * c)).norm());
    }
  return best;
}

double sampledEdgeEdge(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, int n) {
  double best = 1e300;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) {
      const double s = double(i) / n, t = double(j) / n;
      best = std::min(best, ((p0 + s * (p1 - p0)) - (q0 + t * (q1 - q0))).norm());
    }
  return best;
}

TEST(CollisionGeometry, PointTriangleMatchesSampling) {
  std::mt19937 rng(1);
  const int n = 200;
  for (int trial = 0; trial < 300; ++trial) {
    const Vec3 a = randomVec(rng), b = randomVec(rng), p = randomVec(rng, 2.0);
    // Every 10th triangle degenerate: collinear corners.
    const Vec3 c = trial % 10 == 0 ? Vec3(a + 0.3 * (b - a)) : randomVec(rng);
    Vec3 w;
    const double d = pointTriangleDistance(p, a, b, c, &w);
    const double sampled = sampledPointTriangle(p, a, b, c, n);
    const double span = std::max({(a - b).norm(), (b - c).norm(), (a - c).norm()});
    EXPECT_LE(d, sampled + 1e-12) << trial;           // never above a point of the triangle
    EXPECT_GE(d, sampled - 2.0 * span / n) << trial;  // within the sampling resolution
    EXPECT_GE(w.minCoeff(), -1e-12);
    EXPECT_NEAR(w.sum(), 1.0, 1e-12);
    EXPECT_NEAR((p - (w[0] * a + w[1] * b + w[2] * c)).norm(), d, 1e-12);
  }
}

TEST(CollisionGeometry, PointTriangleHandCases) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  Vec3 w;
  EXPECT_DOUBLE_EQ(pointTriangleDistance(Vec3(0.25, 0.25, 0.5), a, b, c, &w), 0.5);
  EXPECT_TRUE(w.isApprox(Vec3(0.5, 0.25, 0.25)));
  EXPECT_DOUBLE_EQ(pointTriangleDistance(Vec3(-1, -1, 0), a, b, c, &w), std::sqrt(2.0));
  EXPECT_EQ(w, Vec3(1, 0, 0));
  EXPECT_DOUBLE_EQ(pointTriangleDistance(Vec3(1, 1, 0), a, b, c), std::sqrt(0.5));  // edge bc
  EXPECT_NEAR(pointTriangleDistance(Vec3(0.2, 0.2, 0), a, b, c), 0.0, 1e-15);    // inside
  // All three corners on one point: the distance to that point, finite weights.
  EXPECT_DOUBLE_EQ(pointTriangleDistance(Vec3(0, 0, 2), a, a, a, &w), 2.0);
  EXPECT_TRUE(w.allFinite());
}

TEST(CollisionGeometry, EdgeEdgeMatchesSamplingIncludingParallel) {
  std::mt19937 rng(2);
  const int n = 400;
  for (int trial = 0; trial < 300; ++trial) {
    const Vec3 p0 = randomVec(rng), p1 = randomVec(rng), q0 = randomVec(rng);
    Vec3 q1 = randomVec(rng);
    if (trial % 5 == 0) q1 = q0 + 0.7 * (p1 - p0);         // parallel
    if (trial % 5 == 1) q1 = q0 + 1e-9 * randomVec(rng);   // nearly a point
    if (trial % 5 == 2) q1 = q0 + (p1 - p0) + 1e-13 * randomVec(rng);  // nearly parallel
    double s, t;
    const double d = edgeEdgeDistance(p0, p1, q0, q1, &s, &t);
    const double sampled = sampledEdgeEdge(p0, p1, q0, q1, n);
    const double span = std::max((p1 - p0).norm(), (q1 - q0).norm());
    EXPECT_LE(d, sampled + 1e-12) << trial;
    EXPECT_GE(d, sampled - 2.0 * span / n) << trial;
    EXPECT_NEAR(((p0 + s * (p1 - p0)) - (q0 + t * (q1 - q0))).norm(), d, 1e-12);
  }
}

TEST(CollisionGeometry, EdgeEdgeHandCases) {
  // Crossing skew lines 1 apart; parallel collinear gap; zero-length edges.
  EXPECT_DOUBLE_EQ(edgeEdgeDistance(Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, -1, 1), Vec3(0, 1, 1)), 1.0);
  EXPECT_DOUBLE_EQ(edgeEdgeDistance(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(3, 0, 0)), 1.0);
  EXPECT_DOUBLE_EQ(edgeEdgeDistance(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 0, 0.5), Vec3(2, 0, 0.5)), 0.5);
  EXPECT_DOUBLE_EQ(edgeEdgeDistance(Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 3, 0), Vec3(0, 3, 0)), 3.0);
}

/// Brute force: the first sampled time the pair is closer than `sep`, or -1.
template <class Distance>
double firstSampledContact(const std::array<Vec3, 4>& x0, const std::array<Vec3, 4>& x1, double sep,
                           Distance distance, int samples, double* min_before = nullptr) {
  for (int k = 0; k <= samples; ++k) {
    const double t = double(k) / samples;
    std::array<Vec3, 4> x;
    for (int i = 0; i < 4; ++i) x[i] = x0[i] + t * (x1[i] - x0[i]);
    if (distance(x) < sep) return t;
  }
  (void)min_before;
  return -1.0;
}

template <class Ccd, class Distance>
void checkCcdAgainstSampling(Ccd ccd, Distance distance, unsigned seed) {
  std::mt19937 rng(seed);
  int hits = 0, misses = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::array<Vec3, 4> x0, x1;
    for (int i = 0; i < 4; ++i) {
      x0[i] = randomVec(rng);
      x1[i] = x0[i] + randomVec(rng, 1.5);
    }
    if (trial % 4 == 0) x1[3] = x1[2] + (x1[1] - x1[0]);  // parallel at the end (edge pairs)
    const double sep = 0.01;
    if (!(distance(x0) > sep)) continue;
    const Impact impact = ccd(x0, x1, sep);
    const double first = firstSampledContact(x0, x1, sep, distance, 4000);
    if (first >= 0.0) {
      // Never misses a contact, and never reports it after it happened.
      ASSERT_TRUE(impact.hit) << trial;
      EXPECT_LE(impact.toi, first) << trial;
      ++hits;
    } else {
      misses += !impact.hit;
    }
    if (impact.hit) {
      // Conservative: the pair is still at least `sep` apart up to toi.
      std::array<Vec3, 4> x;
      for (int k = 0; k <= 200; ++k) {
        const double t = impact.toi * k / 200.0;
        for (int i = 0; i < 4; ++i) x[i] = x0[i] + t * (x1[i] - x0[i]);
        EXPECT_GE(distance(x), sep * (1 - 1e-9)) << trial;
      }
    }
  }
  // Both outcomes occur, and "no contact" is reported where there is none
  // (a CCD that always says "hit" would pass the checks above).
  EXPECT_GT(hits, 10);
  EXPECT_GT(misses, 10);
}

TEST(CollisionGeometry, PointTriangleCcdNeverMissesAndIsConservative) {
  checkCcdAgainstSampling(
      [](const auto& x0, const auto& x1, double s) { return pointTriangleCcd(x0, x1, s); },
      [](const std::array<Vec3, 4>& x) { return pointTriangleDistance(x[0], x[1], x[2], x[3]); },
      3);
}

TEST(CollisionGeometry, EdgeEdgeCcdNeverMissesAndIsConservative) {
  checkCcdAgainstSampling(
      [](const auto& x0, const auto& x1, double s) { return edgeEdgeCcd(x0, x1, s); },
      [](const std::array<Vec3, 4>& x) { return edgeEdgeDistance(x[0], x[1], x[2], x[3]); }, 4);
}

TEST(CollisionGeometry, CcdHandCases) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // A point dropping through the triangle's middle at 1 (from z = 0.5 to -0.5).
  Impact hit = pointTriangleCcd({Vec3(0.2, 0.2, 0.5), a, b, c}, {Vec3(0.2, 0.2, -0.5), a, b, c}, 1e-3);
  ASSERT_TRUE(hit.hit);
  EXPECT_LE(hit.toi, 0.5 - 1e-3);
  EXPECT_GT(hit.toi, 0.49);  // not absurdly early: within 1.1 x separation
  // The same point moving beside the triangle, parallel to it: no hit.
  hit = pointTriangleCcd({Vec3(-0.5, 0.2, 0.1), a, b, c}, {Vec3(1.5, 0.2, 0.1), a, b, c}, 1e-3);
  EXPECT_FALSE(hit.hit);
  // The whole pair translating together: no relative motion, no hit.
  const Vec3 d(3, 1, -2);
  hit = pointTriangleCcd({Vec3(0.2, 0.2, 0.01), a, b, c}, {Vec3(0.2, 0.2, 0.01) + d, a + d, b + d, c + d}, 1e-3);
  EXPECT_FALSE(hit.hit);
  // Starting closer than the separation: hit at 0.
  hit = pointTriangleCcd({Vec3(0.2, 0.2, 1e-4), a, b, c}, {Vec3(0.2, 0.2, 1), a, b, c}, 1e-3);
  EXPECT_TRUE(hit.hit);
  EXPECT_EQ(hit.toi, 0.0);
  // Two edges crossing at right angles, one passing through the other.
  hit = edgeEdgeCcd({Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, -1, 1), Vec3(0, 1, 1)},
                    {Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, -1, -1), Vec3(0, 1, -1)}, 1e-3);
  ASSERT_TRUE(hit.hit);
  EXPECT_LE(hit.toi, 0.5);
  // Parallel edges sliding along each other 0.1 apart: no hit.
  hit = edgeEdgeCcd({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(-2, 0, 0.1), Vec3(-1, 0, 0.1)},
                    {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0.1), Vec3(3, 0, 0.1)}, 1e-3);
  EXPECT_FALSE(hit.hit);
}

TEST(CollisionGeometry, TrianglesIntersectHandCases) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // Piercing, above, touching at a corner, an edge lying across the face.
  EXPECT_TRUE(trianglesIntersect(a, b, c, Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 1), Vec3(2, 2, 0.5)));
  EXPECT_FALSE(trianglesIntersect(a, b, c, Vec3(0, 0, 1e-9), Vec3(1, 0, 1e-9), Vec3(0, 1, 1e-9)));
  EXPECT_TRUE(trianglesIntersect(a, b, c, Vec3(1, 0, 0), Vec3(2, 0, 1), Vec3(2, 1, 1)));
  EXPECT_TRUE(trianglesIntersect(a, b, c, Vec3(-1, 0.2, 0), Vec3(2, 0.2, 0), Vec3(0, 0.2, 1)));
  // Coplanar: overlapping, disjoint, one inside the other.
  EXPECT_TRUE(trianglesIntersect(a, b, c, Vec3(0.5, 0.5, 0), Vec3(-0.5, 0.5, 0), Vec3(0.5, -0.5, 0)));
  EXPECT_FALSE(trianglesIntersect(a, b, c, Vec3(2, 2, 0), Vec3(3, 2, 0), Vec3(2, 3, 0)));
  EXPECT_TRUE(trianglesIntersect(a, b, c, Vec3(0.1, 0.1, 0), Vec3(0.2, 0.1, 0), Vec3(0.1, 0.2, 0)));
  // Two cloth-like layers 1e-6 apart, and the same with one corner poked through.
  EXPECT_FALSE(trianglesIntersect(a, b, c, Vec3(0.1, 0.1, 1e-6), Vec3(0.9, 0.05, 1e-6), Vec3(0.05, 0.9, 1e-6)));
  EXPECT_TRUE(trianglesIntersect(a, b, c, Vec3(0.1, 0.1, -1e-6), Vec3(0.9, 0.05, 1e-6), Vec3(0.05, 0.9, 1e-6)));
}

/// Möller–Trumbore segment against triangle (a different algorithm).
bool segmentHitsTriangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 dir = q - p, e1 = b - a, e2 = c - a, h = dir.cross(e2);
  const double det = e1.dot(h);
  if (std::abs(det) < 1e-14) return false;
  const Vec3 s = p - a;
  const double u = s.dot(h) / det;
  const Vec3 qv = s.cross(e1);
  const double v = dir.dot(qv) / det, t = e2.dot(qv) / det;
  return u >= 0 && v >= 0 && u + v <= 1 && t >= 0 && t <= 1;
}

TEST(CollisionGeometry, TrianglesIntersectMatchesSegmentTests) {
  std::mt19937 rng(5);
  int yes = 0;
  for (int trial = 0; trial < 5000; ++trial) {
    std::array<Vec3, 3> A, B;
    for (auto& v : A) v = randomVec(rng);
    for (auto& v : B) v = randomVec(rng) + Vec3(0.5, 0, 0);
    bool brute = false;
    for (int k = 0; k < 3; ++k) {
      brute = brute || segmentHitsTriangle(A[k], A[(k + 1) % 3], B[0], B[1], B[2]) ||
              segmentHitsTriangle(B[k], B[(k + 1) % 3], A[0], A[1], A[2]);
    }
    EXPECT_EQ(trianglesIntersect(A[0], A[1], A[2], B[0], B[1], B[2]), brute) << trial;
    yes += brute;
  }
  EXPECT_GT(yes, 500);
  EXPECT_LT(yes, 4500);
}

}  // namespace
}  // namespace cloth_sim
