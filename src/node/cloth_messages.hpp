// Messages built from core data. Free functions, no node state: the node and
// the tests use the same code to know what a message must contain.
#pragma once

#include <string>
#include <vector>

#include <geometry_msgs/TransformStamped.h>
#include <std_msgs/ColorRGBA.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include "cloth_sim/ClothState.h"
#include "cloth_sim/model.hpp"
#include "cloth_sim/simulation.hpp"
#include "cloth_sim/step_stats.hpp"

namespace cloth_sim_ros {

/// What one timer tick did: the StepStats of its solver steps, combined.
struct TickStats {
  int steps = 0;            ///< solver steps taken (sub-steps of recovery included)
  double dt = 0.0;          ///< step size the tick was divided into, s
  int cg_iterations = 0;    ///< summed
  double residual = 0.0;    ///< max
  int newton_iterations = 0;
  double wall_time_s = 0.0;
  double energy = 0.0;      ///< after the last step
  double max_strain = 0.0;  ///< after the last step
  int rejected = 0;         ///< attempts rolled back by recovery
  int error_rejected = 0;   ///< error-controlled steps redone smaller
  double h_min = 0.0, h_max = 0.0;  ///< step sizes taken, s
  int contacts = 0;         ///< nodes in contact after the last step
  double contact_normal_force = 0.0;  ///< after the last step, N
  int self_contacts = 0;    ///< self-collision pairs within the thickness after the last step
  bool ok = true;           ///< every step succeeded and stayed finite
  std::string failure;      ///< first failure, else what recovery fixed

  /// Adds one Simulation::step result.
  void add(const cloth_sim::StepStats& s);
};

/// A TRIANGLE_LIST marker with everything but points (and stamp) set:
/// ns, id 0, identity pose, scale 1, one colour.
visualization_msgs::Marker triangleMarker(const std::string& frame_id, const std::string& ns,
                                          const std_msgs::ColorRGBA& color);

/// Writes the model's triangles, three points each, into marker->points
/// (6 (rows-1)(cols-1) points; resized only when the count differs).
void setTrianglePoints(const cloth_sim::Model& model, const cloth_sim::VecX& positions,
                       visualization_msgs::Marker* marker);

/// RViz lights a TRIANGLE_LIST on its front side only (the winding's
/// normal): seen from the back, the cloth is black (a folded towel's upper
/// layer, upside down, showed as a black sheet). The underside marker is
/// each triangle wound the other way and moved this far along its back
/// normal, so from either side the face that is nearer is lit. Well below a
/// self-collision thickness (layers rest ~2 mm apart), above RViz's depth
/// resolution at a few metres (~0.05 mm).
constexpr double kUndersideOffset = 5e-4;  // m

/// Writes the model's triangles, wound the other way and each moved
/// kUndersideOffset along its back normal, into marker->points (as many
/// points as setTrianglePoints; a degenerate triangle is not moved).
void setUndersidePoints(const cloth_sim::Model& model, const cloth_sim::VecX& positions,
                        visualization_msgs::Marker* marker);

/// Strain colour: blue at rest length (or compressed), red at 10% stretch or more.
std_msgs::ColorRGBA strainColor(double strain);
/// Strain at which strainColor is fully red.
constexpr double kFullStrainColor = 0.10;

/// One colour per triangle vertex from per-node strain.
void setStrainColors(const cloth_sim::Model& model, const std::vector<double>& node_strain,
                     visualization_msgs::Marker* marker);

/// The ~colliders colour: a light grey-blue, slightly translucent.
std_msgs::ColorRGBA defaultColliderColor();

/// Side of the square CUBE that shows a plane collider, m.
constexpr double kPlaneMarkerSize = 4.0;
/// Thickness of that CUBE (its top face is the plane), m.
constexpr double kPlaneMarkerThickness = 0.01;

/// The colliders of `sim` where they are now, in `frame_id`: ns = collider
/// name, one marker per collider (plane: a large thin CUBE under the plane;
/// sphere: SPHERE; box: CUBE with its orientation) except a capsule, which is
/// a CYLINDER (id 0) and a SPHERE at each end (ids 1, 2).
void fillColliderMarkers(const cloth_sim::Simulation& sim, const std::string& frame_id,
                         const std_msgs::ColorRGBA& color, visualization_msgs::MarkerArray* out);

/// Fills a ClothState's cloth part: size, positions, velocities, pins, time.
void fillClothState(const cloth_sim::Simulation& sim, cloth_sim::ClothState* msg);

/// The ~cloth_frame transform: child_frame at the cloth's centre of mass
/// (mass-weighted mean of the node positions), axes those of frame_id. It
/// also puts frame_id into tf, so RViz finds its fixed frame when nothing
/// else (a gripper, a robot) publishes it.
geometry_msgs::TransformStamped clothFrame(const cloth_sim::Model& model,
                                           const cloth_sim::VecX& positions,
                                           const std::string& frame_id,
                                           const std::string& child_frame);
/// Fills a ClothState's statistics part from a tick.
void fillTickStats(const TickStats& tick, cloth_sim::ClothState* msg);

/// True if every coordinate is finite.
bool allFinite(const cloth_sim::VecX& values);

}  // namespace cloth_sim_ros
