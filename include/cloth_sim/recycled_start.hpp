// A warm start for a run of linear solves A_n x_n = b_n whose matrices change
// little from one to the next (a cloth settling or at rest): the start is a
// combination of the last few answers, x0 = V c, with c minimising
// |B c - b_n| where B holds their right-hand sides. B = A_old V stands in
// for A_n V, which would cost a product per stored answer: the projection of
// Fischer (1998, "Projection techniques for iterative solution of Ax = b with
// successive right-hand sides") with the earlier matrices' products, known
// for free. Its span holds the linear extrapolation 2 x_n-1 - x_n-2, and it
// finds better where the motion is a few decaying modes (the seed scene at
// CG 1e-8: 5.0 -> 3.2 CG iterations a step with 6 answers kept).
#pragma once

#include <vector>

#include <Eigen/Dense>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

class RecycledStart {
 public:
  /// Keeps up to `capacity` answers (1 to kMaxCapacity).
  explicit RecycledStart(int capacity = kDefaultCapacity);
  static constexpr int kDefaultCapacity = 6;
  static constexpr int kMaxCapacity = 8;

  /// Forgets every answer (a new step size, say).
  void clear();
  /// Keys the kept answers to a step size: another one than theirs forgets them.
  void useFor(double step) {
    if (step != step_) clear();
    step_ = step;
  }
  int size() const { return count_; }

  /// x = V c for right-hand side b. False (x untouched) with no answers kept,
  /// b of another size or a non-finite combination.
  bool guess(const VecX& b, VecX* x);
  /// Keeps answer x of right-hand side b, dropping the oldest when full;
  /// another size than the kept ones' clears them first. After guess(b),
  /// the same b's products with the kept sides are reused.
  void record(const VecX& x, const VecX& b);
  /// The same, b taken by a swap instead of a copy: b holds some earlier
  /// right-hand side (or nothing) afterwards.
  void recordTaking(const VecX& x, VecX& b);

 private:
  void keep(const VecX& x, const VecX& b, VecX* take);  ///< record's; takes b with `take`
  int capacity_;
  int count_ = 0;
  int next_ = 0;                  ///< the slot the next record overwrites
  double step_ = 0.0;             ///< useFor's
  std::vector<VecX> answers_;     ///< V, by slot
  std::vector<VecX> rights_;      ///< B, by slot
  // At most kMaxCapacity square: kept on the stack, no allocation a step.
  using Small = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxCapacity, kMaxCapacity>;
  using SmallVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxCapacity, 1>;
  Small gram_;                    ///< B^T B by slot
  SmallVector projected_;         ///< B^T b of the last guess, by slot
  const double* guessed_ = nullptr;  ///< that b's data (record reuses projected_)
  double b_squared_ = 0.0;           ///< that b's b . b
  SmallVector coefficients_;
  /// coefficients_ from the kept Gram matrix and projected_ (false: singular).
  bool solveNormalEquations();
};

}  // namespace cloth_sim
