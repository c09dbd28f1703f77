// Small scenes built in code for the core tests.
#pragma once

#include <optional>
#include <random>

#include "cloth_sim/collider.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/scene.hpp"

namespace cloth_sim::test {

/// A rows x cols cloth with no springs, no gravity, no pins: add what a test needs.
inline Scene bareScene(int rows, int cols) {
  Scene s;
  s.cloth.rows = rows;
  s.cloth.cols = cols;
  s.gravity = Vec3::Zero();
  s.solver.tolerance = 1e-12;
  s.solver.max_iterations = 1000;
  s.solver.newton_tolerance = 1e-12;
  return s;
}

/// The plane z = 0, normal +z, named "floor"; friction mu (absent: the
/// scene's contact default).
inline ColliderParams floorPlane(std::optional<double> mu = std::nullopt) {
  ColliderParams p;
  p.name = "floor";
  p.type = ColliderParams::Type::Plane;
  p.point = Vec3::Zero();
  p.normal = Vec3::UnitZ();
  p.friction = mu;
  return p;
}

/// The floor plane (friction mu), still over a step, for driving a
/// ContactSet by hand: exact stick/slip, or smoothed throughout (no exact
/// sticking) with a friction_smoothing > 0. Not copyable: `over` points at
/// `colliders`.
struct StillFloor {
  std::vector<Collider> colliders;
  CollidersOverStep over;
  StillFloor(double mu, double thickness, double friction_smoothing = 0.0)
      : colliders{Collider::fromParams(floorPlane(mu), mu)} {
    over.colliders = &colliders;
    over.start = over.end = {Pose{}};
    over.thickness = thickness;
    over.friction_smoothing = friction_smoothing;
    over.exact_sticking = false;
  }
  StillFloor(const StillFloor&) = delete;
  StillFloor& operator=(const StillFloor&) = delete;
};

inline void enable(Scene& s, SpringType type, double stiffness, double damping) {
  auto& g = s.springs[static_cast<int>(type)];
  g.enabled = true;
  g.stiffness = stiffness;
  g.damping = damping;
}

/// The demo-like cloth: stretch, shear, bend, gravity, two top corners pinned.
inline Scene hangingCloth(int n, Method method = Method::ImplicitEuler) {
  Scene s = bareScene(n, n);
  enable(s, SpringType::Stretch, 5000.0, 2.0);
  enable(s, SpringType::Shear, 500.0, 0.5);
  enable(s, SpringType::Bend, 5.0, 0.0);
  s.gravity = Vec3(0.0, 0.0, -9.81);
  s.pins = {0, n - 1};
  s.solver.method = method;
  s.solver.dt = 0.01;
  s.solver.tolerance = 1e-10;
  return s;
}

/// A random state near rest: every coordinate of x moved, and of v (and w, if
/// given) drawn, uniformly within 0.1 from `seed`; node 7 is then put on node 8,
/// so one spring has zero length (it must use its rest direction).
inline void perturbedState(const Model& m, unsigned seed, VecX* x, VecX* v, VecX* w = nullptr) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  *x = m.rest_positions;
  v->resize(x->size());
  if (w) w->resize(x->size());
  for (int k = 0; k < x->size(); ++k) {
    (*x)[k] += u(rng);
    (*v)[k] = u(rng);
    if (w) (*w)[k] = u(rng);
  }
  x->segment<3>(3 * 7) = x->segment<3>(3 * 8);
}

}  // namespace cloth_sim::test
