// Force of one spring and its 3x3 Jacobian blocks. Small free functions,
// tested against finite differences.
//
// For d = x_j - x_i, l = |d|, u = d / l, the force on node i is
//   f_i = k (l - L) u + damping,      f_j = -f_i.
// Damping: along_spring  c ((v_j - v_i).u) u,  relative_velocity  c (v_j - v_i).
// Jacobians are given as the 3x3 block K = df_i/dx_j (= -df_i/dx_i), and
// D = df_i/dv_j (= -df_i/dv_i); the full 6x6 is [[-K, K], [K, -K]].
#pragma once

#include <algorithm>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

struct SpringParams {
  double stiffness = 0.0;
  double damping = 0.0;
  double rest_length = 0.0;
  DampingModel damping_model = DampingModel::AlongSpring;
  /// Unit direction x_j - x_i in the rest layout: the axis used when the
  /// spring is crushed to (near) zero length, so it pushes apart along it.
  Vec3 rest_direction = Vec3::UnitX();
};

/// Below kDegenerateLength * max(L, 1 m) a spring's own direction is
/// numerically meaningless: the rest direction is used instead, so a collapsed
/// spring pushes apart along its rest axis and nothing becomes NaN.
constexpr double kDegenerateLength = 1e-9;

/// Whether a spring of rest length L stretched to length l is degenerate (see above).
inline bool isDegenerate(double l, double rest_length) {
  return !(l > kDegenerateLength * std::max(rest_length, 1.0));
}

/// The spring's unit axis: d / l, or its rest direction when degenerate.
inline Vec3 springDirection(const Vec3& d, double l, double rest_length,
                            const Vec3& rest_direction) {
  return isDegenerate(l, rest_length) ? rest_direction : Vec3(d / l);
}

/// Force on node i of a spring of length l along unit axis u (node j gets the
/// negative): k (l - L) u plus damping of the ends' relative velocity dv =
/// v_j - v_i, along the unit axis w (along_axis; newton holds w over a step,
/// else w = u) or whole. The whole-cloth loops (spring_sweeps.cpp) write the
/// same formula slot by slot, where it vectorises; Forces.MatchPerSpringReferenceSum
/// holds them to each other.
inline Vec3 springForceOnI(double stiffness, double damping, bool along_axis, double l,
                           double rest_length, const Vec3& u, const Vec3& dv, const Vec3& w) {
  Vec3 f = stiffness * (l - rest_length) * u;
  if (damping != 0.0) f += along_axis ? Vec3(damping * dv.dot(w) * w) : Vec3(damping * dv);
  return f;
}
inline Vec3 springForceOnI(double stiffness, double damping, bool along_axis, double l,
                           double rest_length, const Vec3& u, const Vec3& dv) {
  return springForceOnI(stiffness, damping, along_axis, l, rest_length, u, dv, u);
}

/// Unit axis of the spring (d / |d|, or rest_direction when degenerate) and |d|.
void springAxis(const Vec3& xi, const Vec3& xj, const SpringParams& p, Vec3* axis,
                double* length);

/// Force on node i (node j receives the negative).
Vec3 springForce(const Vec3& xi, const Vec3& xj, const Vec3& vi, const Vec3& vj,
                 const SpringParams& p);

/// Elastic energy 1/2 k (l - L)^2.
double springEnergy(const Vec3& xi, const Vec3& xj, const SpringParams& p);

struct SpringJacobian {
  Mat3 K;  ///< df_i/dx_j
  Mat3 D;  ///< df_i/dv_j
};

/// Analytic Jacobian. With project_compression the transverse term
/// k (1 - L/l)(I - u u^T) is clamped at zero when l < L, which keeps K
/// positive semi-definite (and so the system matrix SPD). The along-spring
/// damping's dependence on x is dropped in D's partner (as Baraff-Witkin do);
/// `include_damping_dx` adds it to K for exact Newton and FD tests.
SpringJacobian springJacobian(const Vec3& xi, const Vec3& xj, const Vec3& vi,
                              const Vec3& vj, const SpringParams& p,
                              bool project_compression,
                              bool include_damping_dx = false);

}  // namespace cloth_sim
