// Geometric queries for self-collision, one function each (libigl style):
// closest distances with their closest points, a conservative continuous
// collision time over linear motion, and a triangle–triangle intersection
// test (used by the tests to check "no intersection"). Eigen only, no state.
#pragma once

#include <array>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// Closest point of triangle (a, b, c) to p.
/// Outputs: `weights` (wa, wb, wc), barycentric, >= 0, summing to 1, such that
/// the closest point is wa a + wb b + wc c. Returns the distance |p - q|.
/// A degenerate triangle (collinear or coincident corners) is treated as the
/// segment or point it is: never NaN.
double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                             Vec3* weights = nullptr);

/// Closest points of segments p0p1 and q0q1: p0 + s (p1 - p0) and
/// q0 + t (q1 - q0) with s, t in [0, 1]. Parallel and degenerate (zero-length)
/// segments give one of the closest pairs. Returns the distance.
double edgeEdgeDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1,
                        double* s = nullptr, double* t = nullptr);

/// Result of a continuous collision query over one step's linear motion.
struct Impact {
  bool hit = false;  ///< the distance may fall below the separation in [0, 1]
  double toi = 1.0;  ///< when hit: the distance is >= separation on [0, toi]
};

/// Additive CCD (Li et al. 2021, ACCD): the four points of a primitive pair
/// move linearly from `x0` to `x1` over t in [0, 1]; is there a t where their
/// distance drops below `separation` (> 0)? Conservative: advances t only by
/// steps the distance provably cannot close (distance change <= relative
/// displacement bound times dt), so it never misses a collision. It reports
/// a hit once the distance is within 1.1 x separation (toi: the last time
/// checked before that, so a lower bound of the contact time) or, after
/// `max_iterations` advances, report one it cannot exclude.
/// A pair that starts closer than `separation` reports hit at toi 0.
/// Point–triangle: x = {p, a, b, c}. Edge–edge: x = {p0, p1, q0, q1}.
/// The CCD reports a pair once its distance is within kCcdReportSlack x
/// separation above the separation (and advances by 1 - that of what it
/// may), after at most kCcdMaxIterations advances by default.
constexpr double kCcdReportSlack = 0.1;
constexpr int kCcdMaxIterations = 500;
Impact pointTriangleCcd(const std::array<Vec3, 4>& x0, const std::array<Vec3, 4>& x1,
                        double separation, int max_iterations = kCcdMaxIterations);
Impact edgeEdgeCcd(const std::array<Vec3, 4>& x0, const std::array<Vec3, 4>& x1,
                   double separation, int max_iterations = kCcdMaxIterations);

/// Do closed triangles (a0, a1, a2) and (b0, b1, b2) share at least one point?
/// Touching counts. Non-coplanar triangles intersect iff an edge of one meets
/// the other (the ends of their common segment lie on edges); coplanar ones
/// are tested in 2D (edge crossings, a corner inside the other). Orientation
/// signs are exact (exact_predicates.hpp), so the answer is exact; only two
/// degenerate (collinear) triangles are compared by a rounded distance.
bool trianglesIntersect(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0,
                        const Vec3& b1, const Vec3& b2);

}  // namespace cloth_sim
