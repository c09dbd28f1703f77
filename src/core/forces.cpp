#include "cloth_sim/forces.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

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

void springAxes(const Model& model, const VecX& x, std::vector<Vec3>& axes) {
  axes.resize(model.springs.size());
  for (size_t k = 0; k < model.springs.size(); ++k) {
    const Spring& s = model.springs[k];
    const Vec3 d = x.segment<3>(3 * s.j) - x.segment<3>(3 * s.i);
    axes[k] = springDirection(d, d.norm(), s.rest_length, s.rest_direction);
  }
}

void computeForces(const Model& model, const VecX& x, const VecX& v, VecX& f,
                   const std::vector<Vec3>* damping_axes) {
  f.resize(x.size());
  addExternalForces(model, v, f);
  // springForce's arithmetic, inlined: no SpringParams copy per spring (the
  // Newton steppers call this several times a step); one loop per group, so
  // its constants and the damping branch are hoisted.
  const bool along = model.damping_model == DampingModel::AlongSpring;
  for (const SpringGroup& g : model.groups) {
    const double stiffness = g.stiffness, damping = g.damping;
    for (int k = g.begin; k < g.end; ++k) {
      const Spring& s = model.springs[k];
      const Vec3 d = x.segment<3>(3 * s.j) - x.segment<3>(3 * s.i);
      const double l = d.norm();
      const Vec3 u = springDirection(d, l, s.rest_length, s.rest_direction);
      const Vec3& axis = damping_axes ? (*damping_axes)[k] : u;
      const Vec3 fi = springForceOnI(stiffness, damping, along, l, s.rest_length, u,
                                     v.segment<3>(3 * s.j) - v.segment<3>(3 * s.i), axis);
      f.segment<3>(3 * s.i) += fi;
      f.segment<3>(3 * s.j) -= fi;
    }
  }
}

void assembleSystem(const Model& model, const VecX& x, const VecX& v, double a, double b,
                    bool project_compression, SystemMatrix& A, VecX& f, const VecX* w,
                    VecX* dfdx_w, const std::vector<Vec3>* damping_axes) {
  const int n = model.numNodes();
  A.resize(n, static_cast<int>(model.springs.size()));
  A.reset(model.mass, a * model.air_drag);
  f.resize(x.size());
  addExternalForces(model, v, f);
  if (dfdx_w) dfdx_w->setZero(x.size());
  // Force and Jacobian share the axis: one pass, one sqrt per spring; one
  // loop per group (its constants hoisted).
  const bool along = model.damping_model == DampingModel::AlongSpring;
  const bool held = along && damping_axes;
  for (const SpringGroup& g : model.groups) {
    const double stiffness = g.stiffness, damping = g.damping;
    // Damping adds a h c along the axis (held: along its own axis, below)
    // or isotropically.
    const double damping_axis = along && !held ? a * damping : 0.0,
                 damping_iso = along ? 0.0 : a * damping;
    for (int k = g.begin; k < g.end; ++k) {
      const Spring& s = model.springs[k];
      const Vec3 d = x.segment<3>(3 * s.j) - x.segment<3>(3 * s.i);
      const double l = d.norm();
      const bool degenerate = isDegenerate(l, s.rest_length);
      const Vec3 u = springDirection(d, l, s.rest_length, s.rest_direction);
      // K = k (1 - t) u u^T + k t I with t = 1 - L/l (clamped at 0 under
      // compression when projecting; 0 when degenerate): kept as two scalars,
      // so S = b K (+ damping) is one outer product and a diagonal shift.
      double t = degenerate ? 0.0 : 1.0 - s.rest_length / l;
      if (project_compression) t = std::max(t, 0.0);
      const double k_iso = stiffness * t, k_axis = stiffness - k_iso;
      const Vec3& axis = held ? (*damping_axes)[k] : u;
      const Vec3 fi = springForceOnI(stiffness, damping, along, l, s.rest_length, u,
                                     v.segment<3>(3 * s.j) - v.segment<3>(3 * s.i), axis);
      if (held) A.setDampingAxis(k, a * damping, axis);
      A.setCoupling(k, s.i, s.j, b * k_iso + damping_iso, b * k_axis + damping_axis, u);
      f.segment<3>(3 * s.i) += fi;
      f.segment<3>(3 * s.j) -= fi;
      if (dfdx_w) {
        const Vec3 dw = w->segment<3>(3 * s.j) - w->segment<3>(3 * s.i);
        const Vec3 kdw = k_iso * dw + (k_axis * u.dot(dw)) * u;
        dfdx_w->segment<3>(3 * s.i) += kdw;
        dfdx_w->segment<3>(3 * s.j) -= kdw;
      }
    }
  }
}

EnergyParts measureEnergy(const Model& model, const VecX& x, const VecX& v) {
  EnergyParts e;
  e.kinetic = kineticEnergy(model, v);
  e.potential = gravityEnergy(model, x);
  for (const SpringGroup& g : model.groups) {
    double sum = 0.0;  // sum of (l - L)^2 over the group
    for (int k = g.begin; k < g.end; ++k) {
      const Spring& s = model.springs[k];
      const double l = (x.segment<3>(3 * s.j) - x.segment<3>(3 * s.i)).norm();
      const double stretch = l - s.rest_length;
      sum += stretch * stretch;
      e.max_strain = std::max(e.max_strain, l / s.rest_length - 1.0);
    }
    e.elastic += 0.5 * g.stiffness * sum;
  }
  return e;
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

double springForceScale(const Model& model) {
  // Per group from its sum of L^2 (kept by buildModel): the Newton steppers
  // ask every step, and the springs never change.
  double sum = 0.0;
  for (const SpringGroup& g : model.groups) sum += g.stiffness * g.stiffness * g.rest_length_sq;
  return std::sqrt(sum);
}

namespace {

/// The node sums both round-off figures need, in one pass over the nodes.
struct RoundOffTerms {
  double momentum_sq = 0.0;  ///< sum m^2 |av|^2 = |M av|^2
  double mass_sq = 0.0;      ///< sum m^2
  double kinetic2 = 0.0;     ///< sum m |av|^2 = |av|_M^2
  double m_min = std::numeric_limits<double>::infinity();
};

RoundOffTerms roundOffTerms(const Model& model, const VecX& av) {
  RoundOffTerms t;
  for (int i = 0; i < model.numNodes(); ++i) {
    const double m = model.mass[i], v2 = av.segment<3>(3 * i).squaredNorm();
    t.momentum_sq += m * m * v2;
    t.mass_sq += m * m;
    t.kinetic2 += m * v2;
    t.m_min = std::min(t.m_min, m);
  }
  return t;
}

double residualRoundOff(const Model& model, double bh, const RoundOffTerms& t) {
  return 100.0 * std::numeric_limits<double>::epsilon() *
         (std::sqrt(t.momentum_sq) +
          bh * (std::sqrt(t.mass_sq * model.gravity.squaredNorm()) + springForceScale(model)));
}

}  // namespace

double residualRoundOff(const Model& model, double bh, const VecX& av) {
  return residualRoundOff(model, bh, roundOffTerms(model, av));
}

double energyRoundOff(const Model& model, double bh, const VecX& av) {
  const RoundOffTerms t = roundOffTerms(model, av);
  if (!(t.m_min > 0.0) || !std::isfinite(t.m_min)) return 0.0;  // no nodes, or massless
  const double r = residualRoundOff(model, bh, t);
  return std::sqrt(t.kinetic2 / t.m_min) * r + 0.5 * r * r / t.m_min;
}

}  // namespace cloth_sim
