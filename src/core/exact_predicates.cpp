// Exact orientation predicates: filter, then expansion arithmetic.
// See exact_predicates.hpp. This file is compiled with -ffp-contract=off:
// the error-free transformations need every operation rounded on its own.
#include "cloth_sim/exact_predicates.hpp"

#include <cmath>
#include <limits>

namespace cloth_sim {
namespace {

constexpr double kEps = 0.5 * std::numeric_limits<double>::epsilon();  // 2^-53, unit round-off

/// Knuth's two-sum: s + err == a + b exactly, s = fl(a + b). Any order of
/// magnitudes.
inline void twoSum(double a, double b, double* s, double* err) {
  *s = a + b;
  const double bv = *s - a;
  const double av = *s - bv;
  *err = (a - av) + (b - bv);
}

/// p + err == a * b exactly (fma rounds once, so it yields the low part).
inline void twoProduct(double a, double b, double* p, double* err) {
  *p = a * b;
  *err = std::fma(a, b, -*p);
}

/// A sum of doubles held exactly as a nonoverlapping expansion: components
/// in increasing magnitude, zeros dropped, so the sign of the sum is the
/// sign of the last component.
class Expansion {
 public:
  /// Adds b exactly (grow-expansion with zero elimination).
  void add(double b) {
    double q = b;
    int m = 0;
    for (int i = 0; i < n_; ++i) {
      double s, err;
      twoSum(q, e_[i], &s, &err);
      q = s;
      if (err != 0.0) e_[m++] = err;  // m <= i: writes behind the reads
    }
    if (q != 0.0) e_[m++] = q;
    n_ = m;
  }
  /// Adds sign * x * y * z exactly: x y = p + q, then each part times z.
  void addProduct(double sign, double x, double y, double z) {
    double p, q, pp, pe, qp, qe;
    twoProduct(x, y, &p, &q);
    twoProduct(p, z, &pp, &pe);
    twoProduct(q, z, &qp, &qe);
    add(sign * pp), add(sign * pe), add(sign * qp), add(sign * qe);
  }
  void addProduct(double sign, double x, double y) {
    double p, q;
    twoProduct(x, y, &p, &q);
    add(sign * p), add(sign * q);
  }
  int sign() const { return n_ == 0 ? 0 : (e_[n_ - 1] > 0.0) - (e_[n_ - 1] < 0.0); }

 private:
  // Each add grows the expansion by at most one component: 24 triple
  // products of 4 parts each bound orient3d's.
  double e_[96];
  int n_ = 0;
};

/// det3(p, q, r) = p . (q x r), its six triple products added with `sign`.
void addDet3(Expansion* e, double sign, const Vec3& p, const Vec3& q, const Vec3& r) {
  e->addProduct(sign, p.x(), q.y(), r.z());
  e->addProduct(-sign, p.x(), q.z(), r.y());
  e->addProduct(sign, p.y(), q.z(), r.x());
  e->addProduct(-sign, p.y(), q.x(), r.z());
  e->addProduct(sign, p.z(), q.x(), r.y());
  e->addProduct(-sign, p.z(), q.y(), r.x());
}

/// out = p - q; true when no component was rounded.
bool exactDifference(const Vec3& p, const Vec3& q, Vec3* out) {
  bool exact = true;
  for (int i = 0; i < 3; ++i) {
    double err;
    twoSum(p[i], -q[i], &(*out)[i], &err);
    exact = exact && err == 0.0;
  }
  return exact;
}

int signOf(double v) { return (v > 0.0) - (v < 0.0); }

}  // namespace

namespace exact_detail {

int orient3dExact(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  Expansion e;
  // Nearby points (a mesh's) mostly have exact differences (Sterbenz): then
  // the 3x3 determinant of the differences, 6 triple products, is enough.
  Vec3 u, v, w;
  if (exactDifference(b, a, &u) && exactDifference(c, a, &v) && exactDifference(d, a, &w)) {
    addDet3(&e, 1.0, u, v, w);
    return e.sign();
  }
  // Otherwise det[b - a, c - a, d - a] is minus the 4x4 determinant of the
  // rows (p, 1); expanded along the column of ones it is a sum of 3x3
  // determinants of raw coordinates, so no difference needs rounding.
  addDet3(&e, 1.0, b, c, d);
  addDet3(&e, -1.0, a, c, d);
  addDet3(&e, 1.0, a, b, d);
  addDet3(&e, -1.0, a, b, c);
  return e.sign();
}

int orient2dExact(double ax, double ay, double bx, double by, double cx, double cy) {
  // (bx - ax)(cy - ay) - (by - ay)(cx - ax), multiplied out.
  Expansion e;
  e.addProduct(1.0, ax, by);
  e.addProduct(-1.0, ax, cy);
  e.addProduct(-1.0, ay, bx);
  e.addProduct(1.0, ay, cx);
  e.addProduct(1.0, bx, cy);
  e.addProduct(-1.0, by, cx);
  return e.sign();
}

}  // namespace exact_detail

int orient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const double ux = b.x() - a.x(), uy = b.y() - a.y(), uz = b.z() - a.z();
  const double vx = c.x() - a.x(), vy = c.y() - a.y(), vz = c.z() - a.z();
  const double wx = d.x() - a.x(), wy = d.y() - a.y(), wz = d.z() - a.z();
  const double p1 = vy * wz, p2 = vz * wy, p3 = vz * wx, p4 = vx * wz, p5 = vx * wy, p6 = vy * wx;
  const double det = ux * (p1 - p2) + uy * (p3 - p4) + uz * (p5 - p6);
  const double permanent = std::abs(ux) * (std::abs(p1) + std::abs(p2)) +
                           std::abs(uy) * (std::abs(p3) + std::abs(p4)) +
                           std::abs(uz) * (std::abs(p5) + std::abs(p6));
  // Shewchuk's forward bound for this evaluation is (7 + 56 eps) eps times
  // the permanent; 8 eps covers it. Below 1e-200 underflow could void it.
  const double bound = 8.0 * kEps * permanent;
  if (std::abs(det) > bound && permanent > 1e-200) return signOf(det);
  return exact_detail::orient3dExact(a, b, c, d);
}

int orient2d(double ax, double ay, double bx, double by, double cx, double cy) {
  const double left = (bx - ax) * (cy - ay), right = (by - ay) * (cx - ax);
  const double det = left - right;
  // Shewchuk's bound: (3 + 16 eps) eps (|left| + |right|).
  const double permanent = std::abs(left) + std::abs(right);
  if (std::abs(det) > 4.0 * kEps * permanent && permanent > 1e-200) return signOf(det);
  return exact_detail::orient2dExact(ax, ay, bx, by, cx, cy);
}

}  // namespace cloth_sim
