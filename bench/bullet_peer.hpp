// The benchmark's peer: Bullet 3.24's implicit deformable solver
// (btDeformableMultiBodyDynamicsWorld + btDeformableMassSpringForce, double
// precision) given the same nodes, masses, pins, springs, gravity and damping
// as a cloth_sim Model. No collisions unless static boxes are given (the
// contact benchmark: Bullet's own node-rigid contact and friction against
// btBoxShape bodies of zero mass). Built only when CMake finds
// Bullet's float64 package (CLOTH_SIM_HAVE_BULLET); see bench/README.md for
// how each parameter maps and where Bullet's model differs from ours.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "cloth_sim/model.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {
namespace bench {

/// Bullet's solver knobs. Defaults are Bullet 3.24's own, except where noted.
struct BulletSettings {
  double dt = 1.0 / 240.0;  ///< s; each step() is exactly one internal Bullet step

  /// btDeformableBodySolver::m_maxNewtonIterations (Bullet 3.24 default: 1).
  /// One iteration is one linear solve about (x_n + h v_n, v_n).
  int newton_iterations = 1;
  /// btDeformableBodySolver::m_newtonTolerance (default 1e-4): Newton stops
  /// once ||h f - M dv||_2 < this (absolute, N*s), checked from the 2nd iteration.
  double newton_tolerance = 1e-4;

  /// btConjugateGradient::m_maxIterations (Bullet default 300).
  int cg_max_iterations = 300;
  /// btConjugateGradient::m_tolerance (Bullet default SIMD_EPSILON = 2.2e-16).
  /// CG stops when r.z < cg_tolerance * min(1, b.z0): a bound on the SQUARED
  /// residual, relative only while |b| < 1 (with 3.24's unset, i.e. identity,
  /// preconditioner).
  double cg_tolerance = 2.220446049250313e-16;

  /// btDeformableBodySolver::setLineSearch (Bullet default false).
  bool line_search = false;

  /// true: use btDeformableMassSpringForce itself. It has one elastic and one
  /// damping coefficient for all links (plus a second elastic one for links
  /// flagged bending), so it is accepted only when every spring group present
  /// shares the damping and stretch and shear share the stiffness. false
  /// (default): the same force with per-link coefficients (bullet_peer.cpp).
  /// Not with contact boxes: Bullet's class adds no effective mass
  /// (addScaledHessian) for the contact predictor, so its contact flings.
  bool stock_force = false;

  /// true: clamp the transverse stiffness k (1 - r/l)(I - u u^T) of a
  /// compressed link (l < r) at zero in the Newton system, as cloth_sim's
  /// solver.project_compression does; the force itself is unchanged. false
  /// (default): Bullet's exact, then indefinite, Hessian, as its own force
  /// has. Contact scenes need true: landing compresses links, and Bullet's CG
  /// stops at the first negative-curvature direction with a partial (on its
  /// first iteration: dv = right side) step, which flings the cloth.
  /// Not with stock_force (Bullet's class has no such option).
  bool project_compression = false;

  /// Contact only: btSparseSdf voxel size (m) of Bullet's node-rigid contact
  /// (btSoftBody::checkDeformableContact samples the collider's signed
  /// distance on this grid and interpolates trilinearly). Bullet's default,
  /// 0.25 m, rounds a box's edges by up to that much; 0.01 m is closer to the
  /// box the scene describes.
  double sdf_voxel = 0.01;
};

/// A static box for Bullet's own contact: a btBoxShape in a btRigidBody of
/// zero mass, at `center`, turned by `rotation`.
struct BulletBox {
  Vec3 center = Vec3::Zero();
  Vec3 half_extents = Vec3::Ones();
  Mat3 rotation = Mat3::Identity();
  double friction = 0.0;  ///< Coulomb mu: the rigid body's friction (the soft body's kDF is 1)
};

/// Colliders for the peer. Empty boxes and no self-collision: no collisions
/// of any kind (as before).
struct BulletContact {
  std::vector<BulletBox> boxes;
  /// The soft body's collision margin (m): nodes are kept this far outside
  /// the boxes (cloth_sim's contact.thickness). Replaced by self_thickness / 2
  /// when self_collision is on (Bullet has one margin per soft body).
  double margin = 0.0;

  /// Bullet 3.24's own cloth self-collision (the deformable world's VF_DD
  /// with setSelfCollision(true), on the model's triangles as btSoftBody
  /// faces): after the implicit solve, node-face pairs of non-adjacent faces
  /// closer than 2 x margin at the step's start get a repulsion impulse, then
  /// up to 5 rounds of node-face CCD re-apply those impulses. No edge-edge
  /// test, no fail-safe (bench/README.md, "Self-collision").
  bool self_collision = false;
  /// cloth_sim's self_collision.thickness: Bullet's face-node distance is
  /// 2 x margin, so the margin is set to half of it.
  double self_thickness = 0.0;
  /// Coulomb mu between layers. Bullet takes kDF x kDF for a self pair and
  /// kDF x the rigid's friction for a box, so kDF = sqrt(self_friction) and
  /// each box's friction is divided by it (a box with friction needs
  /// self_friction > 0).
  double self_friction = 0.0;
};

/// Work done inside Bullet, counted through the spring force's callbacks.
struct BulletWork {
  long steps = 0;
  long force_evaluations = 0;  ///< addScaledForces calls (prediction + Newton)
  long matrix_products = 0;    ///< system-matrix products (one per CG iteration + one per solve)
  long newton_solves = 0;      ///< linear solves (exact without line search)
  long cg_iterations() const { return matrix_products - newton_solves; }
};

class BulletPeer {
 public:
  /// Builds the Bullet world. x0 (and v0 if not empty) are 3n vectors; pinned
  /// nodes get zero inverse mass and stay where x0 puts them. Throws
  /// std::invalid_argument naming the field for anything Bullet cannot
  /// represent (air drag, bad sizes, stock_force with per-group coefficients,
  /// non-positive dt or iteration counts).
  BulletPeer(const Model& model, const VecX& x0, const std::vector<int>& pinned,
             const BulletSettings& settings, const VecX& v0 = VecX(),
             const BulletContact& contact = BulletContact());
  ~BulletPeer();
  BulletPeer(const BulletPeer&) = delete;
  BulletPeer& operator=(const BulletPeer&) = delete;

  /// Advances by settings().dt (one btDeformableMultiBodyDynamicsWorld step).
  void step();

  /// Scripted pins: a held node has zero inverse mass and moves at
  /// `velocity` (Bullet integrates x += h v for it, as for every node, and
  /// its projection keeps v); a released one gets its mass back and keeps
  /// its velocity. cloth_sim's move_pin and release events, stepped so that
  /// steps land on the events' times.
  void holdNode(int node, const Vec3& velocity);
  void releaseNode(int node);

  VecX positions() const;   ///< 3n
  VecX velocities() const;  ///< 3n
  double time() const { return time_; }
  long stepCount() const { return steps_; }
  int numNodes() const;
  const BulletSettings& settings() const { return settings_; }
  /// Counts since construction; only with the per-link force (else zeros).
  BulletWork work() const;
  /// Largest |rest length in Bullet - model rest length| (must stay 0: Bullet
  /// resets rest lengths from positions if its "update constants" flag is set).
  double restLengthDrift() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  BulletSettings settings_;
  std::vector<double> mass_;  ///< the model's node masses (release restores them)
  double time_ = 0.0;
  long steps_ = 0;
};

/// Why the stock btDeformableMassSpringForce cannot carry this model's
/// coefficients; empty if it can.
std::string stockForceLimitation(const Model& model);

}  // namespace bench
}  // namespace cloth_sim
