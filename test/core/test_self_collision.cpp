// Self-collision end to end: cloths whose layers meet (folded onto a table,
// draped over a thin rod, a pin driven through a folded cloth at 5 m/s)
// never intersect themselves at any step, stay finite and gain no energy;
// friction holds a folded layer; disabled changes nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "cloth_sim/collision_geometry.hpp"
#include "cloth_sim/scene.hpp"
#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"
#include "../common/cloth_checks.hpp"

namespace cloth_sim {
namespace {

constexpr int kN = 12;
constexpr double kSize = 0.3;  // m, so 2.7 cm between nodes

Scene clothScene(Method method = Method::ImplicitEuler) {
  Scene s = test::bareScene(kN, kN);
  s.cloth.width = s.cloth.length = kSize;
  test::enable(s, SpringType::Stretch, 2000.0, 1.0);
  test::enable(s, SpringType::Shear, 200.0, 0.2);
  test::enable(s, SpringType::Bend, 0.5, 0.0);
  s.gravity = Vec3(0, 0, -9.81);
  s.solver.method = method;
  s.solver.dt = 0.004;
  s.solver.tolerance = 1e-8;
  s.solver.newton_tolerance = 1e-8;
  s.self_collision.enabled = true;
  s.self_collision.thickness = 0.002;
  s.self_collision.friction = 0.2;
  return s;
}

ColliderParams table(double z = 0.0) {
  ColliderParams c;
  c.name = "table";
  c.type = ColliderParams::Type::Plane;
  c.point = Vec3(0, 0, z);
  return c;
}

/// The grid folded in two across its rows: rows 0-4 flat at height z0, a
/// half circle of radius r, the rest lying back above the first half.
VecX foldedPositions(const Model& m, double z0, double r) {
  const double ds = kSize / (kN - 1), fold = 4.5 * ds;
  VecX x = m.rest_positions;
  for (int row = 0; row < m.rows; ++row) {
    const double s = row * ds;
    double y, z;
    if (s <= fold) {
      y = -s, z = z0;
    } else if (s <= fold + M_PI * r) {
      const double phi = (s - fold) / r;
      y = -fold - r * std::sin(phi), z = z0 + r * (1 - std::cos(phi));
    } else {
      y = -fold + (s - fold - M_PI * r), z = z0 + 2 * r;
    }
    for (int col = 0; col < m.cols; ++col) {
      const int i = m.index(row, col);
      x[3 * i + 1] = y;
      x[3 * i + 2] = z;
    }
  }
  return x;
}

struct RunResult {
  int steps = 0;
  int max_intersections = 0;
  /// most pairs within the thickness at any of the last 10 steps (bdf2's top
  /// layer hovers at the thickness: its count flickers 0-50 step to step)
  int final_self_contacts = 0;
  double max_gain = -1e300;  ///< largest energy rise of a step beyond the pins' work, J
};

/// Steps `sim` `steps` times; at every step: ok, finite, intersection-free
/// (counted), energy not gained beyond the work the pins did.
RunResult run(Simulation& sim, int steps) {
  RunResult r;
  EXPECT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0) << "the start must be clean";
  double energy = sim.energy();
  for (int k = 0; k < steps; ++k) {
    const StepStats st = sim.step();
    EXPECT_TRUE(st.ok) << "step " << k << ": " << st.failure;
    EXPECT_TRUE(st.finite) << "step " << k;
    if (!st.ok || !st.finite) break;
    r.max_intersections = std::max(r.max_intersections, test::selfIntersections(sim.model(), sim.positions()));
    r.max_gain = std::max(r.max_gain, st.energy - energy - st.work_in);
    energy = st.energy;
    if (k >= steps - 10) r.final_self_contacts = std::max(r.final_self_contacts, st.self_contacts);
    ++r.steps;
  }
  return r;
}

TEST(SelfCollision, FoldedClothDroppedOnATableNeverIntersects) {
  for (Method method : {Method::ImplicitEuler, Method::Newton, Method::Bdf2}) {
    SCOPED_TRACE(toString(method));
    Scene s = clothScene(method);
    s.colliders.push_back(table());
    Simulation sim(s);
    ASSERT_TRUE(sim.setState(foldedPositions(sim.model(), 0.02, 0.02), VecX::Zero(3 * kN * kN)));
    const RunResult r = run(sim, 100);
    EXPECT_EQ(r.steps, 100);
    EXPECT_EQ(r.max_intersections, 0);
    // bdf2 is not dissipative step by step: it is held to the energy check's
    // allowance, 1e-6 of the energy scale (m g size + E: 1.3e-6 J here).
    // Its friction states are refined on exploring passes' answers
    // (ContactSet::update): 1.16e-6 J in one step, < 3e-7 with full passes.
    const double allowance =
        method == Method::Bdf2 ? 1e-6 * (s.cloth.mass * 9.81 * std::hypot(kSize, kSize)) : 1e-6;
    EXPECT_LE(r.max_gain, allowance);
    // The layers did meet: pairs within the thickness, none closer than a
    // small fraction of it.
    EXPECT_GT(r.final_self_contacts, 0);
    EXPECT_LT(sim.minSelfDistance(), s.self_collision.thickness);
    EXPECT_GT(sim.minSelfDistance(), 0.0);
  }
}

TEST(SelfCollision, AFoldedClothRestingOnATableStaysAtRestWithoutRejectedSteps) {
  // Two layers at rest on a table, at the fold demo's dt and tolerance:
  // each step the top layer falls g h^2 into the bottom one and the filter
  // sets it back. Its pairs share nodes; set back one pair at a time, the
  // top layer was lifted above where it rested (a pair lifting a node its
  // neighbour had already set), steps gained potential energy and were
  // halved (fold.yaml: 3 rejected sub-steps a step at rest).
  for (Method method : {Method::ImplicitEuler, Method::Bdf2}) {
    SCOPED_TRACE(toString(method));
    Scene s = clothScene(method);
    s.solver.dt = 1.0 / 120.0;
    s.solver.tolerance = 1e-4;
    s.colliders.push_back(table());
    Simulation sim(s);
    ASSERT_TRUE(sim.setState(foldedPositions(sim.model(), 0.02, 0.02), VecX::Zero(3 * kN * kN)));
    for (int k = 0; k < 180; ++k) ASSERT_TRUE(sim.step().ok) << "settling, step " << k;
    std::vector<int> top;  // the layer above the bottom one
    for (int i = 0; i < sim.numNodes(); ++i) {
      if (sim.position(i).z() > s.contact.thickness + 0.5 * s.self_collision.thickness) top.push_back(i);
    }
    ASSERT_GT(top.size(), 2u * kN);
    auto topHeight = [&] {
      double z = 0.0;
      for (int i : top) z += sim.position(i).z();
      return z / top.size();
    };
    const double start = topHeight();
    int rejected = 0, solves = 0;
    for (int k = 0; k < 120; ++k) {
      const StepStats st = sim.step();
      ASSERT_TRUE(st.ok) << "step " << k << ": " << st.failure;
      rejected += st.rejected;
      solves += st.self_solves;
    }
    EXPECT_EQ(rejected, 0);
    // implicit_euler: the repulsion holds the top layer inside the solve,
    // the filter has nothing to set back, and no step is solved twice
    // (before it, each step was solved again with the set-back nodes held).
    if (method == Method::ImplicitEuler) EXPECT_EQ(solves, 0);
    EXPECT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0);
    // Not lifted (it may still settle a little).
    EXPECT_LT(topHeight() - start, 0.05 * s.self_collision.thickness);
    std::printf("[ rest     ] %s: top layer of %zu nodes moved %.3g m in 1 s at rest\n",
                toString(method), top.size(), topHeight() - start);
  }
}

