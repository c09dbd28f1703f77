// CG's fused vector kernels and the filter on split vectors
// (cg_kernels.hpp, ConstraintFilter::applySplit) against the plain
// operations they replace, at lengths around their unrolling (8) and a
// cloth's.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "cloth_sim/cg_kernels.hpp"
#include "cloth_sim/constraint_filter.hpp"
#include "cloth_sim/multigrid.hpp"
#include "cloth_sim/spring_sweeps.hpp"

namespace cloth_sim {
namespace {

VecX randomVector(int n, std::mt19937& rng) {
  std::uniform_real_distribution<double> d(-1.0, 1.0);
  VecX v(n);
  for (int i = 0; i < n; ++i) v[i] = d(rng);
  return v;
}

TEST(CgKernels, MatchThePlainVectorOperations) {
  for (int n : {0, 1, 7, 8, 9, 23, 768}) {
    SCOPED_TRACE("n = " + std::to_string(n));
    std::mt19937 rng(n + 1);
    const VecX a = randomVector(n, rng), b = randomVector(n, rng);
    const double scale = 1.0 + a.squaredNorm() + b.squaredNorm();
    EXPECT_NEAR(cg_kernels::dot(n, a.data(), b.data()), a.dot(b), 1e-15 * scale);

    const VecX p = randomVector(n, rng), q = randomVector(n, rng);
    VecX x = a, r = b;
    const double alpha = 0.37;
    const double rr = cg_kernels::updateSolution(n, alpha, p.data(), q.data(), x.data(), r.data());
    const VecX x_ref = a + alpha * p, r_ref = b - alpha * q;
    EXPECT_LE((x - x_ref).norm(), 1e-15 * scale);
    EXPECT_LE((r - r_ref).norm(), 1e-15 * scale);
    EXPECT_NEAR(rr, r_ref.squaredNorm(), 1e-14 * scale);

    VecX d = p;
    cg_kernels::updateDirection(n, -1.5, q.data(), d.data());
    EXPECT_LE((d - (q - 1.5 * p)).norm(), 1e-15 * scale);
  }
}

// The recycled start's one-pass kernels must give what the separate dots and
// scaleAdds they replace give, to the bit: a guess must not depend on how
// its products were grouped.
TEST(CgKernels, DotsAndCombineEqualDotAndScaleAddExactly) {
  for (int n : {1, 7, 8, 9, 23, 768}) {
    std::mt19937 rng(n + 5);
    std::vector<VecX> v;
    const double* p[cg_kernels::kMaxVectors];
    for (int k = 0; k < cg_kernels::kMaxVectors; ++k) v.push_back(randomVector(n, rng));
    for (int k = 0; k < cg_kernels::kMaxVectors; ++k) p[k] = v[k].data();
    const VecX b = randomVector(n, rng), c = 3.0 * randomVector(cg_kernels::kMaxVectors, rng);
    for (int count = 1; count <= cg_kernels::kMaxVectors; ++count) {
      SCOPED_TRACE("n = " + std::to_string(n) + ", count = " + std::to_string(count));
      double out[cg_kernels::kMaxVectors];
      cg_kernels::dots(n, count, p, b.data(), out);
      VecX y(n), y_ref(n);
      cg_kernels::combine(n, count, p, c.data(), y.data());
      for (int k = 0; k < count; ++k) {
        EXPECT_EQ(out[k], cg_kernels::dot(n, p[k], b.data()));
        cg_kernels::scaleAdd(n, c[k], p[k], k == 0 ? 0.0 : 1.0, y_ref.data());
      }
      EXPECT_EQ(0, std::memcmp(y.data(), y_ref.data(), sizeof(double) * n));
    }
  }
}

TEST(CgKernels, BlockJacobiAppliesEachNodesSymmetricBlock) {
  for (int m : {1, 7, 8, 9, 256}) {
    SCOPED_TRACE("nodes = " + std::to_string(m));
    std::mt19937 rng(m);
    std::vector<SymBlock> blocks(m);
    std::vector<double> split(6 * m);
    const VecX entries = randomVector(6 * m, rng);
    for (int i = 0; i < m; ++i) {
      for (int e = 0; e < 6; ++e) {
        blocks[i].v[e] = entries[6 * i + e];
        split[e * m + i] = entries[6 * i + e];
      }
    }
    const double* inv[6];
    for (int e = 0; e < 6; ++e) inv[e] = split.data() + e * m;
    const VecX r = randomVector(3 * m, rng);  // split by component
    VecX z(3 * m);
    const double rz = cg_kernels::blockJacobi(m, inv, r.data(), z.data());
    double rz_ref = 0.0;
    for (int i = 0; i < m; ++i) {
      const Vec3 ri(r[i], r[m + i], r[2 * m + i]);
      const Vec3 zi = blocks[i] * ri;
      EXPECT_LE((Vec3(z[i], z[m + i], z[2 * m + i]) - zi).norm(), 1e-15 * (1.0 + zi.norm()));
      rz_ref += ri.dot(zi);
    }
    EXPECT_NEAR(rz, rz_ref, 1e-13 * (1.0 + std::abs(rz_ref)));
  }
}

TEST(ConstraintFilter, ApplySplitIsApplyOnTheSplitVector) {
  const int n = 11;
  ConstraintFilter filter;
  filter.reset(n);
  filter.eliminate(3);
  filter.eliminate(3);  // twice: still one pin
  filter.eliminate(10);
  const Vec3 normal = Vec3(1.0, 2.0, -2.0) / 3.0;
  filter.project(5, Mat3::Identity() - normal * normal.transpose());
  filter.project(0, Mat3::Zero());  // a sticking contact
  filter.project(10, Mat3::Zero());  // refused: a pin wins
  std::mt19937 rng(7);
  VecX v = randomVector(3 * n, rng);
  VecX split(3 * n);
  sweeps::splitComponents(v, split.data());
  filter.apply(v);
  filter.applySplit(split.data());
  VecX joined(3 * n);
  sweeps::joinComponents(split.data(), n, joined.data());
  EXPECT_LE((joined - v).norm(), 1e-15);
  EXPECT_EQ(v.segment<3>(9), Vec3::Zero());
  EXPECT_EQ(v.segment<3>(30), Vec3::Zero());
  EXPECT_EQ(v.segment<3>(0), Vec3::Zero());
  EXPECT_NEAR(normal.dot(v.segment<3>(15)), 0.0, 1e-15);
  // The mask constructor lists its pins too.
  ConstraintFilter from_mask(std::vector<char>{1, 0, 1});
  VecX w = VecX::Ones(9);
  from_mask.applySplit(w.data());
  EXPECT_EQ(w, (VecX(9) << 1, 0, 1, 1, 0, 1, 1, 0, 1).finished());
}

}  // namespace
}  // namespace cloth_sim
