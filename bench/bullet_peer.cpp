// Bullet 3.24 peer: see bullet_peer.hpp and bench/README.md.
#include "bullet_peer.hpp"

#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableMassSpringForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

static_assert(sizeof(btScalar) == sizeof(double),
              "the Bullet peer needs Bullet's double-precision build (BT_USE_DOUBLE_PRECISION)");

namespace cloth_sim {
namespace bench {
namespace {

using TVStack = btAlignedObjectArray<btVector3>;

btVector3 toBt(const VecX& v, int node) {
  return btVector3(v[3 * node], v[3 * node + 1], v[3 * node + 2]);
}

/// btDeformableBodySolver keeps its Newton and CG settings protected; a
/// subclass is Bullet's intended way to reach them. Nothing else changes.
class TunedDeformableSolver : public btDeformableBodySolver {
 public:
  void configure(const BulletSettings& s) {
    m_maxNewtonIterations = s.newton_iterations;
    m_newtonTolerance = s.newton_tolerance;
    m_cg.m_maxIterations = s.cg_max_iterations;
    m_cg.setTolerance(s.cg_tolerance);
  }
};

/// btDeformableMassSpringForce with one elastic stiffness k and one damping
/// coefficient c per link instead of per force. Same formulas as Bullet 3.24's
/// force, term for term: elastic force k (d - r d^) at the Newton iterate
/// m_q, its exact Hessian (no compression clamp unless project_compression),
/// damping c (dv.d^) d^ with d^ taken at the step's start position m_x (or
/// c dv for relative_velocity), its velocity differential without the d^(x)
/// dependence. Also counts calls. Two additions Bullet's own force lacks, both
/// needed for contact (bench/README.md, "Contact"): addScaledHessian, and the
/// optional compression clamp.
class PerLinkMassSpringForce : public btDeformableMassSpringForce {
 public:
  PerLinkMassSpringForce(std::vector<btScalar> k, std::vector<btScalar> c, bool along_spring,
                         bool project_compression)
      : btDeformableMassSpringForce(0.0, 0.0, along_spring),
        k_(std::move(k)), c_(std::move(c)), along_spring_(along_spring),
        project_compression_(project_compression) {}

  void addScaledForces(btScalar scale, TVStack& force) override {
    ++work_.force_evaluations;
    awaiting_solve_ = true;
    addScaledDampingForce(scale, force);
    addScaledElasticForce(scale, force);
  }

  void addScaledExplicitForce(btScalar scale, TVStack& force) override {
    addScaledElasticForce(scale, force);
  }

  void addScaledDampingForce(btScalar scale, TVStack& force) override {
    forEachLink([&](const btSoftBody::Link& link, int j) {
      const btSoftBody::Node* a = link.m_n[0];
      const btSoftBody::Node* b = link.m_n[1];
      btVector3 f = dampingForce(a, b, b->m_v - a->m_v, scale * c_[j]);
      force[a->index] += f;
      force[b->index] -= f;
    });
  }

  void addScaledElasticForce(btScalar scale, TVStack& force) override {
    forEachLink([&](const btSoftBody::Link& link, int j) {
      const btSoftBody::Node* a = link.m_n[0];
      const btSoftBody::Node* b = link.m_n[1];
      btVector3 d = b->m_q - a->m_q;
      btScalar len = d.norm();
      btVector3 u = len > SIMD_EPSILON ? d / len : btVector3(0, 0, 0);
      btVector3 f = (d - u * link.m_rl) * (scale * k_[j]);
      force[a->index] += f;
      force[b->index] -= f;
    });
  }

  void addScaledDampingForceDifferential(btScalar scale, const TVStack& dv,
                                         TVStack& df) override {
    // Called once per product with the system matrix (CG iteration).
    ++work_.matrix_products;
    if (awaiting_solve_) {
      ++work_.newton_solves;
      awaiting_solve_ = false;
    }
    forEachLink([&](const btSoftBody::Link& link, int j) {
      const btSoftBody::Node* a = link.m_n[0];
      const btSoftBody::Node* b = link.m_n[1];
      btVector3 f = dampingForce(a, b, dv[b->index] - dv[a->index], c_[j] * scale);
      df[a->index] += f;
      df[b->index] -= f;
    });
  }