/// A folded cloth's step on a table, for the filter alone: rows 0-4 on the
/// table (held against moves into it), rows 7-11 lying back over them at
/// the thickness (row 11 over row 0; shifted across by `shift` spacings in
/// x and y), rows 5-6 the crease between, clear of both; x1 and v: every
/// node off the table fallen g h^2 in the step.
struct FoldedStep {
  VecX x0, x1, v;
  SelfCollisionMasses masses;
  std::vector<int> top, bottom;
};

FoldedStep foldedStep(const Model& m, double thickness, const Vec3& shift) {
  const double ds = kSize / (kN - 1);
  FoldedStep f;
  f.x0 = m.rest_positions;
  for (int row = 0; row < kN; ++row) {
    for (int col = 0; col < kN; ++col) {
      const int i = m.index(row, col);
      double x = f.x0[3 * i], y = -row * ds, z = 0.0;
      if (row == 5 || row == 6) y = -4.5 * ds, z = (row - 4) * 0.01;
      if (row >= 7) {
        x += shift.x() * ds, y = -(kN - 1 - row + shift.y()) * ds, z = thickness;
        f.top.push_back(i);
      }
      if (row <= 4) {
        f.bottom.push_back(i);
        f.masses.heavy.push_back(i);
        f.masses.heavy_normal.push_back(Vec3::UnitZ());
        f.masses.heavy_room.push_back(0.0);
      }
      f.x0.segment<3>(3 * i) = Vec3(x, y, z);
    }
  }
  return f;
}

