#include "cloth_sim/forces.hpp"

#include <algorithm>

namespace cloth_sim {

SpringParams springParams(const Model& model, const Spring& s) {
  const SpringGroup& g = model.groups[static_cast<int>(s.type)];
  SpringParams p;
  p.stiffness = g.stiffness;
  p.damping = g.damping;
  p.rest_length = s.rest_length;
  p.damping_model = model.damping_model;
  p.rest_direction = s.rest_direction;
  return p;
}

namespace {

void addExternalForces(const Model& model, const VecX& v, VecX& f) {
  const int n = model.numNodes();
  if (model.has_gravity) {
    for (int i = 0; i < n; ++i) f.segment<3>(3 * i) = model.mass[i] * model.gravity;
  } else {
    f.setZero();
  }
  if (model.air_drag > 0.0) f.noalias() -= model.air_drag * v;
}

}  // namespace

void computeForces(const Model& model, const VecX& x, const VecX& v, VecX& f) {
  f.resize(x.size());
  addExternalForces(model, v, f);
  for (const Spring& s : model.springs) {
    const Vec3 fi = springForce(x.segment<3>(3 * s.i), x.segment<3>(3 * s.j),
                                v.segment<3>(3 * s.i), v.segment<3>(3 * s.j),
                                springParams(model, s));
    f.segment<3>(3 * s.i) += fi;
    f.segment<3>(3 * s.j) -= fi;
  }
}

void assembleSystem(const Model& model, const VecX& x, const VecX& v, double a, double b,
                    bool project_compression, SystemMatrix& A, VecX& f, const VecX* w,
                    VecX* dfdx_w) {
  const int n = model.numNodes();
  A.resize(n, static_cast<int>(model.springs.size()));
  A.reset(model.mass);
  if (model.air_drag > 0.0) {
    for (int i = 0; i < n; ++i) A.diag(i) += a * model.air_drag * Mat3::Identity();
  }
  f.resize(x.size());
  addExternalForces(model, v, f);
  if (dfdx_w) dfdx_w->setZero(x.size());
  for (size_t k = 0; k < model.springs.size(); ++k) {
    const Spring& s = model.springs[k];
    const Vec3 xi = x.segment<3>(3 * s.i), xj = x.segment<3>(3 * s.j);
    const Vec3 vi = v.segment<3>(3 * s.i), vj = v.segment<3>(3 * s.j);
    const SpringParams p = springParams(model, s);
    const Vec3 fi = springForce(xi, xj, vi, vj, p);
    f.segment<3>(3 * s.i) += fi;
    f.segment<3>(3 * s.j) -= fi;
    const SpringJacobian J = springJacobian(xi, xj, vi, vj, p, project_compression);
    A.coupling(static_cast<int>(k)) = a * J.D + b * J.K;
    if (dfdx_w) {
      const Vec3 t = J.K * (w->segment<3>(3 * s.j) - w->segment<3>(3 * s.i));
      dfdx_w->segment<3>(3 * s.i) += t;
      dfdx_w->segment<3>(3 * s.j) -= t;
    }
  }
  A.accumulateDiagonal(model.springs);
}

double kineticEnergy(const Model& model, const VecX& v) {
  double e = 0.0;
  for (int i = 0; i < model.numNodes(); ++i) e += 0.5 * model.mass[i] * v.segment<3>(3 * i).squaredNorm();
  return e;
}

double elasticEnergy(const Model& model, const VecX& x) {
  double e = 0.0;
  for (const Spring& s : model.springs) {
    e += springEnergy(x.segment<3>(3 * s.i), x.segment<3>(3 * s.j), springParams(model, s));
  }
  return e;
}

double gravityEnergy(const Model& model, const VecX& x) {
  if (!model.has_gravity) return 0.0;
  double e = 0.0;
  for (int i = 0; i < model.numNodes(); ++i) e -= model.mass[i] * model.gravity.dot(x.segment<3>(3 * i));
  return e;
}

double maxStrain(const Model& model, const VecX& x) {
  double strain = 0.0;
  for (const Spring& s : model.springs) {
    strain = std::max(strain, (x.segment<3>(3 * s.j) - x.segment<3>(3 * s.i)).norm() / s.rest_length - 1.0);
  }
  return strain;
}

}  // namespace cloth_sim
