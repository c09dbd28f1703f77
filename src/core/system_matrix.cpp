#include "cloth_sim/system_matrix.hpp"

#include <algorithm>

#include "cloth_sim/spring_sweeps.hpp"
#include "direction_terms.hpp"
#include "parallel.hpp"
#include "vectorised.hpp"

namespace cloth_sim {

namespace {

/// One direction's coupling terms (direction_terms.hpp), in double.
CLOTH_SIM_VECTORISED
void directionTerms(int count, int offset, const double* __restrict x0,
                    const double* __restrict x1, const double* __restrict x2,
                    const double* __restrict iso, const double* __restrict axis,
                    const double* __restrict u0, const double* __restrict u1,
                    const double* __restrict u2, const double* __restrict c,
                    const double* __restrict w0, const double* __restrict w1,
                    const double* __restrict w2, double* __restrict t0,
                    double* __restrict t1, double* __restrict t2) {
  detail::directionTerms(count, offset, x0, x1, x2, iso, axis, u0, u1, u2, c, w0, w1, w2, t0,
                         t1, t2);
}

/// Per slot p < count: the coupling block's 6 entries (xx, yy, zz, xy, xz,
/// yz; SymBlock's order) into s[0..5] at p; held damping axes where c is given.
CLOTH_SIM_VECTORISED
void blockEntries(int count, const double* __restrict iso, const double* __restrict axis,
                  const double* __restrict u0, const double* __restrict u1,
                  const double* __restrict u2, const double* __restrict c,
                  const double* __restrict w0, const double* __restrict w1,
                  const double* __restrict w2, double* __restrict s0, double* __restrict s1,
                  double* __restrict s2, double* __restrict s3, double* __restrict s4,
                  double* __restrict s5) {
  for (int p = 0; p < count; ++p) {
    const double a = axis[p], i = iso[p];
    s0[p] = i + a * u0[p] * u0[p];
    s1[p] = i + a * u1[p] * u1[p];
    s2[p] = i + a * u2[p] * u2[p];
    s3[p] = a * u0[p] * u1[p];
    s4[p] = a * u0[p] * u2[p];
    s5[p] = a * u1[p] * u2[p];
  }
  if (!c) return;
  for (int p = 0; p < count; ++p) {
    const double e = c[p];
    s0[p] += e * w0[p] * w0[p];
    s1[p] += e * w1[p] * w1[p];
    s2[p] += e * w2[p] * w2[p];
    s3[p] += e * w0[p] * w1[p];
    s4[p] += e * w0[p] * w2[p];
    s5[p] += e * w1[p] * w2[p];
  }
}

}  // namespace

void SystemMatrix::resize(const std::shared_ptr<const SpringLayout>& layout) {
  if (layout != layout_) {
    layout_ = layout;
    const int n = layout->num_nodes;
    coefficients_.assign(layout->directions.size(), {});
    for (Coefficients& d : coefficients_) {
      for (std::vector<double>* a : {&d.iso, &d.axis, &d.u[0], &d.u[1], &d.u[2]}) {
        a->assign(n, 0.0);
      }
    }
    node_scale_.assign(n, 0.0);
    has_damping_axes_ = false;
    node_blocks_.clear();
    pair_terms_.clear();
    single_dirs_.clear();
  }
  changed();
}

void SystemMatrix::useDampingAxes() {
  for (Coefficients& d : coefficients_) {
    if (d.c.empty()) {
      for (std::vector<double>* a : {&d.c, &d.w[0], &d.w[1], &d.w[2]}) a->assign(numNodes(), 0.0);
    }
  }
  has_damping_axes_ = true;
  changed();
}

void SystemMatrix::reset(const std::vector<double>& mass, double extra_diagonal) {
  double lightest = INFINITY, heaviest = 0.0;
  for (size_t i = 0; i < node_scale_.size(); ++i) {
    node_scale_[i] = mass[i] + extra_diagonal;
    lightest = std::min(lightest, node_scale_[i]);
    heaviest = std::max(heaviest, node_scale_[i]);
  }
  node_scale_range_ = {lightest, heaviest};
  node_blocks_.clear();
  pair_terms_.clear();
  has_damping_axes_ = false;
  single_wanted_ = single_used_;
  single_used_ = false;
  changed();
}

const std::vector<SymBlock>& SystemMatrix::fullDiagonal() const {
  if (full_diag_valid_) return full_diag_;
  // By component (xx yy zz xy xz yz), each direction's blocks added to both ends.
  const int n = numNodes();
  diag_split_.assign(6 * static_cast<size_t>(n), 0.0);
  for (int c = 0; c < 3; ++c) std::copy(node_scale_.begin(), node_scale_.end(), diag_split_.begin() + c * n);
  const bool held = has_damping_axes_;
  for (size_t k = 0; k < coefficients_.size(); ++k) {
    const Coefficients& d = coefficients_[k];
    const int o = layout_->directions[k].offset;
    terms_.reset(n, o, 6);
    blockEntries(n - o, d.iso.data(), d.axis.data(), d.u[0].data(), d.u[1].data(),
                 d.u[2].data(), held ? d.c.data() : nullptr, held ? d.w[0].data() : nullptr,
                 held ? d.w[1].data() : nullptr, held ? d.w[2].data() : nullptr, terms_.term(0),
                 terms_.term(1), terms_.term(2), terms_.term(3), terms_.term(4), terms_.term(5));
    terms_.addSums(diag_split_.data());
  }
  full_diag_.resize(n);
  for (int i = 0; i < n; ++i) {
    for (int c = 0; c < 6; ++c) full_diag_[i].v[c] = diag_split_[c * n + i];
  }
  for (const auto& [node, block] : node_blocks_) full_diag_[node].addScaled(1.0, block);
  for (const PairTerm& t : pair_terms_) {
    for (int k = 0; k < 4; ++k) full_diag_[t.node[k]].addScaled(1.0, t.diagonal(k));
  }
  full_diag_valid_ = true;
  return full_diag_;
}

void SystemMatrix::multiplyAll(const VecX& x_in, VecX& y_out) const {
  const int n = numNodes();
  y_out.resize(3 * n);
  x_split_.resize(3 * n);
  y_split_.resize(3 * n);
  sweeps::splitComponents(x_in, x_split_.data());
  multiplySplitDouble(x_split_.data(), y_split_.data());
  sweeps::joinComponents(y_split_.data(), n, y_out.data());
}

void SystemMatrix::multiplySplitDouble(const double* xs, double* ys) const {
  const int n = numNodes();
  const size_t count = coefficients_.size();
  direction_terms_.resize(count);
  const bool held = has_damping_axes_;
  for (size_t k = 0; k < count; ++k) direction_terms_[k].ensure(n, layout_->directions[k].offset);
  // Slots [first, last) of every direction (slot p: its lower end, node p).
  auto terms = [&](int first, int last) {
    for (size_t k = 0; k < count; ++k) {
      const Coefficients& d = coefficients_[k];
      const int o = layout_->directions[k].offset;
      const int end = std::min(last, n - o);
      if (end <= first) continue;
      sweeps::PaddedTerms& t = direction_terms_[k];
      const int f = first;
      directionTerms(end - f, o, xs + f, xs + n + f, xs + 2 * n + f, d.iso.data() + f,
                     d.axis.data() + f, d.u[0].data() + f, d.u[1].data() + f, d.u[2].data() + f,
                     held ? d.c.data() + f : nullptr, held ? d.w[0].data() + f : nullptr,
                     held ? d.w[1].data() + f : nullptr, held ? d.w[2].data() + f : nullptr,
                     t.term(0) + f, t.term(1) + f, t.term(2) + f);
    }
  };
  // The node blocks m I and the directions two at a time: a pass over y per
  // pair instead of one per direction. Nodes [first, last).
  auto sums = [&](int first, int last) {
    if (count == 0) {
      for (int c = 0; c < 3; ++c) {
        for (int i = first; i < last; ++i) ys[c * n + i] = node_scale_[i] * xs[c * n + i];
      }
    }
    for (size_t k = 0; k < count; k += 2) {
      const sweeps::PaddedTerms* second = k + 1 < count ? &direction_terms_[k + 1] : nullptr;
      if (k == 0) {
        sweeps::PaddedTerms::sumDifferences(node_scale_.data(), xs, direction_terms_[k], second,
                                            ys, first, last);
      } else {
        sweeps::PaddedTerms::addPairDifferences(direction_terms_[k], second, ys, first, last);
      }
    }
  };
  const int parts = parallel::partsFor(threads_, n);
  if (parts == 1) {
    terms(0, n);
    sums(0, n);
  } else {
    // Each entry as one thread computes it: the same product on any count.
#pragma omp parallel num_threads(parts)
    {
      int first = 0, last = n;
      parallel::range(parallel::thread(), parallel::team(), n, &first, &last);
      terms(first, last);
#pragma omp barrier
      sums(first, last);
    }
  }
  addNodeBlocksAndPairTerms(xs, ys);
}

void SystemMatrix::addNodeBlocksAndPairTerms(const double* xs, double* ys) const {
  const int n = numNodes();
  for (const auto& [node, block] : node_blocks_) {
    const Vec3 y = block * Vec3(xs[node], xs[n + node], xs[2 * n + node]);
    for (int c = 0; c < 3; ++c) ys[c * n + node] += y[c];
  }
  multiplyPairTerms(xs, ys);
}

void SystemMatrix::multiplyPairTerms(const double* xs, double* ys) const {
  const int n = numNodes();
  for (const PairTerm& t : pair_terms_) {
    double s[3] = {0.0, 0.0, 0.0};  // sum_k w_k x_k
    for (int k = 0; k < 4; ++k) {
      const int i = t.node[k];
      for (int c = 0; c < 3; ++c) s[c] += t.w[k] * xs[c * n + i];
    }
    t.B.multiply(s, s);
    for (int k = 0; k < 4; ++k) {
      const int i = t.node[k];
      for (int c = 0; c < 3; ++c) ys[c * n + i] += t.w[k] * s[c];
    }
  }
}

}  // namespace cloth_sim
