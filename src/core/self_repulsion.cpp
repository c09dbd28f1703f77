#include "cloth_sim/self_repulsion.hpp"

namespace cloth_sim {

namespace {

constexpr double kEps = SelfRepulsion::kFrictionSmoothing;

/// f1(y) / y, IPC's smoothed Coulomb sign over the speed: 2 / eps - y / eps^2
/// below eps, 1 / y above (finite at 0).
double dragPerSpeed(double y) { return y < kEps ? (2.0 - y / kEps) / kEps : 1.0 / y; }

/// f0(y), f0' = f1: y^2 / eps - y^3 / (3 eps^2) + eps / 3 below eps, y above.
double dissipation(double y) {
  return y < kEps ? y * y / kEps - y * y * y / (3.0 * kEps * kEps) + kEps / 3.0 : y;
}

}  // namespace

double SelfRepulsion::energy(const VecX& x) const {
  double e = 0.0;
  for (const RepulsionTerm& t : terms_) {
    const double d = t.reach - t.gap(x);
    if (d > 0.0) e += 0.5 * t.stiffness * d * d;
  }
  return e;
}

double SelfRepulsion::frictionPotential(const VecX& v) const {
  double p = 0.0;
  for (const RepulsionTerm& t : terms_) {
    if (t.friction > 0.0) p += t.friction * dissipation(t.slip(v).norm());
  }
  return p;
}

void SelfRepulsion::addForces(const VecX& x, const VecX& v, VecX& f) const {
  for (const RepulsionTerm& t : terms_) {
    const double d = t.reach - t.gap(x);
    Vec3 force = Vec3::Zero();  // on a node of weight 1
    if (d > 0.0) force = (t.stiffness * d) * t.n;
    if (t.friction > 0.0) {
      const Vec3 u = t.slip(v);
      force -= (t.friction * dragPerSpeed(u.norm())) * u;
    }
    for (int k = 0; k < 4; ++k) f.segment<3>(3 * t.node[k]) += t.w[k] * force;
  }
}

void SelfRepulsion::addToSystem(const VecX& x, const VecX& v, double a, double b, bool linearized,
                                SystemMatrix& A, VecX& f, const VecX* w, VecX* dfdx_w) const {
  const Mat3 I = Mat3::Identity();
  for (const RepulsionTerm& t : terms_) {
    const double d = t.reach - t.gap(x);
    const bool normal = linearized ? t.active : d > 0.0;
    if (!normal && t.friction == 0.0) continue;
    Vec3 force = Vec3::Zero();
    Mat3 B = Mat3::Zero();
    if (normal) {
      force = (t.stiffness * d) * t.n;
      B = (b * t.stiffness) * t.n * t.n.transpose();
      if (w && dfdx_w) {  // df/dx w = -k (w (x) n) ((w (x) n) . w)
        const double s = t.stiffness * t.gap(*w);
        for (int k = 0; k < 4; ++k) dfdx_w->segment<3>(3 * t.node[k]) -= (s * t.w[k]) * t.n;
      }
    }
    if (t.friction > 0.0) {
      const Vec3 u = t.slip(v);
      const double drag = t.friction * dragPerSpeed(u.norm());
      force -= drag * u;
      B += (a * drag) * (I - t.n * t.n.transpose());
    }
    for (int k = 0; k < 4; ++k) f.segment<3>(3 * t.node[k]) += t.w[k] * force;
    A.addPairTerm({t.node, t.w, SymBlock::from(B)});
  }
}

int SelfRepulsion::updateActiveSet(const VecX& x) {
  int changed = 0;
  for (RepulsionTerm& t : terms_) {
    const bool on = t.gap(x) < t.reach;
    changed += on != t.active;
    t.active = on;
  }
  return changed;
}

}  // namespace cloth_sim
