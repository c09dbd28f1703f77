#include "cloth_sim/recycled_start.hpp"

#include <algorithm>

#include "cloth_sim/cg_kernels.hpp"

namespace cloth_sim {

namespace {

/// The least-squares problem's ridge, relative to the largest |b_i|^2: the
/// kept right-hand sides of a cloth at rest are nearly parallel, and the
/// normal equations square their conditioning. This small a ridge only
/// bounds c where B is singular to round-off.
constexpr double kRidge = 1e-12;

}  // namespace

RecycledStart::RecycledStart(int capacity)
    : capacity_(std::max(capacity, 1)),
      answers_(capacity_),
      rights_(capacity_),
      gram_(Eigen::MatrixXd::Zero(capacity_, capacity_)),
      projected_(Eigen::VectorXd::Zero(capacity_)) {}

void RecycledStart::clear() {
  count_ = 0;
  next_ = 0;
  guessed_ = nullptr;
}

bool RecycledStart::guess(const VecX& b, VecX* x) {
  guessed_ = nullptr;
  if (count_ == 0 || b.size() != rights_[0].size()) return false;
  const int n = static_cast<int>(b.size());
  for (int k = 0; k < count_; ++k) projected_[k] = cg_kernels::dot(n, rights_[k].data(), b.data());
  guessed_ = b.data();
  normal_ = gram_.topLeftCorner(count_, count_);
  normal_.diagonal().array() += kRidge * normal_.diagonal().maxCoeff();
  coefficients_ = normal_.ldlt().solve(projected_.head(count_));
  if (!coefficients_.allFinite()) return false;
  x->resize(n);
  for (int k = 0; k < count_; ++k) {
    cg_kernels::scaleAdd(n, coefficients_[k], answers_[k].data(), k == 0 ? 0.0 : 1.0, x->data());
  }
  return true;
}

void RecycledStart::record(const VecX& x, const VecX& b) {
  if (count_ > 0 && b.size() != rights_[0].size()) clear();
  const int n = static_cast<int>(b.size());
  // b's products with the kept sides: the guess's, if it was for this b (the
  // slot about to be overwritten is set below).
  const bool known = guessed_ == b.data();
  guessed_ = nullptr;
  const int slot = next_;
  answers_[slot] = x;
  rights_[slot] = b;
  count_ = std::min(count_ + 1, capacity_);
  next_ = (next_ + 1) % capacity_;
  for (int k = 0; k < count_; ++k) {
    const double d = k != slot && known ? projected_[k]
                                        : cg_kernels::dot(n, rights_[k].data(), b.data());
    gram_(slot, k) = gram_(k, slot) = d;
  }
}

}  // namespace cloth_sim
