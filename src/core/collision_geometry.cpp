// Self-collision geometry: distances, additive CCD, triangle–triangle test.
// See collision_geometry.hpp for the contracts.
#include "cloth_sim/collision_geometry.hpp"

#include "cloth_sim/exact_predicates.hpp"

#include <algorithm>
#include <cmath>

namespace cloth_sim {
namespace {

double clamp01(double v) { return std::min(1.0, std::max(0.0, v)); }

/// Distance from p to segment ab; `s` its parameter along ab.
double pointSegmentDistance(const Vec3& p, const Vec3& a, const Vec3& b, double* s) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? clamp01((p - a).dot(ab) / len2) : 0.0;
  if (s) *s = t;
  return (p - (a + t * ab)).norm();
}

}  // namespace

double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                             Vec3* weights) {
  // Ericson, Real-Time Collision Detection §5.1.5: Voronoi regions of the
  // corners and edges, else the face.
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  Vec3 w;
  const double area2 = ab.cross(ac).squaredNorm();
  const double scale2 = std::max(ab.squaredNorm(), ac.squaredNorm());
  if (!(area2 > 1e-24 * scale2 * scale2)) {
    // Degenerate: the triangle is (at most) a segment; the closest of its
    // three edges is exact.
    double s0, s1, s2;
    const double d0 = pointSegmentDistance(p, a, b, &s0);
    const double d1 = pointSegmentDistance(p, b, c, &s1);
    const double d2 = pointSegmentDistance(p, a, c, &s2);
    if (d0 <= d1 && d0 <= d2) {
      w = Vec3(1 - s0, s0, 0);
    } else if (d1 <= d2) {
      w = Vec3(0, 1 - s1, s1);
    } else {
      w = Vec3(1 - s2, 0, s2);
    }
  } else {
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    const Vec3 bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    const Vec3 cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    const double vc = d1 * d4 - d3 * d2;
    const double vb = d5 * d2 - d1 * d6;
    const double va = d3 * d6 - d5 * d4;
    if (d1 <= 0 && d2 <= 0) {
      w = Vec3(1, 0, 0);
    } else if (d3 >= 0 && d4 <= d3) {
      w = Vec3(0, 1, 0);
    } else if (d6 >= 0 && d5 <= d6) {
      w = Vec3(0, 0, 1);
    } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
      const double v = d1 / (d1 - d3);
      w = Vec3(1 - v, v, 0);
    } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
      const double t = d2 / (d2 - d6);
      w = Vec3(1 - t, 0, t);
    } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
      const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
      w = Vec3(0, 1 - t, t);
    } else {
      const double denom = 1.0 / (va + vb + vc);
      const double v = vb * denom, t = vc * denom;
      w = Vec3(1 - v - t, v, t);
    }
  }
  if (weights) *weights = w;
  return (p - (w[0] * a + w[1] * b + w[2] * c)).norm();
}

double edgeEdgeDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1,
                        double* s_out, double* t_out) {
  // Ericson §5.1.9, with the (nearly) parallel case taken from the four
  // end-point distances: there the interior formula is ill-conditioned, and
  // a closest pair of parallel segments always includes an end point.
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0, t = 0;
  const double denom = a * e - std::pow(d1.dot(d2), 2);
  if (a > 0 && e > 0 && denom > 1e-12 * a * e) {
    const double b = d1.dot(d2), c = d1.dot(r);
    s = clamp01((b * f - c * e) / denom);
    t = (b * s + f) / e;
    if (t < 0) {
      t = 0;
      s = clamp01(-c / a);
    } else if (t > 1) {
      t = 1;
      s = clamp01((b - c) / a);
    }
  } else {
    double u;
    double best = pointSegmentDistance(p0, q0, q1, &u);
    s = 0, t = u;
    double d = pointSegmentDistance(p1, q0, q1, &u);
    if (d < best) best = d, s = 1, t = u;
    d = pointSegmentDistance(q0, p0, p1, &u);
    if (d < best) best = d, s = u, t = 0;
    d = pointSegmentDistance(q1, p0, p1, &u);
    if (d < best) best = d, s = u, t = 1;
  }
  if (s_out) *s_out = s;
  if (t_out) *t_out = t;
  return ((p0 + s * d1) - (q0 + t * d2)).norm();
}

