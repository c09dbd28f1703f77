// The whole-cloth force loop (computeForces, inlined for speed) against the
// per-spring reference springForce, for both damping models, with gravity,
// air drag and a zero-length spring.
#include <gtest/gtest.h>

#include "cloth_sim/forces.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

TEST(Forces, MatchPerSpringReferenceSum) {
  for (DampingModel dm : {DampingModel::AlongSpring, DampingModel::RelativeVelocity}) {
    Scene s = test::hangingCloth(6);
    s.damping_model = dm;
    s.air_drag = 0.3;
    const Model m = buildModel(s);
    VecX x, v;
    test::perturbedState(m, 11, &x, &v);  // with one zero-length spring
    VecX f;
    computeForces(m, x, v, f);
    VecX ref(x.size());
    for (int i = 0; i < m.numNodes(); ++i) {
      ref.segment<3>(3 * i) = m.mass[i] * m.gravity - m.air_drag * v.segment<3>(3 * i);
    }
    for (const Spring& sp : m.springs) {
      const Vec3 fi = springForce(x.segment<3>(3 * sp.i), x.segment<3>(3 * sp.j),
                                  v.segment<3>(3 * sp.i), v.segment<3>(3 * sp.j),
                                  springParams(m, sp));
      ref.segment<3>(3 * sp.i) += fi;
      ref.segment<3>(3 * sp.j) -= fi;
    }
    EXPECT_LE((f - ref).norm(), 1e-13 * ref.norm());
  }
}

// The per-group sums (measureEnergy's elastic energy, springForceScale's
// cached rest lengths) against per-spring sums, also after a stiffness change.
TEST(Forces, GroupSumsMatchPerSpringSums) {
  Scene s = test::hangingCloth(7);
  s.springs[static_cast<int>(SpringType::Bend)].enabled = true;
  s.springs[static_cast<int>(SpringType::Bend)].stiffness = 3.0;
  Model m = buildModel(s);
  VecX x, v;
  test::perturbedState(m, 5, &x, &v);
  for (double stretch_k : {m.groups[0].stiffness, 7.5e3}) {
    m.groups[static_cast<int>(SpringType::Stretch)].stiffness = stretch_k;
    double elastic = 0.0, strain = 0.0, scale_sq = 0.0;
    for (const Spring& sp : m.springs) {
      const SpringParams p = springParams(m, sp);
      elastic += springEnergy(x.segment<3>(3 * sp.i), x.segment<3>(3 * sp.j), p);
      strain = std::max(strain, (x.segment<3>(3 * sp.j) - x.segment<3>(3 * sp.i)).norm() /
                                    sp.rest_length - 1.0);
      scale_sq += (p.stiffness * sp.rest_length) * (p.stiffness * sp.rest_length);
    }
    const EnergyParts e = measureEnergy(m, x, v);
    EXPECT_NEAR(e.elastic, elastic, 1e-12 * elastic);
    EXPECT_EQ(e.max_strain, strain);
    EXPECT_NEAR(springForceScale(m), std::sqrt(scale_sq), 1e-12 * std::sqrt(scale_sq));
  }
}

}  // namespace
}  // namespace cloth_sim
