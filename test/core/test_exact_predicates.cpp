// Exact orientation predicates: right where a plain double evaluation is
// wrong (near-degenerate inputs), checked against exact integer arithmetic,
// and the filter agrees with the exact stage.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "cloth_sim/collision_geometry.hpp"
#include "cloth_sim/exact_predicates.hpp"

namespace cloth_sim {
namespace {

int sgn(double v) { return (v > 0) - (v < 0); }

/// The textbook evaluation in double, with a as the origin.
int naive3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return sgn((b - a).dot((c - a).cross(d - a)));
}
int naive2d(double ax, double ay, double bx, double by, double cx, double cy) {
  return sgn((bx - ax) * (cy - ay) - (by - ay) * (cx - ax));
}

TEST(ExactPredicates, PlainCases) {
  const Vec3 o(0, 0, 0), x(1, 0, 0), y(0, 1, 0), z(0, 0, 1);
  EXPECT_EQ(orient3d(o, x, y, z), 1);
  EXPECT_EQ(orient3d(o, y, x, z), -1);
  EXPECT_EQ(orient3d(o, x, y, Vec3(0.3, 0.7, 0)), 0);
  EXPECT_EQ(orient3d(o, x, 2 * x, z), 0);  // degenerate plane
  EXPECT_EQ(orient2d(0, 0, 1, 0, 0, 1), 1);
  EXPECT_EQ(orient2d(0, 0, 0, 1, 1, 0), -1);
  EXPECT_EQ(orient2d(0, 0, 1, 1, 3, 3), 0);
}

// Shewchuk's picture: a point 0.5 + (i, j) ulps against the line through
// (12, 12) and (24, 24). The exact sign is sign(j - i) (the determinant is
// 12 (ay - ax)); double evaluation gets a good part of the grid wrong.
TEST(ExactPredicates, Orient2dOnTheUlpGridNearALine) {
  const double ulp = std::ldexp(1.0, -53);  // spacing of doubles at 0.5
  int naive_wrong = 0;
  for (int i = 0; i < 256; ++i) {
    for (int j = 0; j < 256; ++j) {
      const double ax = 0.5 + i * ulp, ay = 0.5 + j * ulp;
      const int want = (j > i) - (j < i);
      ASSERT_EQ(orient2d(ax, ay, 12, 12, 24, 24), want) << i << " " << j;
      naive_wrong += naive2d(ax, ay, 12, 12, 24, 24) != want;
    }
  }
  EXPECT_GT(naive_wrong, 1000);  // the test is a real one
}

// The same in 3D: the plane x = y through (12,12,0), (24,24,0), (12,12,1);
// det[c - b, d - b, a - b] = 12 (ax - ay).
TEST(ExactPredicates, Orient3dOnTheUlpGridNearAPlane) {
  const double ulp = std::ldexp(1.0, -53);
  const Vec3 b(12, 12, 0), c(24, 24, 0), d(12, 12, 1);
  int naive_wrong = 0;
  for (int i = 0; i < 128; ++i) {
    for (int j = 0; j < 128; ++j) {
      const Vec3 a(0.5 + i * ulp, 0.5 + j * ulp, 0.5 + ((i * 7 + j * 3) % 64) * ulp);
      const int want = (i > j) - (i < j);
      ASSERT_EQ(orient3d(b, c, d, a), want) << i << " " << j;
      // The same determinant with its rows permuted evenly / oddly.
      ASSERT_EQ(orient3d(a, b, c, d), -want) << i << " " << j;
      ASSERT_EQ(orient3d(c, d, a, b), -want) << i << " " << j;
      naive_wrong += naive3d(b, c, d, a) != want || naive3d(a, b, c, d) != -want;
    }
  }
  EXPECT_GT(naive_wrong, 500);
}

/// Points (i 2^-26, j 2^-26, k 2^-56) with |i|, |j| <= 2^20, |k| < 2^52:
/// every term of the determinant has one z and two x/y factors, so it is
/// 2^-108 times an integer below 2^103 that __int128 holds exactly.
int referenceOrient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  using I = __int128;
  auto xy = [](double v) { return static_cast<I>(std::ldexp(v, 26)); };
  auto z = [](double v) { return static_cast<I>(std::ldexp(v, 56)); };
  const I ux = xy(b.x()) - xy(a.x()), uy = xy(b.y()) - xy(a.y()), uz = z(b.z()) - z(a.z());
  const I vx = xy(c.x()) - xy(a.x()), vy = xy(c.y()) - xy(a.y()), vz = z(c.z()) - z(a.z());
  const I wx = xy(d.x()) - xy(a.x()), wy = xy(d.y()) - xy(a.y()), wz = z(d.z()) - z(a.z());
  const I det = ux * (vy * wz - vz * wy) - uy * (vx * wz - vz * wx) + uz * (vx * wy - vy * wx);
  return (det > 0) - (det < 0);
}

