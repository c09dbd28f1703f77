// Exact orientation signs for double inputs: a floating-point estimate with
// a forward error bound, and, only when the bound cannot decide the sign, an
// exact evaluation with expansion arithmetic (error-free two-sum and
// two-product, the idea of Shewchuk 1997; written here from the idea).
// Exact as long as no product of three coordinates underflows or overflows
// (|coordinates| within about 1e-90..1e90, or zero): true of any cloth.
#pragma once

#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// Sign of det[b - a, c - a, d - a] (rows): +1 if d lies on the side of the
/// plane abc that (b - a) x (c - a) points to, -1 on the other, 0 exactly on
/// it (or abc degenerate).
int orient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);

/// Sign of det[b - a, c - a] in the plane: +1 counter-clockwise abc, -1
/// clockwise, 0 collinear.
int orient2d(double ax, double ay, double bx, double by, double cx, double cy);

namespace exact_detail {
/// The exact stages alone (no filter), for the tests.
int orient3dExact(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
int orient2dExact(double ax, double ay, double bx, double by, double cx, double cy);
}  // namespace exact_detail

}  // namespace cloth_sim
