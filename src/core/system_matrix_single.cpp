// The system matrix's product in single precision, for CG solves whose
// tolerance is far above what float rounding does to it (see
// SystemMatrix::singlePrecisionFits). The product's sweeps are bound by
// their loads and instructions (docs/profile.md): in float a vector holds
// twice the lanes, and the product on a 32 x 32 cloth takes 3.9 us where
// double takes 8.0. The node blocks (mass, friction) stay double.
#include <algorithm>
#include <cmath>

#include "cloth_sim/system_matrix.hpp"
#include "direction_terms.hpp"
#include "parallel.hpp"
#include "vectorised.hpp"

namespace cloth_sim {

namespace {

/// Rounding of a product's term relative to the coupling it comes from: a
/// few float roundings (2^-24 each), kept 10x below the CG tolerance.
constexpr double kSingleRounding = 40.0 * 0x1p-24;

CLOTH_SIM_VECTORISED
void toSingle(int count, const double* __restrict in, float* __restrict out) {
  for (int p = 0; p < count; ++p) out[p] = static_cast<float>(in[p]);
}

/// One direction's coupling terms (direction_terms.hpp), in float.
CLOTH_SIM_VECTORISED
void directionTermsSingle(int count, int offset, const float* __restrict x0,
                          const float* __restrict x1, const float* __restrict x2,
                          const float* __restrict iso, const float* __restrict axis,
                          const float* __restrict u0, const float* __restrict u1,
                          const float* __restrict u2, const float* __restrict c,
                          const float* __restrict w0, const float* __restrict w1,
                          const float* __restrict w2, float* __restrict t0,
                          float* __restrict t1, float* __restrict t2) {
  detail::directionTerms(count, offset, x0, x1, x2, iso, axis, u0, u1, u2, c, w0, w1, w2, t0,
                         t1, t2);
}

/// Each t has its offset's zeros before slot 0 and zeros in its last slots:
/// t[p] - t[p - o] is slot p's term on its lower end minus that of the slot
/// whose upper end p is.

/// sum (first: =, else +=) the differences of directions a and b (b may be
/// null): the pairs before the last.
CLOTH_SIM_VECTORISED
void addDifferencesSingle(int n, const float* __restrict ta, int oa, const float* __restrict tb,
                          int ob, bool first, float* __restrict sum) {
  if (tb && first) {
    for (int p = 0; p < n; ++p) sum[p] = (ta[p] - ta[p - oa]) + (tb[p] - tb[p - ob]);
  } else if (tb) {
    for (int p = 0; p < n; ++p) sum[p] += (ta[p] - ta[p - oa]) + (tb[p] - tb[p - ob]);
  } else if (first) {
    for (int p = 0; p < n; ++p) sum[p] = ta[p] - ta[p - oa];
  } else {
    for (int p = 0; p < n; ++p) sum[p] += ta[p] - ta[p - oa];
  }
}

/// y = m x + (sum +) the last pair's differences, in double (sum null: the
/// only pair).
CLOTH_SIM_VECTORISED
void finishSingle(int n, const float* __restrict ta, int oa, const float* __restrict tb, int ob,
                  const float* __restrict sum, const double* __restrict m,
                  const double* __restrict x, double* __restrict y) {
  if (tb && sum) {
    for (int p = 0; p < n; ++p) {
      const float t = sum[p] + ((ta[p] - ta[p - oa]) + (tb[p] - tb[p - ob]));
      y[p] = m[p] * x[p] + static_cast<double>(t);
    }
  } else if (sum) {
    for (int p = 0; p < n; ++p) {
      y[p] = m[p] * x[p] + static_cast<double>(sum[p] + (ta[p] - ta[p - oa]));
    }
  } else if (tb) {
    for (int p = 0; p < n; ++p) {
      y[p] = m[p] * x[p] + static_cast<double>((ta[p] - ta[p - oa]) + (tb[p] - tb[p - ob]));
    }
  } else {
    for (int p = 0; p < n; ++p) y[p] = m[p] * x[p] + static_cast<double>(ta[p] - ta[p - oa]);
  }
}

}  // namespace

double SystemMatrix::couplingToMassRatio() const {
  if (ratio_valid_) return ratio_;
  if (std::isfinite(psd_coupling_bound_) && node_scale_range_.first > 0.0) {
    // The assembler's bound over the lightest node: the per-node sums below
    // on a cloth of equal masses (its interior nodes' sums are the bound),
    // and no pass over the slots (5 % of the seed's step).
    ratio_ = psd_coupling_bound_ / node_scale_range_.first;
    ratio_valid_ = true;
    return ratio_;
  }
  const int n = numNodes();
  // Per node: its node block and the norms (bounds) of the couplings at
  // both ends of each slot.
  std::vector<double>& coupled = coupled_;
  coupled.assign(n, 0.0);
  for (size_t k = 0; k < coefficients_.size(); ++k) {
    const Coefficients& d = coefficients_[k];
    const int o = layout_->directions[k].offset;
    for (int p = 0; p + o < n; ++p) {
      double norm = std::abs(d.iso[p]) + std::abs(d.axis[p]);
      if (has_damping_axes_) norm += std::abs(d.c[p]);
      coupled[p] += norm;
      coupled[p + o] += norm;
    }
  }
  double ratio = 0.0;
  for (int i = 0; i < n; ++i) {
    // A node block of zero or less with couplings: no bound, stay double.
    if (coupled[i] > 0.0) {
      ratio = node_scale_[i] > 0.0 ? std::max(ratio, coupled[i] / node_scale_[i]) : INFINITY;
    }
  }
  ratio_ = ratio;
  ratio_valid_ = true;
  return ratio_;
}

double SystemMatrix::relaxedSingleRounding() const {
  // Without extra node blocks or pair terms, A = node blocks + PSD couplings
  // >= the node blocks; the ratio is then the assembler's bound's.
  const auto [lightest, heaviest] = node_scale_range_;
  if (!layout_ || !node_blocks_.empty() || !pair_terms_.empty() ||
      !std::isfinite(psd_coupling_bound_) || !(lightest > 0.0) || !std::isfinite(heaviest)) {
    return INFINITY;
  }
  return kSingleRounding * couplingToMassRatio() * (heaviest / lightest);
}

void SystemMatrix::multiplySplitFloat(const double* xs, double* ys) const {
  if (!single_valid_) makeSingleCopies();
  multiplySplitSingle(xs, ys, nullptr);
}

void SystemMatrix::multiplySplitFloat(const double* xs, const float* xf, double* ys) const {
  if (!single_valid_) makeSingleCopies();
  multiplySplitSingle(xs, ys, xf);
}

bool SystemMatrix::singlePrecisionFits(double tolerance) const {
  // Below kSingleRounding no cloth fits (its ratio would be under 1): the
  // bound's pass is skipped.
  return layout_ && tolerance >= kSingleRounding &&
         couplingToMassRatio() * kSingleRounding <= tolerance;
}

void SystemMatrix::multiplySplit(const double* xs, double* ys) const {
  if (single_tolerance_ > 0.0 && ++single_products_ > 1 &&
      singlePrecisionFits(single_tolerance_)) {
    if (!single_valid_) makeSingleCopies();
    multiplySplitSingle(xs, ys, nullptr);
  } else {
    multiplySplitDouble(xs, ys);
  }
}

void SystemMatrix::sizeSingleCopies() const {
  const int n = numNodes();
  single_dirs_.resize(coefficients_.size());
  for (size_t k = 0; k < coefficients_.size(); ++k) {
    SingleDirection& s = single_dirs_[k];
    const int o = layout_->directions[k].offset;
    const size_t terms = 3 * static_cast<size_t>(n + o);
    if (s.terms.size() != terms) s.terms.assign(terms, 0.0f);  // the padding stays zero
    // Slots a sweep does not write stay zero, as their double coefficients.
    s.coefficients.resize((has_damping_axes_ ? 9 : 5) * static_cast<size_t>(n), 0.0f);
  }
}

float* SystemMatrix::singleCoefficients(int direction) {
  if (!single_wanted_ || has_damping_axes_ || !layout_) return nullptr;
  if (single_dirs_.size() != coefficients_.size() ||
      single_dirs_[direction].coefficients.size() != 5 * static_cast<size_t>(numNodes())) {
    sizeSingleCopies();
  }
  return single_dirs_[direction].coefficients.data();
}

void SystemMatrix::makeSingleCopies() const {
  const int n = numNodes();
  sizeSingleCopies();
  for (size_t k = 0; k < coefficients_.size(); ++k) {
    const Coefficients& d = coefficients_[k];
    SingleDirection& s = single_dirs_[k];
    float* out = s.coefficients.data();
    for (const std::vector<double>* a : {&d.iso, &d.axis, &d.u[0], &d.u[1], &d.u[2]}) {
      toSingle(n, a->data(), out);
      out += n;
    }
    if (has_damping_axes_) {
      for (const std::vector<double>* a : {&d.c, &d.w[0], &d.w[1], &d.w[2]}) {
        toSingle(n, a->data(), out);
        out += n;
      }
    }
  }
  single_valid_ = true;
}

void SystemMatrix::singleTerms(size_t k, const float* x, int first, int last) const {
  const int n = numNodes();
  SingleDirection& s = single_dirs_[k];
  const int o = layout_->directions[k].offset;
  const int end = std::min(last, n - o);
  if (end <= first) return;
  const float* c = s.coefficients.data() + first;
  const bool held = s.coefficients.size() == 9 * static_cast<size_t>(n);
  const size_t stride = static_cast<size_t>(n + o);
  float* t = s.terms.data() + o + first;
  const float* xp = x + first;
  directionTermsSingle(end - first, o, xp, xp + n, xp + 2 * n, c, c + n, c + 2 * n, c + 3 * n,
                       c + 4 * n, held ? c + 5 * n : nullptr, held ? c + 6 * n : nullptr,
                       held ? c + 7 * n : nullptr, held ? c + 8 * n : nullptr, t, t + stride,
                       t + 2 * stride);
}

void SystemMatrix::singlePairSums(size_t k, int first, int last, const double* xs,
                                  double* ys) const {
  const int n = numNodes();
  const size_t count = single_dirs_.size();
  const bool has_b = k + 1 < count;
  const int oa = layout_->directions[k].offset;
  const int ob = has_b ? layout_->directions[k + 1].offset : 0;
  const size_t stride_a = static_cast<size_t>(n + oa);
  const size_t stride_b = has_b ? static_cast<size_t>(n + ob) : 0;
  const float* ta = single_dirs_[k].terms.data() + oa + first;
  const float* tb = has_b ? single_dirs_[k + 1].terms.data() + ob + first : nullptr;
  const int m = last - first;
  for (int comp = 0; comp < 3; ++comp) {
    const float* a = ta + comp * stride_a;
    const float* b = tb ? tb + comp * stride_b : nullptr;
    float* partial = sum_single_.data() + comp * n + first;
    if (k + 2 >= count) {
      finishSingle(m, a, oa, b, ob, k == 0 ? nullptr : partial, node_scale_.data() + first,
                   xs + comp * n + first, ys + comp * n + first);
    } else {
      addDifferencesSingle(m, a, oa, b, ob, k == 0, partial);
    }
  }
}

void SystemMatrix::multiplySplitSingle(const double* xs, double* ys, const float* xf) const {
  const int n = numNodes();
  single_used_ = true;
  sum_single_.resize(3 * static_cast<size_t>(n));
  const size_t count = single_dirs_.size();
  if (!xf) x_single_.resize(3 * static_cast<size_t>(n));
  const float* x = xf ? xf : x_single_.data();
  if (count == 0) {
    for (int i = 0; i < 3 * n; ++i) ys[i] = node_scale_[i % n] * xs[i];
  } else if (const int parts = parallel::partsFor(threads_, n); parts == 1) {
    // Two directions' terms at a time, then their differences into the sums
    // while the terms are still in cache; the last pair's with y = m x.
    if (!xf) toSingle(3 * n, xs, x_single_.data());
    for (size_t k = 0; k < count; k += 2) {
      singleTerms(k, x, 0, n);
      if (k + 1 < count) singleTerms(k + 1, x, 0, n);
      singlePairSums(k, 0, n, xs, ys);
    }
  } else {
    // On threads: every direction's terms over a range of slots, then (once
    // all are written) the sums over a range of nodes; each entry as above.
#pragma omp parallel num_threads(parts)
    {
      int first = 0, last = n;
      parallel::range(parallel::thread(), parallel::team(), n, &first, &last);
      if (!xf) {
        for (int c = 0; c < 3; ++c) {
          toSingle(last - first, xs + c * n + first, x_single_.data() + c * n + first);
        }
#pragma omp barrier
      }
      for (size_t k = 0; k < count; ++k) singleTerms(k, x, first, last);
#pragma omp barrier
      for (size_t k = 0; k < count; k += 2) singlePairSums(k, first, last, xs, ys);
    }
  }
  addNodeBlocksAndPairTerms(xs, ys);
}

}  // namespace cloth_sim