// Random coplanar and nearly coplanar quadruples: points of the plane
// z = nx x + ny y with 30-bit slopes (exact in double, a zero that double
// evaluation mostly misses), half of them nudged off it by one unit of z.
TEST(ExactPredicates, Orient3dMatchesIntegerArithmeticNearCoplanar) {
  std::mt19937_64 rng(14);
  std::uniform_int_distribution<long> coord(-(1L << 20), 1L << 20), slope(-(1L << 30), 1L << 30);
  std::uniform_int_distribution<int> nudge(-1, 1);
  int naive_wrong = 0, zeros = 0;
  for (int trial = 0; trial < 200000; ++trial) {
    const long nx = slope(rng), ny = slope(rng);
    auto point = [&] {
      const long i = coord(rng), j = coord(rng);
      return Vec3(std::ldexp(i, -26), std::ldexp(j, -26), std::ldexp(double(nx * i + ny * j), -56));
    };
    const Vec3 a = point(), b = point(), c = point();
    Vec3 d = point();
    if (trial % 2) d.z() += std::ldexp(nudge(rng), -56);
    const int want = referenceOrient3d(a, b, c, d);
    ASSERT_EQ(orient3d(a, b, c, d), want) << trial;
    ASSERT_EQ(orient3d(b, c, a, d), want) << trial;
    ASSERT_EQ(exact_detail::orient3dExact(a, b, c, d), want) << trial;
    naive_wrong += naive3d(a, b, c, d) != want;
    zeros += want == 0;
  }
  EXPECT_GT(naive_wrong, 50000);  // the test is a real one
  EXPECT_GT(zeros, 50000);
}

// Arbitrary doubles (no grid): the filter's fast answers agree with the
// exact stage, and both with long double wherever long double is clear.
TEST(ExactPredicates, FilterAgreesWithExactStageOnRandomDoubles) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 100000; ++trial) {
    const Vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    // Half of them nearly on the plane (rounded combinations of a, b, c).
    Vec3 d(u(rng), u(rng), u(rng));
    if (trial % 2) d = a + d.x() * (b - a) + d.y() * (c - a);
    const int fast = orient3d(a, b, c, d), exact = exact_detail::orient3dExact(a, b, c, d);
    ASSERT_EQ(fast, exact) << trial;
    using L = long double;
    const L ux = L(b.x()) - a.x(), uy = L(b.y()) - a.y(), uz = L(b.z()) - a.z();
    const L vx = L(c.x()) - a.x(), vy = L(c.y()) - a.y(), vz = L(c.z()) - a.z();
    const L wx = L(d.x()) - a.x(), wy = L(d.y()) - a.y(), wz = L(d.z()) - a.z();
    const L det = ux * (vy * wz - vz * wy) - uy * (vx * wz - vz * wx) + uz * (vx * wy - vy * wx);
    if (std::abs(det) > 1e-15L) ASSERT_EQ(exact, det > 0 ? 1 : -1) << trial;
    const int f2 = orient2d(a.x(), a.y(), b.x(), b.y(), d.x(), d.y());
    ASSERT_EQ(f2, exact_detail::orient2dExact(a.x(), a.y(), b.x(), b.y(), d.x(), d.y())) << trial;
  }
}

// The cloth's own case: a strip between two rows of a folded grid lies
// exactly in one plane, (x, y_r, z_r) and (x, y_r+1, z_r+1), though no
// double evaluation of its normal is exact. Triangles of the strip that
// share no node must not count as intersecting; ones that touch must.
TEST(ExactPredicates, CoplanarStripTrianglesOfAFoldAreDecidedExactly) {
  const double ds = 0.3 / 11, r = 0.02;
  int checked = 0;
  for (int row = 0; row < 6; ++row) {
    const double p0 = 0.3 + 0.7 * row, p1 = p0 + ds / r;  // angles on the fold's arc
    const double y0 = -0.12 - r * std::sin(p0), z0 = 0.02 + r * (1 - std::cos(p0));
    const double y1 = -0.12 - r * std::sin(p1), z1 = 0.02 + r * (1 - std::cos(p1));
    auto at = [&](int col, int side) { return side ? Vec3(col * ds, y1, z1) : Vec3(col * ds, y0, z0); };
    for (int col = 0; col + 3 < 12; ++col) {
      // Two triangles of the strip one node apart, then touching at a corner.
      EXPECT_FALSE(trianglesIntersect(at(col, 0), at(col + 1, 0), at(col, 1), at(col + 2, 0),
                                      at(col + 3, 0), at(col + 2, 1)));
      EXPECT_FALSE(trianglesIntersect(at(col, 0), at(col + 1, 1), at(col, 1), at(col + 2, 0),
                                      at(col + 3, 1), at(col + 2, 1)));
      EXPECT_TRUE(trianglesIntersect(at(col, 0), at(col + 1, 0), at(col, 1), at(col + 1, 0),
                                     at(col + 3, 0), at(col + 2, 1)));
      checked += 3;
    }
  }
  EXPECT_EQ(checked, 6 * 9 * 3);
}

}  // namespace
}  // namespace cloth_sim
