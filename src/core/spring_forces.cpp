#include "cloth_sim/spring_forces.hpp"

#include <algorithm>
#include <cmath>

namespace cloth_sim {

void springAxis(const Vec3& xi, const Vec3& xj, const SpringParams& p, Vec3* axis,
                double* length) {
  const Vec3 d = xj - xi;
  const double l = d.norm();
  *length = l;
  *axis = springDirection(d, l, p.rest_length, p.rest_direction);
}

Vec3 springForce(const Vec3& xi, const Vec3& xj, const Vec3& vi, const Vec3& vj,
                 const SpringParams& p) {
  Vec3 u;
  double l;
  springAxis(xi, xj, p, &u, &l);
  return springForceOnI(p.stiffness, p.damping, p.damping_model == DampingModel::AlongSpring, l,
                        p.rest_length, u, vj - vi);
}

double springEnergy(const Vec3& xi, const Vec3& xj, const SpringParams& p) {
  const double stretch = (xj - xi).norm() - p.rest_length;
  return 0.5 * p.stiffness * stretch * stretch;
}

SpringJacobian springJacobian(const Vec3& xi, const Vec3& xj, const Vec3& vi,
                              const Vec3& vj, const SpringParams& p,
                              bool project_compression, bool include_damping_dx) {
  Vec3 u;
  double l;
  springAxis(xi, xj, p, &u, &l);
  const bool degenerate = isDegenerate(l, p.rest_length);
  const Mat3 uu = u * u.transpose();
  const Mat3 transverse = Mat3::Identity() - uu;

  SpringJacobian J;
  J.K = p.stiffness * uu;
  if (!degenerate) {
    double t = 1.0 - p.rest_length / l;  // < 0 under compression
    if (project_compression) t = std::max(t, 0.0);
    J.K += p.stiffness * t * transverse;
  }
  if (p.damping_model == DampingModel::AlongSpring) {
    J.D = p.damping * uu;
    if (include_damping_dx && p.damping != 0.0 && !degenerate) {
      // d/dd of c (dv.u) u, with du/dd = (I - u u^T) / l.
      const Vec3 dv = vj - vi;
      J.K += p.damping / l * (u * (transverse * dv).transpose() + dv.dot(u) * transverse);
    }
  } else {
    J.D = p.damping * Mat3::Identity();
  }
  return J;
}

}  // namespace cloth_sim
