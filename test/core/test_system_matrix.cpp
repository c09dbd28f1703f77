// The system matrix's layout by direction (spring_layout.hpp): on every grid
// shape (chains, two-column strips, where a shear diagonal and a row share
// an offset, squares) its product and block diagonal equal the sums over
// its blocks written out per spring, with and without held damping axes;
// springs it cannot lay out are refused. Extra node blocks (contact friction)
// are part of both. The single-precision product is taken only where its
// rounding is far below CG's tolerance.
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>

#include "cloth_sim/forces.hpp"
#include "cloth_sim/spring_sweeps.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

Model gridModel(int rows, int cols) {
  Scene s = test::bareScene(rows, cols);
  test::enable(s, SpringType::Stretch, 1.0, 0.0);
  test::enable(s, SpringType::Shear, 1.0, 0.0);
  test::enable(s, SpringType::Bend, 1.0, 0.0);
  return buildModel(s);
}

Vec3 unitVector(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Vec3 u(g(rng), g(rng), g(rng));
  return u.normalized();
}

TEST(SystemMatrix, ProductAndDiagonalAreTheSumsOfTheBlocksOnEveryGridShape) {
  const int shapes[][2] = {{1, 6}, {6, 1}, {2, 2}, {2, 5}, {5, 2}, {3, 3}, {3, 4}, {9, 7}};
  for (const auto& shape : shapes) {
    for (bool held : {false, true}) {
      SCOPED_TRACE(std::to_string(shape[0]) + "x" + std::to_string(shape[1]) +
                   (held ? " with held damping axes" : ""));
      const Model m = gridModel(shape[0], shape[1]);
      const int n = m.numNodes(), springs = static_cast<int>(m.springs.size());
      ASSERT_GT(springs, 0);
      std::mt19937 rng(n + springs);
      std::uniform_real_distribution<double> coefficient(-2.0, 3.0);
      SystemMatrix A;
      A.resize(m.layout);
      A.reset(m.mass, 0.25);
      std::vector<Mat3> blocks(springs);
      std::vector<Mat3> extra(n, Mat3::Zero());
      for (int k = 0; k < springs; ++k) {
        const double iso = coefficient(rng), axis = coefficient(rng);
        const Vec3 u = unitVector(rng);
        A.setCoupling(k, iso, axis, u);
        blocks[k] = iso * Mat3::Identity() + axis * u * u.transpose();
        if (held) {
          const double c = coefficient(rng);
          const Vec3 w = unitVector(rng);
          A.setDampingAxis(k, c, w);
          blocks[k] += c * w * w.transpose();
        }
      }
      // Extra node blocks (a contact's friction): on the first and last node.
      for (int node : {0, n - 1}) {
        const Vec3 w = unitVector(rng);
        const Mat3 block = coefficient(rng) * Mat3::Identity() + w * w.transpose();
        A.addNodeBlock(node, block);
        extra[node] += block;
      }
      VecX x(3 * n);
      for (int k = 0; k < x.size(); ++k) x[k] = coefficient(rng);
      VecX y_ref(3 * n);
      std::vector<Mat3> diag(n);
      for (int i = 0; i < n; ++i) {
        diag[i] = (m.mass[i] + 0.25) * Mat3::Identity() + extra[i];
        y_ref.segment<3>(3 * i) = diag[i] * x.segment<3>(3 * i);
      }
      for (int k = 0; k < springs; ++k) {
        const Spring& s = m.springs[k];
        const Vec3 t = blocks[k] * (x.segment<3>(3 * s.i) - x.segment<3>(3 * s.j));
        y_ref.segment<3>(3 * s.i) += t;
        y_ref.segment<3>(3 * s.j) -= t;
        diag[s.i] += blocks[k];
        diag[s.j] += blocks[k];
        EXPECT_LE((A.coupling(k) - blocks[k]).norm(), 1e-15 * (1.0 + blocks[k].norm()));
      }
      VecX y;
      A.multiplyAll(x, y);
      EXPECT_LE((y - y_ref).norm(), 1e-14 * y_ref.norm());
      for (int i = 0; i < n; ++i) {
        EXPECT_LE((A.fullDiag(i) - diag[i]).norm(), 1e-14 * diag[i].norm()) << "node " << i;
      }
    }
  }
}