/// x1 and v of `f` for its x0: what is off the table fell g h^2.
void fall(const Model& m, double h, FoldedStep* f) {
  f->x1 = f->x0;
  f->v = VecX::Zero(f->x0.size());
  for (int i = 0; i < m.numNodes(); ++i) {
    if (f->x0[3 * i + 2] > 0.0) f->x1[3 * i + 2] -= 9.81 * h * h, f->v[3 * i + 2] = -9.81 * h;
  }
}

TEST(SelfCollision, SetsAFallenRestingLayerBackInAFewSweeps) {
  // The filter alone, on the step of a folded cloth at rest on a table: the
  // top layer, lying at the thickness on the bottom one (held by the table),
  // has fallen g h^2 into it. The sweeps end once the nodes are still, with
  // the layer back at the thickness and no higher.
  Scene s = clothScene();
  Simulation sim(s);
  const Model& m = sim.model();
  const double thickness = s.self_collision.thickness, h = 1.0 / 120.0;
  FoldedStep f = foldedStep(m, thickness, Vec3::Zero());
  // The top layer tilted by a millimetre over its length (a cloth does not
  // lie flat to the micrometre), and resting: the layers touch at its low
  // edge.
  double low = 1e300;
  for (int i : f.top) low = std::min(low, f.x0[3 * i + 1]);
  for (int i : f.top) f.x0[3 * i + 2] += 0.001 * (f.x0[3 * i + 1] - low) / kSize;
  fall(m, h, &f);
  SelfCollision filter(m, s.self_collision);
  const SelfCollisionResult r = filter.apply(m, h, f.x0, f.masses, f.x1, f.v);
  ASSERT_TRUE(r.ok) << r.failure;
  EXPECT_GT(r.proximity_impulses, 0);
  EXPECT_LE(r.proximity_sweeps, 10);
  // Set back to the thickness where it fell into it, and not lifted above
  // where it started.
  for (int i : f.top) {
    const double fell = f.x0[3 * i + 2] - 9.81 * h * h;
    EXPECT_GT(f.x1[3 * i + 2], std::min(fell, thickness) - 1e-3 * thickness) << "node " << i;
    EXPECT_LT(f.x1[3 * i + 2], f.x0[3 * i + 2] + 1e-3 * thickness) << "node " << i;
  }
  std::printf("[ sweeps   ] resting layer of %zu nodes: %d proximity impulses, %d sweeps\n",
              f.top.size(), r.proximity_impulses, r.proximity_sweeps);
}

TEST(SelfCollision, NeverLiftsALayerHeldOnATableByEasingOffItsPush) {
  // Offset layers on a table: the top layer (shifted across by a fraction
  // of a spacing, so a node meets several pairs) has fallen g h^2 into the
  // bottom one, which the table holds against moves into it. The sweeps
  // push and ease off many pairs; the eased impulses must not lift bottom
  // nodes their pushes never moved (they did: the layer above followed, and
  // a folded towel crept up 0.3 um a step).
  Scene s = clothScene();
  Simulation sim(s);
  const Model& m = sim.model();
  const double thickness = s.self_collision.thickness, h = 1.0 / 120.0;
  FoldedStep f = foldedStep(m, thickness, Vec3(0.4, 0.3, 0.0));
  fall(m, h, &f);
  SelfCollision filter(m, s.self_collision);
  const SelfCollisionResult r = filter.apply(m, h, f.x0, f.masses, f.x1, f.v);
  ASSERT_TRUE(r.ok) << r.failure;
  EXPECT_GT(r.proximity_impulses, 0);
  double lifted = 0.0;
  for (int i : f.bottom) lifted = std::max(lifted, std::abs(f.x1[3 * i + 2]));
  EXPECT_LT(lifted, 1e-12 * thickness);
  std::printf("[ offset   ] %d proximity impulses, %d sweeps, bottom layer moved %.3g m along the normal\n",
              r.proximity_impulses, r.proximity_sweeps, lifted);
}