  void buildDampingForceDifferentialDiagonal(btScalar scale, TVStack& diag) override {
    // Only Bullet's KKT preconditioner asks for this.
    forEachLink([&](const btSoftBody::Link& link, int j) {
      const btSoftBody::Node* a = link.m_n[0];
      const btSoftBody::Node* b = link.m_n[1];
      btVector3 d = b->m_x - a->m_x;
      btVector3 w(1, 1, 1);
      if (along_spring_ && d.norm() > SIMD_EPSILON) {
        btVector3 u = d.normalized();
        w = u * u;
      }
      if (a->m_im > 0) diag[a->index] -= w * (scale * c_[j]);
      if (b->m_im > 0) diag[b->index] -= w * (scale * c_[j]);
    });
  }

  void addScaledElasticForceDifferential(btScalar scale, const TVStack& dx,
                                         TVStack& df) override {
    forEachLink([&](const btSoftBody::Link& link, int j) {
      const btSoftBody::Node* a = link.m_n[0];
      const btSoftBody::Node* b = link.m_n[1];
      btVector3 d = a->m_q - b->m_q;
      btScalar len = d.norm();
      if (len <= SIMD_EPSILON) return;
      btVector3 u = d / len;
      btVector3 ddx = dx[a->index] - dx[b->index];
      btScalar ks = scale * k_[j];
      btScalar slack = (len - link.m_rl) / len;
      // Compressed (len < r): the transverse term is negative and the system
      // matrix indefinite once h^2 k (r/len - 1) exceeds a node's mass; then
      // btConjugateGradient::solve stops at the first negative-curvature
      // direction with a partial dv (dv = its right side if on iteration 1).
      // project_compression clamps it at 0, as cloth_sim's option does.
      if (project_compression_ && slack < 0) slack = 0;
      btScalar along = u.dot(ddx);
      // -k [u u^T + (1 - r/l)(I - u u^T)] (dx_a - dx_b)
      btVector3 f = u * (-ks * along) + u * (ks * along * slack) - ddx * (ks * slack);
      df[a->index] += f;
      df[b->index] -= f;
    });
  }

  void addScaledHessian(btScalar scale) override {
    // Implicit mode's predictor, btDeformableBackwardEulerObjective::
    // applyExplicitForce: v* = v_n + M_eff^-1 h f(x_n + h v_n) (+ h g), with
    // M_eff = M plus what each force adds here (reset to M every step). The
    // node-rigid contact is detected and solved on v*, with M_eff as the
    // node's mass (CollideSDF_RD: m_c5 = m_effectiveMass_inv); then the
    // Newton solve keeps the velocity the contact solve gave each contact
    // node (projected directions). Bullet's mass-spring force adds nothing,
    // so v* is an explicit Euler step: unstable for drop32's springs at
    // h = 1/1000 s (not yet at 1/2000 s), and then a contact node's v* (and
    // the friction bound taken from its normal impulse) is garbage. Added here, as Bullet's
    // btDeformableLinearElasticityForce adds its own: each node's diagonal
    // block of the implicit system matrix, h c W + h^2 k [u u^T +
    // max(0, 1 - r/l)(I - u u^T)], which makes v* a block-Jacobi step of the
    // implicit solve. Free nodes' v* is discarded (setupDeformableSolve), so
    // runs without contact do not change.
    const btMatrix3x3 identity = btMatrix3x3::getIdentity();
    auto outer = [](const btVector3& u) {
      return btMatrix3x3(u[0] * u[0], u[0] * u[1], u[0] * u[2], u[1] * u[0], u[1] * u[1],
                         u[1] * u[2], u[2] * u[0], u[2] * u[1], u[2] * u[2]);
    };
    forEachLink([&](const btSoftBody::Link& link, int j) {
      btSoftBody::Node* a = link.m_n[0];
      btSoftBody::Node* b = link.m_n[1];
      btMatrix3x3 block;
      block.setZero();
      btVector3 d = b->m_q - a->m_q;
      btScalar len = d.norm();
      if (len > SIMD_EPSILON) {
        btMatrix3x3 uu = outer(d / len);
        btScalar slack = std::max<btScalar>(0.0, (len - link.m_rl) / len);
        block = (uu + (identity - uu) * slack) * (scale * scale * k_[j]);
      }
      btMatrix3x3 damping = identity;  // relative velocity: c I
      if (along_spring_) {             // along the spring at m_x: c d^ d^T
        btVector3 dx = b->m_x - a->m_x;
        if (dx.norm() > SIMD_EPSILON) {
          damping = outer(dx.normalized());
        } else {
          damping.setZero();
        }
      }
      block += damping * (scale * c_[j]);
      if (a->m_im > 0) a->m_effectiveMass += block;
      if (b->m_im > 0) b->m_effectiveMass += block;
    });
  }