// The single-precision product (system_matrix_single.cpp): taken only where
// its rounding is far below CG's tolerance (soft couplings, loose
// tolerance), and then within float rounding of the double product; stiff
// couplings or a tight tolerance keep the double product to the bit, and so
// does a matrix changed since the choice.
TEST(SystemMatrix, SinglePrecisionProductOnlyWhereItsRoundingIsFarBelowTheTolerance) {
  const int shapes[][2] = {{1, 6}, {2, 5}, {9, 7}};
  for (const auto& shape : shapes) {
    for (bool held : {false, true}) {
      SCOPED_TRACE(std::to_string(shape[0]) + "x" + std::to_string(shape[1]) +
                   (held ? " with held damping axes" : ""));
      const Model m = gridModel(shape[0], shape[1]);
      const int n = m.numNodes(), springs = static_cast<int>(m.springs.size());
      std::mt19937 rng(3 * n + held);
      std::uniform_real_distribution<double> unit(0.0, 1.0);
      auto fill = [&](SystemMatrix& A, double scale) {
        A.resize(m.layout);
        A.reset(m.mass);
        std::vector<double> coupled(n, 0.0);
        for (int k = 0; k < springs; ++k) {
          const double iso = scale * unit(rng), axis = scale * unit(rng);
          A.setCoupling(k, iso, axis, unitVector(rng));
          double norm = iso + axis;
          if (held) {
            const double c = scale * unit(rng);
            A.setDampingAxis(k, c, unitVector(rng));
            norm += c;
          }
          coupled[m.springs[k].i] += norm;
          coupled[m.springs[k].j] += norm;
        }
        double ratio = 0.0;
        for (int i = 0; i < n; ++i) ratio = std::max(ratio, coupled[i] / m.mass[i]);
        return ratio;
      };
      VecX x(3 * n);
      for (int k = 0; k < x.size(); ++k) x[k] = unit(rng) - 0.5;
      std::vector<double> xs(3 * n), ys(3 * n);
      sweeps::splitComponents(x, xs.data());
      auto product = [&](const SystemMatrix& A) {
        A.multiplySplit(xs.data(), ys.data());
        VecX y(3 * n);
        sweeps::joinComponents(ys.data(), n, y.data());
        return y;
      };

      // Soft: couplings about 20 times the node mass.
      SystemMatrix soft;
      const double ratio = fill(soft, 20.0 * m.mass[0]);
      EXPECT_NEAR(soft.couplingToMassRatio(), ratio, 1e-12 * ratio);
      VecX exact;
      soft.multiplyAll(x, exact);
      ASSERT_TRUE(soft.singlePrecisionFits(1e-2));
      soft.allowSinglePrecision(1e-2);
      EXPECT_EQ(product(soft), exact);  // the first product of a solve: double
      const VecX rounded = product(soft);
      const double size = (ratio + 1.0) * m.mass[0] * x.lpNorm<Eigen::Infinity>();
      EXPECT_GT((rounded - exact).lpNorm<Eigen::Infinity>(), 0.0);  // float was used
      EXPECT_LT((rounded - exact).lpNorm<Eigen::Infinity>(), 1e-6 * size);
      // A tight tolerance: double, to the bit.
      EXPECT_FALSE(soft.singlePrecisionFits(1e-8));
      soft.allowSinglePrecision(1e-8);
      for (int k = 0; k < 3; ++k) EXPECT_EQ(product(soft), exact);
      // Changed after float copies were made: the copies are made anew.
      soft.allowSinglePrecision(1e-2);
      product(soft);
      product(soft);
      soft.setCoupling(0, 1.0 * m.mass[0], 0.5 * m.mass[0], Vec3::UnitX());
      soft.multiplyAll(x, exact);
      EXPECT_LT((product(soft) - exact).lpNorm<Eigen::Infinity>(), 1e-6 * size);

      // Stiff: couplings 1e7 times the node mass (stretch 1e7 at dt 1/30 on
      // the demo cloth is ~3e7): double at any tolerance CG is given.
      SystemMatrix stiff;
      fill(stiff, 1e7 * m.mass[0]);
      EXPECT_FALSE(stiff.singlePrecisionFits(1e-1));
      stiff.allowSinglePrecision(1e-1);
      stiff.multiplyAll(x, exact);
      for (int k = 0; k < 3; ++k) EXPECT_EQ(product(stiff), exact);
    }
  }
}

TEST(SpringLayout, GroupsAGridByDirectionAndRefusesSpringsItCannotLayOut) {
  const Model m = gridModel(4, 5);
  // stretch: rows and columns; shear: both diagonals; bend: rows and columns.
  EXPECT_EQ(m.layout->directions.size(), 6u);
  for (size_t k = 0; k < m.springs.size(); ++k) {
    const SpringSlot& slot = m.layout->slot[k];
    const SpringDirection& d = m.layout->directions[slot.direction];
    EXPECT_EQ(d.type, m.springs[k].type);
    EXPECT_EQ(slot.other - slot.node, d.offset);
    EXPECT_EQ(d.valid[slot.node], 1.0);
    EXPECT_EQ(d.rest_length[slot.node], m.springs[k].rest_length);
  }
  std::vector<Spring> springs(1);
  springs[0].i = springs[0].j = 2;
  EXPECT_THROW(layOutSprings(4, springs), std::invalid_argument);  // a node to itself
  springs[0].j = 4;
  EXPECT_THROW(layOutSprings(4, springs), std::invalid_argument);  // outside the nodes
  springs[0].j = 3;
  springs.push_back(springs[0]);
  std::swap(springs[1].i, springs[1].j);
  EXPECT_THROW(layOutSprings(4, springs), std::invalid_argument);  // the same two nodes twice
  springs[1].type = SpringType::Bend;
  EXPECT_EQ(layOutSprings(4, springs)->directions.size(), 2u);  // another type: allowed
}

}  // namespace
}  // namespace cloth_sim