TEST(SelfCollision, WithoutItTheFoldedDropIntersects) {
  // The scene above is a real test: without self-collision the top layer
  // falls through the bottom one.
  Scene s = clothScene();
  s.colliders.push_back(table());
  s.self_collision.enabled = false;
  Simulation sim(s);
  ASSERT_TRUE(sim.setState(foldedPositions(sim.model(), 0.02, 0.02), VecX::Zero(3 * kN * kN)));
  int most = 0;
  for (int k = 0; k < 100; ++k) {
    sim.step();
    most = std::max(most, test::selfIntersections(sim.model(), sim.positions()));
  }
  EXPECT_GT(most, 10);
}

TEST(SelfCollision, ClothOnAThinRodDrapesWithoutIntersecting) {
  Scene s = clothScene();
  ColliderParams rod;
  rod.name = "rod";
  rod.type = ColliderParams::Type::Capsule;
  rod.a = Vec3(-0.1, -0.5 * kSize, 1.45);
  rod.b = Vec3(kSize + 0.1, -0.5 * kSize, 1.45);
  rod.radius = 0.004;
  s.colliders.push_back(rod);
  s.self_collision.friction = 0.0;
  Simulation sim(s);
  const RunResult r = run(sim, 150);  // 0.6 s: falls, drapes, halves swing together
  EXPECT_EQ(r.steps, 150);
  EXPECT_EQ(r.max_intersections, 0);
  EXPECT_LE(r.max_gain, 1e-6);
  // The halves hang down on both sides of the rod, close together.
  double lowest = 1e9;
  for (int i = 0; i < sim.numNodes(); ++i) lowest = std::min(lowest, sim.position(i).z());
  EXPECT_LT(lowest, 1.45 - 0.08);
  EXPECT_LT(sim.minSelfDistance(), 0.02);
}

TEST(SelfCollision, PinDrivenThroughAFoldedClothAt5MetersPerSecond) {
  // No gravity: a node of the top layer is pinned and driven straight down
  // at 5 m/s through where the bottom layer is (a fast fling).
  Scene s = clothScene();
  s.gravity = Vec3::Zero();
  Simulation sim(s);
  const Model& m = sim.model();
  ASSERT_TRUE(sim.setState(foldedPositions(m, 1.0, 0.02), VecX::Zero(3 * kN * kN)));
  const int top = m.index(9, 6);  // above bottom-layer row 2
  ASSERT_TRUE(sim.pin({top}));
  ASSERT_TRUE(sim.drivePin(top, Vec3(0, 0, -5.0), 0.04));  // 20 cm down in 10 steps
  const RunResult r = run(sim, 30);
  EXPECT_EQ(r.steps, 30);
  EXPECT_EQ(r.max_intersections, 0);
  // The pin went where the bottom layer was, so it pushed the layer ahead of it.
  EXPECT_LT(sim.position(top).z(), 1.0 - 0.15);
  EXPECT_LT(sim.position(m.index(2, 6)).z(), sim.position(top).z());
}

/// How far the top layer's free edge moves relative to the bottom layer
/// under a sideways pull, the bottom layer held by pins.
double topLayerSlide(double friction) {
  Scene s = clothScene();
  s.gravity = Vec3(-4.0, 0, -9.0);  // along the fold line (x), so the fold does not hold it
  s.self_collision.friction = friction;
  Simulation sim(s);
  const Model& m = sim.model();
  EXPECT_TRUE(sim.setState(foldedPositions(m, 1.0, 0.004), VecX::Zero(3 * kN * kN)));
  std::vector<int> bottom;
  for (int row = 0; row <= 4; ++row)
    for (int col = 0; col < kN; ++col) bottom.push_back(m.index(row, col));
  EXPECT_TRUE(sim.pin(bottom));
  const int edge = m.index(kN - 1, kN / 2);
  const double x_start = sim.position(edge).x();
  const RunResult r = run(sim, 60);
  EXPECT_EQ(r.max_intersections, 0);
  return std::abs(sim.position(edge).x() - x_start);
}