  double totalElasticEnergy(btScalar) override {
    double energy = 0;
    forEachLink([&](const btSoftBody::Link& link, int j) {
      btScalar stretch = (link.m_n[1]->m_q - link.m_n[0]->m_q).norm() - link.m_rl;
      energy += 0.5 * k_[j] * stretch * stretch;
    });
    return energy;
  }

  double totalDampingEnergy(btScalar dt) override {
    // Bullet's line-search merit: -(1/2 f_damping . v) / dt.
    double energy = 0;
    forEachLink([&](const btSoftBody::Link& link, int j) {
      const btSoftBody::Node* a = link.m_n[0];
      const btSoftBody::Node* b = link.m_n[1];
      btVector3 f = dampingForce(a, b, b->m_v - a->m_v, 0.5 * c_[j]);
      energy -= (f.dot(a->m_v) - f.dot(b->m_v)) / dt;
    });
    return energy;
  }

  const BulletWork& work() const { return work_; }

 private:
  /// Damping force s dv, or along the link at m_x: (s dv.d^) d^. Products in
  /// Bullet's order, so that the stock and per-link forces agree to the bit.
  btVector3 dampingForce(const btSoftBody::Node* a, const btSoftBody::Node* b,
                         const btVector3& dv, btScalar s) const {
    if (along_spring_) {
      btVector3 d = b->m_x - a->m_x;
      if (d.norm() > SIMD_EPSILON) {
        btVector3 u = d.normalized();
        return s * dv.dot(u) * u;
      }
    }
    return s * dv;
  }

  template <class Fn>
  void forEachLink(Fn&& fn) {
    for (int s = 0; s < m_softBodies.size(); ++s) {
      btSoftBody* body = m_softBodies[s];
      if (!body->isActive()) continue;
      for (int j = 0; j < body->m_links.size(); ++j) fn(body->m_links[j], j);
    }
  }

