// Small scenes built in code for the core tests.
#pragma once

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

}  // namespace cloth_sim::test
