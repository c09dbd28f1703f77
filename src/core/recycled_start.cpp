#include "cloth_sim/recycled_start.hpp"

#include <algorithm>
#include <cmath>

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
    : capacity_(std::clamp(capacity, 1, kMaxCapacity)),
      answers_(capacity_),
      rights_(capacity_),
      gram_(Small::Zero(capacity_, capacity_)),
      projected_(SmallVector::Zero(capacity_)) {}

void RecycledStart::clear() {
  count_ = 0;
  next_ = 0;
  guessed_ = nullptr;
}

bool RecycledStart::guess(const VecX& b, VecX* x) {
  guessed_ = nullptr;
  if (count_ == 0 || b.size() != rights_[0].size()) return false;
  const int n = static_cast<int>(b.size());
  // One pass over b for its products with the kept sides, one to combine
  // the answers (a pass each: 12 passes over the vectors were 8 % of the
  // seed's step).
  // With b . b, for the Gram matrix's new entry when b is recorded.
  const double* v[cg_kernels::kMaxVectors];
  double products[cg_kernels::kMaxVectors];
  for (int k = 0; k < count_; ++k) v[k] = rights_[k].data();
  const bool with_b = count_ < cg_kernels::kMaxVectors;
  if (with_b) v[count_] = b.data();
  cg_kernels::dots(n, count_ + (with_b ? 1 : 0), v, b.data(), products);
  for (int k = 0; k < count_; ++k) projected_[k] = products[k];
  b_squared_ = with_b ? products[count_] : cg_kernels::dot(n, b.data(), b.data());
  guessed_ = b.data();
  if (!solveNormalEquations()) return false;
  x->resize(n);
  for (int k = 0; k < count_; ++k) v[k] = answers_[k].data();
  cg_kernels::combine(n, count_, v, coefficients_.data(), x->data());
  return true;
}

bool RecycledStart::solveNormalEquations() {
  // (B^T B + ridge) c = B^T b by Cholesky, written out: at most 8 x 8, where
  // a general factorization's set-up cost more than the solve (5 % of the
  // seed's step).
  const int m = count_;
  double max_diagonal = 0.0;
  for (int j = 0; j < m; ++j) max_diagonal = std::max(max_diagonal, gram_(j, j));
  const double ridge = kRidge * max_diagonal;
  double l[kMaxCapacity][kMaxCapacity];
  double y[kMaxCapacity];
  for (int j = 0; j < m; ++j) {
    double d = gram_(j, j) + ridge;
    for (int k = 0; k < j; ++k) d -= l[j][k] * l[j][k];
    if (!(d > 0.0)) return false;  // singular to round-off despite the ridge (or NaN)
    l[j][j] = std::sqrt(d);
    for (int i = j + 1; i < m; ++i) {
      double e = gram_(i, j);
      for (int k = 0; k < j; ++k) e -= l[i][k] * l[j][k];
      l[i][j] = e / l[j][j];
    }
  }
  for (int i = 0; i < m; ++i) {  // L y = B^T b
    double e = projected_[i];
    for (int k = 0; k < i; ++k) e -= l[i][k] * y[k];
    y[i] = e / l[i][i];
  }
  coefficients_.resize(m);
  for (int i = m - 1; i >= 0; --i) {  // L^T c = y
    double e = y[i];
    for (int k = i + 1; k < m; ++k) e -= l[k][i] * coefficients_[k];
    coefficients_[i] = e / l[i][i];
  }
  return coefficients_.allFinite();
}

void RecycledStart::record(const VecX& x, const VecX& b) { keep(x, b, nullptr); }

void RecycledStart::recordTaking(const VecX& x, VecX& b) { keep(x, b, &b); }

void RecycledStart::keep(const VecX& x, const VecX& b, VecX* take) {
  if (count_ > 0 && b.size() != rights_[0].size()) clear();
  const int n = static_cast<int>(b.size());
  // b's products with the kept sides: the guess's, if it was for this b (the
  // slot about to be overwritten is set below).
  const bool known = guessed_ == b.data();
  guessed_ = nullptr;
  const int slot = next_;
  answers_[slot] = x;
  if (take) {
    rights_[slot].swap(*take);  // b (the same vector) holds an old side now
  } else {
    rights_[slot] = b;
  }
  const double* kept = rights_[slot].data();
  count_ = std::min(count_ + 1, capacity_);
  next_ = (next_ + 1) % capacity_;
  for (int k = 0; k < count_; ++k) {
    const double d = !known     ? cg_kernels::dot(n, rights_[k].data(), kept)
                     : k == slot ? b_squared_
                                 : projected_[k];
    gram_(slot, k) = gram_(k, slot) = d;
  }
}

}  // namespace cloth_sim
