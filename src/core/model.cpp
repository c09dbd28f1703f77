#include "cloth_sim/model.hpp"

#include <algorithm>
#include <cstdlib>
#include <random>

namespace cloth_sim {

VecX gridPositions(const Scene& scene) {
  const auto& c = scene.cloth;
  const double dx = c.cols > 1 ? c.width / (c.cols - 1) : 0.0;
  const double dy = c.length / (c.rows - 1);
  VecX x(3 * c.rows * c.cols);
  for (int r = 0; r < c.rows; ++r) {
    for (int col = 0; col < c.cols; ++col) {
      // Horizontal: rows run along -y; vertical: rows hang along -z.
      const Vec3 offset = scene.cloth.plane == Plane::Horizontal
                              ? Vec3(col * dx, -r * dy, 0.0)
                              : Vec3(col * dx, 0.0, -r * dy);
      x.segment<3>(3 * (r * c.cols + col)) = c.origin + offset;
    }
  }
  return x;
}

namespace {

void addGroup(const Scene& scene, SpringType type, const VecX& x, Model* m) {
  const auto& params = scene.springs[static_cast<int>(type)];
  SpringGroup& g = m->groups[static_cast<int>(type)];
  g.present = params.enabled && params.stiffness > 0.0;
  g.stiffness = params.stiffness;
  g.damping = params.damping;
  g.begin = static_cast<int>(m->springs.size());
  if (g.present) {
    auto add = [&](int r0, int c0, int r1, int c1) {
      if (r1 < 0 || r1 >= m->rows || c1 < 0 || c1 >= m->cols) return;
      Spring s;
      s.i = m->index(r0, c0);
      s.j = m->index(r1, c1);
      const Vec3 d = x.segment<3>(3 * s.j) - x.segment<3>(3 * s.i);
      s.rest_length = d.norm();
      s.rest_direction = d / s.rest_length;
      s.type = type;
      g.rest_length_sq += s.rest_length * s.rest_length;
      m->springs.push_back(s);
    };
    for (int r = 0; r < m->rows; ++r) {
      for (int c = 0; c < m->cols; ++c) {
        switch (type) {
          case SpringType::Stretch:
            add(r, c, r, c + 1);
            add(r, c, r + 1, c);
            break;
          case SpringType::Shear:
            add(r, c, r + 1, c + 1);
            if (c + 1 < m->cols) add(r, c + 1, r + 1, c);
            break;
          case SpringType::Bend:
            add(r, c, r, c + 2);
            add(r, c, r + 2, c);
            break;
        }
      }
    }
  }
  g.end = static_cast<int>(m->springs.size());
}

}  // namespace

Model buildModel(const Scene& scene) {
  Model m;
  m.rows = scene.cloth.rows;
  m.cols = scene.cloth.cols;
  const int n = m.rows * m.cols;
  m.mass.assign(n, scene.cloth.mass / n);
  for (const auto& [index, mass] : scene.cloth.node_mass) m.mass[index] = mass;
  m.rest_positions = gridPositions(scene);
  for (int t = 0; t < kNumSpringTypes; ++t) {
    addGroup(scene, static_cast<SpringType>(t), m.rest_positions, &m);
  }
  m.layout = layOutSprings(n, m.springs);
  m.damping_model = scene.damping_model;
  m.gravity = scene.gravity;
  m.has_gravity = scene.gravity.squaredNorm() > 0.0;
  m.air_drag = scene.air_drag;
  for (int r = 0; r + 1 < m.rows; ++r) {
    for (int c = 0; c + 1 < m.cols; ++c) {
      const int a = m.index(r, c), b = m.index(r, c + 1);
      const int d = m.index(r + 1, c), e = m.index(r + 1, c + 1);
      // Counter-clockwise seen from +z for the horizontal layout.
      m.triangles.emplace_back(a, d, b);
      m.triangles.emplace_back(b, d, e);
    }
  }
  return m;
}

VecX initialPositions(const Scene& scene, const VecX& grid) {
  VecX x = grid;
  const int n = static_cast<int>(x.size() / 3);
  Vec3 centroid = Vec3::Zero();
  for (int i = 0; i < n; ++i) centroid += x.segment<3>(3 * i);
  centroid /= n;
  const auto& init = scene.initial;
  for (int i = 0; i < n; ++i) {
    auto xi = x.segment<3>(3 * i);
    if (init.collapse) {
      xi = centroid;
    } else if (init.stretch != 1.0) {
      xi = centroid + init.stretch * (xi - centroid);
    }
  }
  if (init.scatter > 0.0) {
    std::mt19937 rng(init.seed);
    std::uniform_real_distribution<double> offset(-0.5 * init.scatter, 0.5 * init.scatter);
    for (int k = 0; k < x.size(); ++k) x[k] += offset(rng);
  }
  return x;
}

int middleNode(const Spring& s, int n, int cols) {
  if (cols <= 0 || n % cols != 0) return -1;
  const int dr = s.j / cols - s.i / cols, dc = s.j % cols - s.i % cols;
  const bool two_lines = std::max(std::abs(dr), std::abs(dc)) == 2 && dr % 2 == 0 && dc % 2 == 0;
  return two_lines ? (s.i / cols + dr / 2) * cols + s.i % cols + dc / 2 : -1;
}

}  // namespace cloth_sim
