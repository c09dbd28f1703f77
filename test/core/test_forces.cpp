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

}  // namespace
}  // namespace cloth_sim
