// The discrete cloth: nodes, masses, springs (only the groups the scene has),
// triangles for rendering and export. Built once from a Scene.
#pragma once

#include <memory>
#include <vector>

#include "cloth_sim/scene.hpp"
#include "cloth_sim/spring_layout.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

struct Spring {
  int i = 0;              ///< first node
  int j = 0;              ///< second node
  double rest_length = 0; ///< from the initial (unstretched) layout
  SpringType type = SpringType::Stretch;
  Vec3 rest_direction = Vec3::UnitX();  ///< unit x_j - x_i in the grid layout
};

/// Stiffness and damping of one spring group (mutable at runtime).
struct SpringGroup {
  bool present = false;
  double stiffness = 0.0;
  double damping = 0.0;
  int begin = 0;  ///< springs [begin, end) of this group in Model::springs
  int end = 0;
  double rest_length_sq = 0.0;  ///< sum of the group's rest lengths squared (springForceScale)
};

struct Model {
  int rows = 0;
  int cols = 0;
  std::vector<double> mass;       ///< per node, kg
  std::vector<Spring> springs;    ///< grouped: all stretch, then shear, then bend
  std::array<SpringGroup, kNumSpringTypes> groups{};
  /// The springs by direction (spring_layout.hpp), shared by copies.
  std::shared_ptr<const SpringLayout> layout;
  DampingModel damping_model = DampingModel::AlongSpring;
  Vec3 gravity = Vec3::Zero();
  bool has_gravity = false;
  double air_drag = 0.0;
  std::vector<Eigen::Vector3i> triangles;  ///< two per cell, consistent winding
  VecX rest_positions;  ///< 3n, the grid layout (before `initial` edits)

  int numNodes() const { return static_cast<int>(mass.size()); }
  int index(int row, int col) const { return row * cols + col; }
};

/// Grid layout of the scene's cloth (3n vector, node i = row * cols + col).
VecX gridPositions(const Scene& scene);
/// Builds the model. Rest lengths come from gridPositions. Scene must be valid.
Model buildModel(const Scene& scene);
/// Applies the scene's `initial` edits (stretch, scatter, collapse) to positions.
VecX initialPositions(const Scene& scene, const VecX& grid);

/// The grid node halfway between a spring's ends when they are two grid
/// lines apart in a straight or diagonal line (a bend spring) on a grid of
/// n nodes with `cols` columns; -1 otherwise or without a grid (cols <= 0).
/// The multigrid and the Cholesky factor reroute such springs through it.
int middleNode(const Spring& s, int n, int cols);

}  // namespace cloth_sim
