#include "cloth_messages.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

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
  error_rejected += s.error_rejected;
  h_min = cloth_sim::smallerStep(h_min, s.h_min);
  h_max = std::max(h_max, s.h_max);
  contacts = s.contacts;
  contact_normal_force = s.contact_normal_force;
  self_contacts = s.self_contacts;
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

void setUndersidePoints(const cloth_sim::Model& model, const cloth_sim::VecX& positions,
                        visualization_msgs::Marker* marker) {
  const size_t count = 3 * model.triangles.size();
  if (marker->points.size() != count) marker->points.resize(count);
  size_t k = 0;
  for (const Eigen::Vector3i& tri : model.triangles) {
    const cloth_sim::Vec3 a = positions.segment<3>(3 * tri[0]);
    const cloth_sim::Vec3 b = positions.segment<3>(3 * tri[1]);
    const cloth_sim::Vec3 c = positions.segment<3>(3 * tri[2]);
    const cloth_sim::Vec3 normal = (b - a).cross(c - a);
    const double area2 = normal.norm();
    const cloth_sim::Vec3 shift =
        area2 > 0.0 ? cloth_sim::Vec3(normal * (-kUndersideOffset / area2)) : cloth_sim::Vec3::Zero();
    for (const cloth_sim::Vec3* corner : {&a, &c, &b}) {  // the other way round
      geometry_msgs::Point& p = marker->points[k++];
      p.x = (*corner)[0] + shift[0];
      p.y = (*corner)[1] + shift[1];
      p.z = (*corner)[2] + shift[2];
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

geometry_msgs::TransformStamped clothFrame(const cloth_sim::Model& model,
                                           const cloth_sim::VecX& positions,
                                           const std::string& frame_id,
                                           const std::string& child_frame) {
  geometry_msgs::TransformStamped t;
  t.header.frame_id = frame_id;
  t.child_frame_id = child_frame;
  cloth_sim::Vec3 sum = cloth_sim::Vec3::Zero();
  double mass = 0.0;
  for (int i = 0; i < model.numNodes(); ++i) {
    sum += model.mass[i] * positions.segment<3>(3 * i);
    mass += model.mass[i];
  }
  const cloth_sim::Vec3 centre = mass > 0.0 ? cloth_sim::Vec3(sum / mass) : cloth_sim::Vec3::Zero();
  t.transform.translation.x = centre.x();
  t.transform.translation.y = centre.y();
  t.transform.translation.z = centre.z();
  t.transform.rotation.w = 1.0;
  return t;
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
  msg->max_penetration = sim.maxPenetration();
  msg->min_self_distance = sim.minSelfDistance();
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
  msg->contacts = static_cast<uint32_t>(tick.contacts);
  msg->contact_normal_force = tick.contact_normal_force;
  msg->self_contacts = static_cast<uint32_t>(tick.self_contacts);
}

namespace {

geometry_msgs::Quaternion toQuaternion(const cloth_sim::Mat3& rotation) {
  const Eigen::Quaterniond q(rotation);
  geometry_msgs::Quaternion out;
  out.x = q.x();
  out.y = q.y();
  out.z = q.z();
  out.w = q.w();
  return out;
}

/// A rotation that takes +z to the unit vector `axis`.
cloth_sim::Mat3 zTo(const cloth_sim::Vec3& axis) {
  return Eigen::Quaterniond::FromTwoVectors(cloth_sim::Vec3::UnitZ(), axis).toRotationMatrix();
}

void setPosition(const cloth_sim::Vec3& p, visualization_msgs::Marker* m) {
  m->pose.position.x = p.x();
  m->pose.position.y = p.y();
  m->pose.position.z = p.z();
}

}  // namespace

std_msgs::ColorRGBA defaultColliderColor() {
  std_msgs::ColorRGBA c;
  c.r = 0.55f;
  c.g = 0.6f;
  c.b = 0.7f;
  c.a = 0.85f;
  return c;
}

void fillColliderMarkers(const cloth_sim::Simulation& sim, const std::string& frame_id,
                         const std_msgs::ColorRGBA& color, visualization_msgs::MarkerArray* out) {
  using cloth_sim::Vec3;
  using visualization_msgs::Marker;
  using Type = cloth_sim::Collider::Type;
  out->markers.clear();
  const std::vector<cloth_sim::Collider>& colliders = sim.colliders();
  for (size_t k = 0; k < colliders.size(); ++k) {
    const cloth_sim::Collider& c = colliders[k];
    const cloth_sim::Pose& pose = sim.colliderState(static_cast<int>(k)).pose;
    Marker m;
    m.header.frame_id = frame_id;
    m.ns = c.name().empty() ? "colliders[" + std::to_string(k) + "]" : c.name();
    m.id = 0;
    m.action = Marker::ADD;
    m.color = color;
    m.frame_locked = false;
    m.pose.orientation.w = 1.0;
    switch (c.type()) {
      case Type::Plane: {
        const Vec3 normal = (pose.rotation * c.planeNormal()).normalized();
        m.type = Marker::CUBE;
        setPosition(pose.translation - 0.5 * kPlaneMarkerThickness * normal, &m);
        m.pose.orientation = toQuaternion(zTo(normal));
        m.scale.x = m.scale.y = kPlaneMarkerSize;
        m.scale.z = kPlaneMarkerThickness;
        out->markers.push_back(m);
        break;
      }
      case Type::Sphere:
        m.type = Marker::SPHERE;
        setPosition(pose.translation, &m);
        m.scale.x = m.scale.y = m.scale.z = 2.0 * c.radius();
        out->markers.push_back(m);
        break;
      case Type::Box:
        m.type = Marker::CUBE;
        setPosition(pose.translation, &m);
        m.pose.orientation = toQuaternion(pose.rotation);
        m.scale.x = 2.0 * c.halfExtents().x();
        m.scale.y = 2.0 * c.halfExtents().y();
        m.scale.z = 2.0 * c.halfExtents().z();
        out->markers.push_back(m);
        break;
      case Type::Capsule: {
        const Vec3 a = pose.translation;
        const Vec3 b = pose.toWorld(c.segment());
        const double length = (b - a).norm();
        m.type = Marker::CYLINDER;
        setPosition(0.5 * (a + b), &m);
        m.pose.orientation =
            toQuaternion(length > 0.0 ? zTo((b - a) / length) : cloth_sim::Mat3::Identity());
        m.scale.x = m.scale.y = 2.0 * c.radius();
        m.scale.z = std::max(length, 1e-6);  // RViz refuses a zero scale
        out->markers.push_back(m);
        for (int end = 0; end < 2; ++end) {
          Marker cap = m;
          cap.id = 1 + end;
          cap.type = Marker::SPHERE;
          setPosition(end == 0 ? a : b, &cap);
          cap.pose.orientation = geometry_msgs::Quaternion();
          cap.pose.orientation.w = 1.0;
          cap.scale.x = cap.scale.y = cap.scale.z = 2.0 * c.radius();
          out->markers.push_back(cap);
        }
        break;
      }
    }
  }
}

bool allFinite(const cloth_sim::VecX& values) { return values.allFinite(); }

}  // namespace cloth_sim_ros