  std::vector<btScalar> k_, c_;
  bool along_spring_;
  bool project_compression_;
  BulletWork work_;
  bool awaiting_solve_ = false;  ///< a residual was evaluated, no solve seen yet
};

void requireFinite(double value, const char* field) {
  if (!std::isfinite(value)) {
    throw std::invalid_argument(std::string(field) + ": must be finite");
  }
}

void validate(const Model& model, const VecX& x0, const VecX& v0,
              const std::vector<int>& pinned, const BulletSettings& s) {
  const int n = model.numNodes();
  auto fail = [](const std::string& msg) { throw std::invalid_argument(msg); };
  if (!(s.dt > 0) || !std::isfinite(s.dt)) fail("bullet.dt: must be > 0 and finite");
  if (s.newton_iterations < 1) fail("bullet.newton_iterations: must be >= 1");
  if (!(s.newton_tolerance >= 0)) fail("bullet.newton_tolerance: must be >= 0");
  if (s.cg_max_iterations < 1) fail("bullet.cg_max_iterations: must be >= 1");
  if (!(s.cg_tolerance >= 0)) fail("bullet.cg_tolerance: must be >= 0");
  if (n < 1) fail("model: has no nodes");
  if (x0.size() != 3 * n) fail("x0: size must be 3 * nodes");
  if (v0.size() != 0 && v0.size() != 3 * n) fail("v0: size must be 0 or 3 * nodes");
  if (model.rest_positions.size() != 3 * n) fail("model.rest_positions: size must be 3 * nodes");
  if (!x0.allFinite()) fail("x0: must be finite");
  if (v0.size() != 0 && !v0.allFinite()) fail("v0: must be finite");
  if (model.air_drag != 0.0) {
    fail("air_drag: the Bullet peer has no per-node linear drag "
         "(btSoftBody::Config::drag rescales velocity per step instead); set it to 0");
  }
  for (int i : pinned) {
    if (i < 0 || i >= n) fail("pins: index " + std::to_string(i) + " out of range");
  }
  for (int i = 0; i < n; ++i) {
    if (!(model.mass[i] > 0)) fail("model.mass: node " + std::to_string(i) + " must be > 0");
  }
  if (model.has_gravity) {
    for (int a = 0; a < 3; ++a) requireFinite(model.gravity[a], "gravity");
  }
  if (s.stock_force) {
    std::string why = stockForceLimitation(model);
    if (!why.empty()) fail("bullet.stock_force: " + why);
    if (s.project_compression) {
      fail("bullet.stock_force: btDeformableMassSpringForce has no project_compression");
    }
  }
}

}  // namespace

std::string stockForceLimitation(const Model& model) {
  double damping = -1, elastic = -1;
  for (int t = 0; t < kNumSpringTypes; ++t) {
    const SpringGroup& g = model.groups[t];
    if (!g.present) continue;
    if (damping >= 0 && g.damping != damping) {
      return "btDeformableMassSpringForce has one damping coefficient for all links, "
             "but the spring groups' damping differ";
    }
    damping = g.damping;
    if (t == static_cast<int>(SpringType::Bend)) continue;  // bending links have their own k
    if (elastic >= 0 && g.stiffness != elastic) {
      return "btDeformableMassSpringForce has one elastic stiffness for non-bending links, "
             "but stretch and shear stiffness differ";
    }
    elastic = g.stiffness;
  }
  return "";
}

struct BulletPeer::Impl {
  // ~Impl takes the body out of the world and destroys the world before the
  // members it points to (destroyed in reverse declaration order).
  btSoftBodyRigidBodyCollisionConfiguration collision_config;
  btCollisionDispatcher dispatcher{&collision_config};
  btDbvtBroadphase broadphase;
  TunedDeformableSolver solver;
  btDeformableMultiBodyConstraintSolver constraint_solver;
  std::unique_ptr<btDeformableLagrangianForce> spring_force;
  PerLinkMassSpringForce* per_link = nullptr;  ///< spring_force, if per-link
  std::unique_ptr<btDeformableGravityForce> gravity_force;
  std::unique_ptr<btDeformableMultiBodyDynamicsWorld> world;
  std::unique_ptr<btSoftBody> body;
  std::vector<double> rest_lengths;
  // Static boxes (contact scenes only).
  std::vector<std::unique_ptr<btBoxShape>> box_shapes;
  std::vector<std::unique_ptr<btRigidBody>> boxes;