namespace {

/// ACCD (Li et al. 2021, Alg. 1) for either primitive pair; `distance` gives
/// the pair's distance at given positions, `bound` the largest rate at which
/// it can close per unit t (sum of the two sides' largest relative speeds).
template <class Distance>
Impact additiveCcd(const std::array<Vec3, 4>& x0, const std::array<Vec3, 4>& x1,
                   double separation, int max_iterations, bool point_triangle,
                   Distance distance) {
  // The first advance leaves at least 10 % of the start gap (as the paper);
  // a pair is reported once within 10 % of the separation above it. The
  // paper stops at 10 % of the start gap (a time of impact for a line
  // search); here "no hit" must mean "never below the separation", so a pair
  // sliding past at a safe distance is followed to the end instead.
  constexpr double kEta = kCcdReportSlack;
  std::array<Vec3, 4> p;
  Vec3 mean = Vec3::Zero();
  for (int i = 0; i < 4; ++i) mean += 0.25 * (x1[i] - x0[i]);
  for (int i = 0; i < 4; ++i) p[i] = x1[i] - x0[i] - mean;  // shared motion removed
  double lp;
  if (point_triangle) {
    lp = p[0].norm() + std::max({p[1].norm(), p[2].norm(), p[3].norm()});
  } else {
    lp = std::max(p[0].norm(), p[1].norm()) + std::max(p[2].norm(), p[3].norm());
  }
  double d = distance(x0);
  if (!(d > separation)) return Impact{true, 0.0};
  if (lp == 0.0) return Impact{false, 1.0};
  // (d^2 - s^2) / (d + s) = d - s, written as the paper does (no cancellation
  // issue here: both in double, d > s).
  const double gap = kEta * separation;
  double t = 0.0;
  double tl = (1.0 - kEta) * (d - separation) / lp;
  std::array<Vec3, 4> x;
  for (int it = 0; it < max_iterations; ++it) {
    const double t_next = t + tl;
    for (int i = 0; i < 4; ++i) x[i] = x0[i] + t_next * (x1[i] - x0[i]);
    d = distance(x);
    if (t > 0.0 && !(d - separation >= gap)) return Impact{true, t};
    t = t_next;
    if (t > 1.0) return Impact{false, 1.0};
    tl = (1.0 - kEta) * (d - separation) / lp;
  }
  return Impact{true, t};  // could not exclude a collision: say so
}

}  // namespace

Impact pointTriangleCcd(const std::array<Vec3, 4>& x0, const std::array<Vec3, 4>& x1,
                        double separation, int max_iterations) {
  return additiveCcd(x0, x1, separation, max_iterations, true, [](const std::array<Vec3, 4>& x) {
    return pointTriangleDistance(x[0], x[1], x[2], x[3]);
  });
}

Impact edgeEdgeCcd(const std::array<Vec3, 4>& x0, const std::array<Vec3, 4>& x1,
                   double separation, int max_iterations) {
  return additiveCcd(x0, x1, separation, max_iterations, false, [](const std::array<Vec3, 4>& x) {
    return edgeEdgeDistance(x[0], x[1], x[2], x[3]);
  });
}

// ------------------------------------------------ triangle–triangle ----
// Every sign below is exact (exact_predicates.hpp), so the answer is exact
// for non-degenerate triangles: touching counts as intersecting, and
// coplanar neighbours that only come close are not flagged.
namespace {

struct P2 {
  double x, y;
};

int orient(const P2& a, const P2& b, const P2& c) { return orient2d(a.x, a.y, b.x, b.y, c.x, c.y); }

bool onSegment2d(const P2& a, const P2& b, const P2& p) {  // p collinear with ab
  return std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) && std::min(a.y, b.y) <= p.y &&
         p.y <= std::max(a.y, b.y);
}

bool segmentsIntersect2d(const P2& a, const P2& b, const P2& c, const P2& d) {
  const int o1 = orient(a, b, c), o2 = orient(a, b, d);
  const int o3 = orient(c, d, a), o4 = orient(c, d, b);
  if (o1 != o2 && o3 != o4 && o1 * o2 <= 0 && o3 * o4 <= 0) return true;
  if (o1 == 0 && onSegment2d(a, b, c)) return true;
  if (o2 == 0 && onSegment2d(a, b, d)) return true;
  if (o3 == 0 && onSegment2d(c, d, a)) return true;
  if (o4 == 0 && onSegment2d(c, d, b)) return true;
  return false;
}

