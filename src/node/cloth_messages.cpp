#include "cloth_messages.hpp"

#include <algorithm>
#include <cmath>

namespace cloth_sim_ros {

void TickStats::add(const cloth_sim::StepStats& s) {
  steps += s.substeps;
  cg_iterations += s.cg_iterations;
  residual = std::max(residual, s.residual);
  newton_iterations += s.newton_iterations;
  wall_time_s += s.wall_time_s;
  energy = s.energy;
  max_strain = s.max_strain;
  rejected += s.rejected;
  const bool step_ok = s.ok && s.finite;
  if (!step_ok && ok) {  // the first real failure outranks a recovery note
    failure = s.failure.empty() ? std::string("state became non-finite") : s.failure;
  } else if (failure.empty()) {
    failure = s.failure;
  }
  ok = ok && step_ok;
}

visualization_msgs::Marker triangleMarker(const std::string& frame_id, const std::string& ns,
                                          const std_msgs::ColorRGBA& color) {
  visualization_msgs::Marker m;
  m.header.frame_id = frame_id;
  m.ns = ns;
  m.id = 0;
  m.type = visualization_msgs::Marker::TRIANGLE_LIST;
  m.action = visualization_msgs::Marker::ADD;
  m.pose.orientation.w = 1.0;  // identity: points are in frame_id
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  m.color = color;
  m.frame_locked = false;
  return m;
}

void setTrianglePoints(const cloth_sim::Model& model, const cloth_sim::VecX& positions,
                       visualization_msgs::Marker* marker) {
  const size_t count = 3 * model.triangles.size();
  if (marker->points.size() != count) marker->points.resize(count);
  size_t k = 0;
  for (const Eigen::Vector3i& tri : model.triangles) {
    for (int corner = 0; corner < 3; ++corner, ++k) {
      const int node = tri[corner];
      geometry_msgs::Point& p = marker->points[k];
      p.x = positions[3 * node];
      p.y = positions[3 * node + 1];
      p.z = positions[3 * node + 2];
    }
  }
}

std_msgs::ColorRGBA strainColor(double strain) {
  double s = std::isfinite(strain) ? strain / kFullStrainColor : 1.0;
  s = std::min(1.0, std::max(0.0, s));
  std_msgs::ColorRGBA c;
  c.r = static_cast<float>(s);
  c.g = 0.0f;
  c.b = static_cast<float>(1.0 - s);
  c.a = 1.0f;
  return c;
}

void setStrainColors(const cloth_sim::Model& model, const std::vector<double>& node_strain,
                     visualization_msgs::Marker* marker) {
  const size_t count = 3 * model.triangles.size();
  if (marker->colors.size() != count) marker->colors.resize(count);
  size_t k = 0;
  for (const Eigen::Vector3i& tri : model.triangles) {
    for (int corner = 0; corner < 3; ++corner, ++k) {
      marker->colors[k] = strainColor(node_strain[tri[corner]]);
    }
  }
}

void fillClothState(const cloth_sim::Simulation& sim, cloth_sim::ClothState* msg) {
  const cloth_sim::Model& model = sim.model();
  const int n = model.numNodes();
  msg->rows = static_cast<uint32_t>(model.rows);
  msg->cols = static_cast<uint32_t>(model.cols);
  msg->positions.resize(n);
  msg->velocities.resize(n);
  const cloth_sim::VecX& x = sim.positions();
  const cloth_sim::VecX& v = sim.velocities();
  for (int i = 0; i < n; ++i) {
    msg->positions[i].x = x[3 * i];
    msg->positions[i].y = x[3 * i + 1];
    msg->positions[i].z = x[3 * i + 2];
    msg->velocities[i].x = v[3 * i];
    msg->velocities[i].y = v[3 * i + 1];
    msg->velocities[i].z = v[3 * i + 2];
  }
  const std::vector<int> pinned = sim.pinnedNodes();
  msg->pinned.assign(pinned.begin(), pinned.end());
  std::sort(msg->pinned.begin(), msg->pinned.end());
  msg->sim_time = sim.time();
}

void fillTickStats(const TickStats& tick, cloth_sim::ClothState* msg) {
  msg->steps = static_cast<uint32_t>(tick.steps);
  msg->dt = tick.dt;
  msg->cg_iterations = static_cast<uint32_t>(tick.cg_iterations);
  msg->residual = tick.residual;
  msg->newton_iterations = static_cast<uint32_t>(tick.newton_iterations);
  msg->step_time = tick.wall_time_s;
  msg->energy = tick.energy;
  msg->max_strain = tick.max_strain;
  msg->rejected = static_cast<uint32_t>(tick.rejected);
  msg->ok = tick.ok;
  msg->failure = tick.failure;
}

bool allFinite(const cloth_sim::VecX& values) { return values.allFinite(); }

}  // namespace cloth_sim_ros