  ~Impl() {
    if (world) {
      for (auto& box : boxes) world->removeRigidBody(box.get());
    }
    if (world && body) world->removeSoftBody(body.get());
    world.reset();
  }
};

BulletPeer::BulletPeer(const Model& model, const VecX& x0, const std::vector<int>& pinned,
                       const BulletSettings& settings, const VecX& v0,
                       const BulletContact& contact)
    : settings_(settings), mass_(model.mass.begin(), model.mass.end()) {
  const bool self = contact.self_collision;
  if (self) {
    if (!(contact.self_thickness > 0) || !std::isfinite(contact.self_thickness)) {
      throw std::invalid_argument("self_collision.thickness: must be > 0 and finite");
    }
    if (!(contact.self_friction >= 0) || !std::isfinite(contact.self_friction)) {
      throw std::invalid_argument("self_collision.friction: must be >= 0 and finite");
    }
    for (const BulletBox& b : contact.boxes) {
      if (b.friction > 0 && contact.self_friction == 0) {
        throw std::invalid_argument(
            "self_collision.friction: Bullet scales a box's friction by the soft body's "
            "kDF = sqrt(self friction), so boxes with friction need self friction > 0");
      }
    }
  }
  if (!contact.boxes.empty()) {
    if (!(contact.margin >= 0) || !std::isfinite(contact.margin)) {
      throw std::invalid_argument("contact.margin: must be >= 0 and finite");
    }
    if (!(settings.sdf_voxel > 0) || !std::isfinite(settings.sdf_voxel)) {
      throw std::invalid_argument("bullet.sdf_voxel: must be > 0 and finite");
    }
    for (const BulletBox& b : contact.boxes) {
      if (!(b.half_extents.minCoeff() > 0) || !(b.friction >= 0)) {
        throw std::invalid_argument("contact.boxes: half extents must be > 0, friction >= 0");
      }
    }
    if (settings.stock_force) {
      // No addScaledHessian: Bullet's contact would work on an explicit predictor.
      throw std::invalid_argument(
          "bullet.stock_force: btDeformableMassSpringForce cannot carry contact "
          "(no effective mass for the contact predictor); use the per-link force");
    }
  }
  validate(model, x0, v0, pinned, settings);
  const int n = model.numNodes();
  impl_ = std::make_unique<Impl>();
  Impl& m = *impl_;

  m.constraint_solver.setDeformableSolver(&m.solver);
  m.world = std::make_unique<btDeformableMultiBodyDynamicsWorld>(
      &m.dispatcher, &m.broadphase, &m.constraint_solver, &m.collision_config, &m.solver);
  // Gravity reaches the cloth only through btDeformableGravityForce.
  m.world->setGravity(btVector3(0, 0, 0));
  m.world->getWorldInfo().m_gravity.setZero();
  m.world->setImplicit(true);
  m.world->setLineSearch(settings.line_search);
  // Bullet 3.24's default (useProjection false) pairs conjugate residual with
  // a KKT preconditioner that is never initialised in implicit mode; the solve
  // then returns dv = 0 and the cloth does not move at all. useProjection
  // true selects CG with pins as projections, the working implicit path.
  m.world->setUseProjection(true);
  m.solver.configure(settings);

  // Nodes at the rest layout, so Bullet's own rest lengths (if it ever
  // recomputes them) are the model's; then moved to x0 below.
  std::vector<bool> is_pinned(n, false);
  for (int i : pinned) is_pinned[i] = true;
  m.body = std::make_unique<btSoftBody>(&m.world->getWorldInfo(), 0, nullptr, nullptr);
  btSoftBody& body = *m.body;
  for (int i = 0; i < n; ++i) {
    body.appendNode(toBt(model.rest_positions, i), is_pinned[i] ? 0.0 : model.mass[i]);
  }
  const bool stock = settings.stock_force;
  std::vector<btScalar> k, c;
  k.reserve(model.springs.size());
  c.reserve(model.springs.size());
  double stock_elastic = -1, stock_bending = -1, stock_damping = 0;
  for (const Spring& s : model.springs) {
    body.appendLink(s.i, s.j, nullptr, false);
    btSoftBody::Link& link = body.m_links[body.m_links.size() - 1];
    link.m_rl = s.rest_length;
    link.m_c1 = s.rest_length * s.rest_length;
    const SpringGroup& g = model.groups[static_cast<int>(s.type)];
    k.push_back(g.stiffness);
    c.push_back(g.damping);
    if (stock) {
      link.m_bbending = s.type == SpringType::Bend ? 1 : 0;
      (s.type == SpringType::Bend ? stock_bending : stock_elastic) = g.stiffness;
      stock_damping = g.damping;
    }
    m.rest_lengths.push_back(s.rest_length);
  }
  if (self) {
    // The cloth's triangles as Bullet faces: what its self-collision tests.
    for (const auto& t : model.triangles) body.appendFace(t[0], t[1], t[2]);
  }
  body.m_bUpdateRtCst = false;  // keep our rest lengths (appendLink/appendFace set it)
  for (int i = 0; i < n; ++i) {
    btSoftBody::Node& node = body.m_nodes[i];
    node.m_x = node.m_q = toBt(x0, i);
    node.m_v = node.m_vn = (v0.size() && !is_pinned[i]) ? toBt(v0, i) : btVector3(0, 0, 0);
  }
  body.setActivationState(DISABLE_DEACTIVATION);    // never put to sleep
  if (contact.boxes.empty() && !self) {
    body.m_cfg.collisions = 0;                      // no contact of any kind
    m.world->addSoftBody(&body, 0, 0);              // filter group/mask 0: no pairs
  } else {
    // Bullet's deformable node-vs-rigid contact (as its DeformableRigid
    // example): signed distance from the sparse SDF at x_n (implicit mode's
    // predictDeformableMotion sets m_q = m_x), a contact when it is within
    // the margin; the contact solve acts on the predictor's v* (see
    // PerLinkMassSpringForce::addScaledHessian); friction kDF * the rigid's
    // friction. (SDF_RD alone does nothing in 3.24: nodes are tested only
    // with SDF_RDN.) Self-collision (as its DeformableSelfCollision example):
    // VF_DD, the only soft-soft mode the deformable world runs
    // (btSoftBody::defaultCollisionHandler switches on the whole soft-soft
    // mask, so VF_DD must be the only bit of it).
    int collisions = 0;
    if (!contact.boxes.empty()) {
      collisions |= btSoftBody::fCollision::SDF_RD | btSoftBody::fCollision::SDF_RDN;
    }
    if (self) collisions |= btSoftBody::fCollision::VF_DD;
    body.m_cfg.collisions = collisions;
    // A self pair's friction is kDF * kDF, a box's kDF * its own.
    const double kdf = self ? std::sqrt(contact.self_friction) : 1.0;
    body.m_cfg.kDF = kdf;
    body.m_cfg.kKHR = 1.0;
    body.m_cfg.kCHR = 1.0;
    body.getCollisionShape()->setMargin(self ? 0.5 * contact.self_thickness : contact.margin);
    body.setCollisionFlags(0);
    if (contact.boxes.empty()) {
      m.world->addSoftBody(&body, 0, 0);            // no rigid pairs; self-collision is not
    } else {                                        // a broadphase pair
      m.world->getWorldInfo().m_sparsesdf.setDefaultVoxelsz(settings.sdf_voxel);
      m.world->getWorldInfo().m_sparsesdf.Reset();
      m.world->addSoftBody(&body);                  // default filters: collides with rigids
    }
    if (self) {
      body.setSelfCollision(true);
      // predictDeformableMotion builds the face tree only when it updates
      // the constants, which m_bUpdateRtCst = false turns off: build it here.
      body.initializeFaceTree();
    }
    for (const BulletBox& b : contact.boxes) {
      auto shape = std::make_unique<btBoxShape>(
          btVector3(b.half_extents.x(), b.half_extents.y(), b.half_extents.z()));
      // btBoxShape keeps its outer extents, but its distance is that of a box
      // shrunk by the margin plus the margin: edges rounded by the margin
      // (0.04 m by default). 1 mm keeps them sharp enough.
      shape->setMargin(0.001);
      btTransform pose;
      pose.setIdentity();
      pose.setOrigin(btVector3(b.center.x(), b.center.y(), b.center.z()));
      const Mat3& r = b.rotation;
      pose.setBasis(btMatrix3x3(r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0),
                                r(2, 1), r(2, 2)));
      btRigidBody::btRigidBodyConstructionInfo info(0.0, nullptr, shape.get());
      info.m_startWorldTransform = pose;
      auto rigid = std::make_unique<btRigidBody>(info);
      rigid->setFriction(kdf > 0 ? b.friction / kdf : 0.0);
      m.world->addRigidBody(rigid.get());
      m.box_shapes.push_back(std::move(shape));
      m.boxes.push_back(std::move(rigid));
    }
  }