bool pointInTriangle2d(const P2& p, const P2& a, const P2& b, const P2& c) {
  const int s1 = orient(a, b, p), s2 = orient(b, c, p), s3 = orient(c, a, p);
  return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

/// Drops the coordinate axis along which triangle abc projects with the
/// largest area, chosen among the projections whose exact area is nonzero:
/// then the projection is one-to-one on abc's plane, and coplanar questions
/// keep their answers in 2D. `valid` is false for a degenerate triangle
/// (every projection exactly a segment or a point).
struct Projector {
  int u = 0, v = 1;
  bool valid = false;
  Projector(const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 n = (b - a).cross(c - a).cwiseAbs();  // rounded: only to rank the axes
    double best = -1.0;
    for (int drop = 0; drop < 3; ++drop) {
      const int i = (drop + 1) % 3, j = (drop + 2) % 3;
      if (orient2d(a[i], a[j], b[i], b[j], c[i], c[j]) != 0 && n[drop] > best) {
        best = n[drop], u = i, v = j, valid = true;
      }
    }
  }
  P2 operator()(const Vec3& p) const { return P2{p[u], p[v]}; }
};

/// Segment pq and non-degenerate triangle abc lying in one plane.
bool coplanarSegmentTriangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b,
                             const Vec3& c, const Projector& pr) {
  const P2 P = pr(p), Q = pr(q), A = pr(a), B = pr(b), C = pr(c);
  return pointInTriangle2d(P, A, B, C) || pointInTriangle2d(Q, A, B, C) ||
         segmentsIntersect2d(P, Q, A, B) || segmentsIntersect2d(P, Q, B, C) ||
         segmentsIntersect2d(P, Q, C, A);
}

/// Closed segment pq against closed non-degenerate triangle abc.
bool segmentTriangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c,
                     const Projector& abc) {
  const int sp = orient3d(a, b, c, p), sq = orient3d(a, b, c, q);
  if (sp * sq > 0) return false;
  if (sp == 0 && sq == 0) return coplanarSegmentTriangle(p, q, a, b, c, abc);
  // pq crosses the plane within pq (not lying in it): it meets the triangle
  // iff its line passes on one side of all three edges (Plücker signs),
  // zero meaning through an edge or a corner.
  const int s1 = orient3d(p, q, a, b), s2 = orient3d(p, q, b, c), s3 = orient3d(p, q, c, a);
  return (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
}

}  // namespace

bool trianglesIntersect(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0,
                        const Vec3& b1, const Vec3& b2) {
  const std::array<Vec3, 3> A = {a0, a1, a2}, B = {b0, b1, b2};
  // Disjoint boxes: exact (no arithmetic), and cheap.
  const Vec3 alo = a0.cwiseMin(a1).cwiseMin(a2), ahi = a0.cwiseMax(a1).cwiseMax(a2);
  const Vec3 blo = b0.cwiseMin(b1).cwiseMin(b2), bhi = b0.cwiseMax(b1).cwiseMax(b2);
  if ((ahi.array() < blo.array()).any() || (bhi.array() < alo.array()).any()) return false;
  const Projector pa(a0, a1, a2), pb(b0, b1, b2);
  if (!pa.valid && !pb.valid) {
    // Both degenerate (segments or points): their edges meet. The only case
    // decided by a rounded distance; a mesh's triangles are not collinear.
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (edgeEdgeDistance(A[i], A[(i + 1) % 3], B[j], B[(j + 1) % 3]) == 0.0) return true;
    return false;
  }
  // One degenerate: it is the union of its edges.
  if (!pa.valid || !pb.valid) {
    const auto& S = pa.valid ? B : A;
    const auto& T = pa.valid ? A : B;
    const Projector& pt = pa.valid ? pa : pb;
    for (int k = 0; k < 3; ++k)
      if (segmentTriangle(S[k], S[(k + 1) % 3], T[0], T[1], T[2], pt)) return true;
    return false;
  }
  // Quick reject: B wholly on one side of A's plane, or A of B's.
  const int sb0 = orient3d(a0, a1, a2, b0), sb1 = orient3d(a0, a1, a2, b1),
            sb2 = orient3d(a0, a1, a2, b2);
  if ((sb0 > 0 && sb1 > 0 && sb2 > 0) || (sb0 < 0 && sb1 < 0 && sb2 < 0)) return false;
  const int sa0 = orient3d(b0, b1, b2, a0), sa1 = orient3d(b0, b1, b2, a1),
            sa2 = orient3d(b0, b1, b2, a2);
  if ((sa0 > 0 && sa1 > 0 && sa2 > 0) || (sa0 < 0 && sa1 < 0 && sa2 < 0)) return false;
  if (sb0 == 0 && sb1 == 0 && sb2 == 0) {
    // Coplanar: an edge of one crosses the other, or one holds the other.
    for (int k = 0; k < 3; ++k) {
      if (coplanarSegmentTriangle(A[k], A[(k + 1) % 3], b0, b1, b2, pa)) return true;
    }
    const P2 P = pa(b0), Q = pa(a0), R = pa(a1), S = pa(a2);
    return pointInTriangle2d(P, Q, R, S);
  }
  // Not coplanar: the triangles' common part is a segment whose ends lie on
  // edges, so some edge of one meets the other.
  for (int k = 0; k < 3; ++k) {
    if (segmentTriangle(A[k], A[(k + 1) % 3], b0, b1, b2, pb)) return true;
    if (segmentTriangle(B[k], B[(k + 1) % 3], a0, a1, a2, pa)) return true;
  }
  return false;
}

}  // namespace cloth_sim