TEST(SelfCollision, HighFrictionHoldsAFoldedLayer) {
  const double slides = topLayerSlide(0.0);
  const double holds = topLayerSlide(5.0);
  EXPECT_GT(slides, 0.01);
  EXPECT_LT(holds, 0.25 * slides);
}

TEST(SelfCollision, DisabledIsBitIdenticalToNoSection) {
  const std::string base =
      "cloth: {rows: 10, cols: 10}\n"
      "springs: {stretch: {stiffness: 1000}, shear: {stiffness: 100}}\n"
      "pins: [0, 9]\n"
      "colliders: [{type: sphere, center: [0.5, -0.5, 1.2], radius: 0.2}]\n";
  Simulation plain(parseScene(base));
  Simulation off(parseScene(base + "self_collision: {enabled: false, thickness: 0.01, friction: 1}\n"));
  for (int k = 0; k < 60; ++k) {
    plain.step();
    off.step();
  }
  EXPECT_EQ(plain.positions(), off.positions());
  EXPECT_EQ(plain.velocities(), off.velocities());
  EXPECT_EQ(off.lastStats().self_contacts, 0);
  EXPECT_TRUE(std::isinf(off.minSelfDistance()));
}

TEST(SelfCollisionScene, ReadsTheSectionAndRefusesBadValues) {
  const std::string base = "cloth: {rows: 3, cols: 3}\n";
  const Scene s = parseScene(base + "self_collision: {enabled: true, thickness: 0.003, friction: 0.4}\n");
  EXPECT_TRUE(s.self_collision.enabled);
  EXPECT_EQ(s.self_collision.thickness, 0.003);
  EXPECT_EQ(s.self_collision.friction, 0.4);
  EXPECT_FALSE(parseScene(base).self_collision.enabled);
  auto error = [&](const std::string& extra) {
    try {
      parseScene(base + extra);
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  auto rejected = [&](const std::string& extra, const std::string& field) {
    const std::string e = error(extra);
    EXPECT_EQ(e.rfind(field + ":", 0), 0u) << extra << " -> " << e;
  };
  rejected("self_collision: {enabled: true, thickness: -0.001}\n", "self_collision.thickness");
  rejected("self_collision: {enabled: true, thickness: .nan}\n", "self_collision.thickness");
  rejected("self_collision: {enabled: true, thickness: 0}\n", "self_collision.thickness");
  rejected("self_collision: {enabled: true, friction: -1}\n", "self_collision.friction");
  rejected("self_collision: {enabled: yes please}\n", "self_collision.enabled");
  rejected("self_collision: {enabled: true, thickness: [1]}\n", "self_collision.thickness");
  rejected("self_collision: {enabled: true, margin: 1}\n", "self_collision.margin");
  rejected("self_collision: 3\n", "self_collision");
  rejected("self_collision: {enabled: true}\nsolver: {method: symplectic_euler}\n", "solver.method");
  EXPECT_NE(error("self_collision: {enabled: true, thickness: 0}\n").find("> 0 when"), std::string::npos);
  // Disabled, a zero thickness is fine.
  EXPECT_NO_THROW(parseScene(base + "self_collision: {enabled: false, thickness: 0}\n"));
}

// The filter's moves below kSettledShift thicknesses used to be left
// unsolved as negligible. On a stiff heap (stretch 1e8, dt 1 ms) a few
// micrometres store k dx^2 / 2 of a few 1e-4 J in the springs, a gain no
// halving shrank: the stability map's run failed at t = 0.132 s after 8
// halvings. Now a solve follows whenever the springs would store more than
// a tenth of the energy check's allowance.
TEST(SelfCollision, StiffHeapSolvesTheFiltersSmallMoves) {
  Simulation sim(loadScene(std::string(CLOTH_SIM_SOURCE_DIR) + "/config/scenes/hard/self/s1_heap.yaml",
                           {"solver.method=implicit_euler", "solver.dt=0.001",
                            "springs.stretch.stiffness=1e8"}));
  for (int n = 0; n < 140; ++n) {
    const StepStats s = sim.step();
    ASSERT_TRUE(s.ok) << "t = " << sim.time() << ": " << s.failure;
    ASSERT_TRUE(s.finite);
  }
  EXPECT_NEAR(sim.time(), 0.14, 1e-12);
  EXPECT_EQ(test::selfIntersections(sim.model(), sim.positions()), 0);
}

}  // namespace
}  // namespace cloth_sim