  const bool along = model.damping_model == DampingModel::AlongSpring;
  if (!model.springs.empty()) {
    if (stock) {
      if (stock_elastic < 0) stock_elastic = stock_bending;
      if (stock_bending < 0) stock_bending = stock_elastic;
      m.spring_force = std::make_unique<btDeformableMassSpringForce>(
          stock_elastic, stock_damping, along, stock_bending);
    } else {
      auto force = std::make_unique<PerLinkMassSpringForce>(std::move(k), std::move(c), along,
                                                            settings.project_compression);
      m.per_link = force.get();
      m.spring_force = std::move(force);
    }
    m.world->addForce(&body, m.spring_force.get());
  }
  if (model.has_gravity) {
    m.gravity_force = std::make_unique<btDeformableGravityForce>(
        btVector3(model.gravity.x(), model.gravity.y(), model.gravity.z()));
    m.world->addForce(&body, m.gravity_force.get());
  }
}

BulletPeer::~BulletPeer() = default;

void BulletPeer::step() {
  // maxSubSteps = 0: exactly one internal step of length dt, no interpolation.
  impl_->world->stepSimulation(settings_.dt, 0);
  ++steps_;
  time_ = steps_ * settings_.dt;
}

void BulletPeer::holdNode(int node, const Vec3& velocity) {
  if (node < 0 || node >= numNodes()) throw std::invalid_argument("holdNode: node out of range");
  btSoftBody::Node& n = impl_->body->m_nodes[node];
  // m_im directly: btSoftBody::setMass would also set m_bUpdateRtCst, and the
  // next step would reset every rest length from the current positions.
  n.m_im = 0.0;
  n.m_v = n.m_vn = btVector3(velocity.x(), velocity.y(), velocity.z());
}

void BulletPeer::releaseNode(int node) {
  if (node < 0 || node >= numNodes()) throw std::invalid_argument("releaseNode: node out of range");
  impl_->body->m_nodes[node].m_im = 1.0 / mass_[node];
}

int BulletPeer::numNodes() const { return impl_->body->m_nodes.size(); }

VecX BulletPeer::positions() const {
  const auto& nodes = impl_->body->m_nodes;
  VecX x(3 * nodes.size());
  for (int i = 0; i < nodes.size(); ++i) {
    for (int a = 0; a < 3; ++a) x[3 * i + a] = nodes[i].m_x[a];
  }
  return x;
}

VecX BulletPeer::velocities() const {
  const auto& nodes = impl_->body->m_nodes;
  VecX v(3 * nodes.size());
  for (int i = 0; i < nodes.size(); ++i) {
    for (int a = 0; a < 3; ++a) v[3 * i + a] = nodes[i].m_v[a];
  }
  return v;
}

BulletWork BulletPeer::work() const {
  BulletWork w;
  if (impl_->per_link) w = impl_->per_link->work();
  w.steps = steps_;
  return w;
}

double BulletPeer::restLengthDrift() const {
  const auto& links = impl_->body->m_links;
  double drift = 0;
  for (int j = 0; j < links.size(); ++j) {
    drift = std::max(drift, std::abs(links[j].m_rl - impl_->rest_lengths[j]));
  }
  return drift;
}

}  // namespace bench
}  // namespace cloth_sim
