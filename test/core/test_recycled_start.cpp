// The recycled warm start (recycled_start.hpp): with a fixed matrix and
// right-hand sides made of a few modes, the start from the kept answers is
// the answer itself once as many answers as modes are kept; it contains the
// linear extrapolation; it says so when it has nothing, and forgets on
// clear() and on a change of size.
#include <gtest/gtest.h>

#include <random>

#include "cloth_sim/recycled_start.hpp"

namespace cloth_sim {
namespace {

Eigen::MatrixXd spdMatrix(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd R(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) R(i, j) = g(rng);
  }
  return R * R.transpose() + n * Eigen::MatrixXd::Identity(n, n);
}

TEST(RecycledStart, ReproducesTheAnswerOfRightSidesInTheKeptSpan) {
  const int n = 30;
  const Eigen::MatrixXd A = spdMatrix(n, 1);
  const Eigen::LDLT<Eigen::MatrixXd> solve(A);
  std::mt19937 rng(2);
  std::normal_distribution<double> g(0.0, 1.0);
  VecX modes[3];
  for (VecX& m : modes) m = VecX::NullaryExpr(n, [&] { return g(rng); });
  // b_k = sum_j r_j^k m_j: three decaying modes, as a settling cloth's.
  auto rhs = [&](int k) {
    return VecX(std::pow(0.9, k) * modes[0] + std::pow(-0.7, k) * modes[1] +
                std::pow(0.5, k) * modes[2]);
  };
  RecycledStart start(4);
  VecX x;
  EXPECT_FALSE(start.guess(rhs(0), &x));  // nothing kept yet
  for (int k = 0; k < 3; ++k) {
    const VecX b = rhs(k);
    start.guess(b, &x);
    start.record(solve.solve(b), b);
  }
  EXPECT_EQ(start.size(), 3);
  const VecX b = rhs(3);
  ASSERT_TRUE(start.guess(b, &x));
  EXPECT_LT((A * x - b).norm(), 1e-9 * b.norm());
  // Full: the oldest goes, and it still holds (any three of them span).
  for (int k = 3; k < 8; ++k) {
    const VecX bk = rhs(k);
    start.guess(bk, &x);
    start.record(solve.solve(bk), bk);
  }
  EXPECT_EQ(start.size(), 4);
  const VecX b8 = rhs(8);
  ASSERT_TRUE(start.guess(b8, &x));
  EXPECT_LT((A * x - b8).norm(), 1e-8 * b8.norm());
}

TEST(RecycledStart, IsAtLeastAsGoodAsTheLinearExtrapolation) {
  // A slowly changing matrix (a settling cloth's), right sides along a
  // smooth path: the start's residual is no worse than 2 x1 - x0's.
  const int n = 40;
  const Eigen::MatrixXd A0 = spdMatrix(n, 3), dA = spdMatrix(n, 4) / n;
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  const VecX p = VecX::NullaryExpr(n, [&] { return g(rng); });
  const VecX q = VecX::NullaryExpr(n, [&] { return g(rng); });
  RecycledStart start;
  VecX answers[2];
  for (int k = 0; k < 12; ++k) {
    const double t = 0.05 * k;
    const Eigen::MatrixXd A = A0 + t * dA;
    const VecX b = std::cos(t) * p + std::sin(2.0 * t) * q;
    VecX x;
    const bool guessed = start.guess(b, &x);
    if (k >= 2) {
      ASSERT_TRUE(guessed);
      const VecX linear = 2.0 * answers[1] - answers[0];
      EXPECT_LE((A * x - b).norm(), (A * linear - b).norm() * (1.0 + 1e-9)) << "step " << k;
    }
    const VecX answer = A.ldlt().solve(b);
    start.record(answer, b);
    answers[0] = answers[1];
    answers[1] = answer;
  }
}

TEST(RecycledStart, ForgetsOnClearAndOnAChangeOfSize) {
  RecycledStart start;
  const VecX b = VecX::Ones(6);
  start.record(VecX::Constant(6, 2.0), b);
  VecX x;
  ASSERT_TRUE(start.guess(b, &x));
  EXPECT_LT((x - VecX::Constant(6, 2.0)).norm(), 1e-10);
  EXPECT_FALSE(start.guess(VecX::Ones(9), &x));  // another size: nothing to offer
  start.record(VecX::Ones(9), VecX::Ones(9));    // and recording it forgets the rest
  EXPECT_EQ(start.size(), 1);
  start.clear();
  EXPECT_EQ(start.size(), 0);
  EXPECT_FALSE(start.guess(VecX::Ones(9), &x));
}

}  // namespace
}  // namespace cloth_sim
