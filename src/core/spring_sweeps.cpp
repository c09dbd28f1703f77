#include "cloth_sim/spring_sweeps.hpp"

#include <algorithm>
#include <cmath>

#include "cloth_sim/spring_forces.hpp"
#include "vectorised.hpp"

namespace cloth_sim {
namespace sweeps {

void splitComponents(const VecX& x, double* out) {
  const int n = static_cast<int>(x.size() / 3);
  const double* in = x.data();
  for (int i = 0; i < n; ++i) {
    out[i] = in[3 * i];
    out[n + i] = in[3 * i + 1];
    out[2 * n + i] = in[3 * i + 2];
  }
}

void joinComponents(const double* in, int n, double* out) {
  for (int i = 0; i < n; ++i) {
    out[3 * i] = in[i];
    out[3 * i + 1] = in[n + i];
    out[3 * i + 2] = in[2 * n + i];
  }
}

void PaddedTerms::reset(int n, int offset, int components) {
  n_ = n;
  offset_ = offset;
  padded_ = n + offset;
  components_ = components;
  buffer_.resize(components * static_cast<size_t>(padded_));
  data_ = buffer_.data();
  for (int c = 0; c < components; ++c) {  // the pads; a sweep fills the rest
    std::fill(data_ + c * padded_, data_ + c * padded_ + offset, 0.0);
    std::fill(data_ + c * padded_ + n, data_ + (c + 1) * padded_, 0.0);
  }
}

namespace {

CLOTH_SIM_VECTORISED
void addDifferences(int n, int offset, int padded, const double* __restrict t,
                    double* __restrict y) {
  const double *__restrict t0 = t, *__restrict t1 = t + padded, *__restrict t2 = t + 2 * padded;
  double *__restrict y0 = y, *__restrict y1 = y + n, *__restrict y2 = y + 2 * n;
  for (int p = 0; p < n; ++p) {
    y0[p] += t0[p + offset] - t0[p];
    y1[p] += t1[p + offset] - t1[p];
    y2[p] += t2[p + offset] - t2[p];
  }
}

/// y = (m x or y) + (ta[p + oa] - ta[p]) + (tb[p + ob] - tb[p]) for one
/// component (ta, tb padded term arrays).
template <bool kInit>
inline __attribute__((always_inline)) void twoDifferences(
    int n, const double* __restrict m, const double* __restrict x, const double* __restrict ta,
    int oa, const double* __restrict tb, int ob, double* __restrict y) {
  for (int p = 0; p < n; ++p) {
    const double base = kInit ? m[p] * x[p] : y[p];
    y[p] = base + ((ta[p + oa] - ta[p]) + (tb[p + ob] - tb[p]));
  }
}

/// Nodes [first, last) of n.
CLOTH_SIM_VECTORISED
void sumTwoDirections(int first, int last, int n, const double* m, const double* x,
                      const double* ta, int oa, int pa, const double* tb, int ob, int pb,
                      double* y) {
  for (int c = 0; c < 3; ++c) {
    twoDifferences<true>(last - first, m + first, x + c * n + first, ta + c * pa + first, oa,
                         tb + c * pb + first, ob, y + c * n + first);
  }
}

CLOTH_SIM_VECTORISED
void addTwoDirections(int first, int last, int n, const double* ta, int oa, int pa,
                      const double* tb, int ob, int pb, double* y) {
  for (int c = 0; c < 3; ++c) {
    twoDifferences<false>(last - first, nullptr, nullptr, ta + c * pa + first, oa,
                          tb + c * pb + first, ob, y + c * n + first);
  }
}

CLOTH_SIM_VECTORISED
void addSums(int n, int offset, const double* __restrict t, double* __restrict y) {
  for (int p = 0; p < n; ++p) y[p] += t[p + offset] + t[p];
}

/// addDifferencesOfAll for one component and kCount directions.
template <int kCount>
inline __attribute__((always_inline)) void differencesOfAll(int n, const double* const* t,
                                                            const int* o, bool from_zero,
                                                            double* __restrict y) {
  if (from_zero) {
    for (int p = 0; p < n; ++p) {
      double s = 0.0;
      for (int k = 0; k < kCount; ++k) s += t[k][p + o[k]] - t[k][p];
      y[p] = s;
    }
  } else {
    for (int p = 0; p < n; ++p) {
      double s = y[p];
      for (int k = 0; k < kCount; ++k) s += t[k][p + o[k]] - t[k][p];
      y[p] = s;
    }
  }
}

CLOTH_SIM_VECTORISED
void differencesOfAllDispatch(int n, int count, const double* const* t, const int* o,
                              bool from_zero, double* y) {
  withCount<PaddedTerms::kMaxDirections>(count, [&](auto k) __attribute__((always_inline)) {
    differencesOfAll<decltype(k)::value>(n, t, o, from_zero, y);
  });
}

/// forceSweep's loop for one combination of outputs and damping. kRegular:
/// every spring taken as longer than kDegenerateLength (no rest directions
/// loaded, no selects), returning false if one was not, to be swept again
/// whole without kRegular. kWisV: w is v (implicit_euler's K v0).
template <bool kMatrix, bool kKw, bool kHeld, bool kAlong, bool kKnownLength, bool kSingle,
          bool kWisV, bool kRegular>
inline __attribute__((always_inline)) bool forceLoopOnce(const ForceSweepIn& in,
                                                         const ForceSweepOut& out) {
  const int o = in.offset;
  int irregular = 0;
  const double* __restrict known = in.length;
  const double *__restrict x0 = in.x[0], *__restrict x1 = in.x[1], *__restrict x2 = in.x[2];
  const double *__restrict v0 = in.v[0], *__restrict v1 = in.v[1], *__restrict v2 = in.v[2];
  const double *__restrict w0 = in.w[0], *__restrict w1 = in.w[1], *__restrict w2 = in.w[2];
  const double *__restrict h0 = in.held[0], *__restrict h1 = in.held[1],
               *__restrict h2 = in.held[2];
  const double *__restrict valid = in.valid, *__restrict rest = in.rest_length;
  const double *__restrict r0 = in.rest_dir[0], *__restrict r1 = in.rest_dir[1],
               *__restrict r2 = in.rest_dir[2];
  double *__restrict f0 = out.f[0], *__restrict f1 = out.f[1], *__restrict f2 = out.f[2];
  double *__restrict kw0 = out.kw[0], *__restrict kw1 = out.kw[1], *__restrict kw2 = out.kw[2];
  double *__restrict iso = out.iso, *__restrict axis = out.axis;
  double *__restrict u0s = out.u[0], *__restrict u1s = out.u[1], *__restrict u2s = out.u[2];
  double *__restrict cs = out.c;
  float *__restrict iso_f = out.iso_single, *__restrict axis_f = out.axis_single;
  float *__restrict u0f = out.u_single[0], *__restrict u1f = out.u_single[1],
                    *__restrict u2f = out.u_single[2];
  double *__restrict hw0 = out.hw[0], *__restrict hw1 = out.hw[1], *__restrict hw2 = out.hw[2];
  const double k = in.stiffness, c = in.damping, a = in.a, b = in.b;
  const double floor = in.project_compression ? 0.0 : -HUGE_VAL;
  const int slots = in.slots;  // a local: the stores below might alias `in`
  // The arrays never overlap (restrict on these locals is not used by GCC 12
  // to drop its run-time alias checks, too many for it here).
#pragma GCC ivdep
  for (int p = 0; p < slots; ++p) {
    const double d0 = x0[p + o] - x0[p], d1 = x1[p + o] - x1[p], d2 = x2[p + o] - x2[p];
    const double l = kKnownLength ? known[p] : std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    const double L = rest[p];
    // springDirection and isDegenerate (spring_forces.hpp), as selects.
    const bool degenerate = !(l > kDegenerateLength * std::max(L, 1.0));
    const double inv = 1.0 / l;
    double u0 = d0 * inv, u1 = d1 * inv, u2 = d2 * inv;
    double t = 1.0 - L * inv;
    if (kRegular) {
      irregular |= degenerate;
    } else {
      // Loaded either way: selects, not branches.
      const double rd0 = r0[p], rd1 = r1[p], rd2 = r2[p];
      u0 = degenerate ? rd0 : u0, u1 = degenerate ? rd1 : u1, u2 = degenerate ? rd2 : u2;
      t = degenerate ? 0.0 : t;
    }
    // K = k (1 - t) u u^T + k t I, t = 1 - L/l (0 when degenerate; clamped
    // at 0 under compression when projecting): kept as two scalars.
    t = std::max(t, floor);
    const double km = k * valid[p], cm = c * valid[p];  // empty slots: nothing
    const double k_iso = km * t, k_axis = km - k_iso;
    const double e0 = kHeld ? h0[p] : u0, e1 = kHeld ? h1[p] : u1, e2 = kHeld ? h2[p] : u2;
    const double dv0 = v0[p + o] - v0[p], dv1 = v1[p + o] - v1[p], dv2 = v2[p + o] - v2[p];
    const double s = km * (l - L);
    if (kAlong) {
      const double q = cm * (dv0 * e0 + dv1 * e1 + dv2 * e2);
      f0[p] = s * u0 + q * e0;
      f1[p] = s * u1 + q * e1;
      f2[p] = s * u2 + q * e2;
    } else {
      f0[p] = s * u0 + cm * dv0;
      f1[p] = s * u1 + cm * dv1;
      f2[p] = s * u2 + cm * dv2;
    }
    if (kMatrix) {
      const double iso_p = b * k_iso + (kAlong ? 0.0 : a * cm);
      const double axis_p = b * k_axis + (kAlong && !kHeld ? a * cm : 0.0);
      iso[p] = iso_p;
      axis[p] = axis_p;
      u0s[p] = u0;
      u1s[p] = u1;
      u2s[p] = u2;
      if (kSingle) {
        iso_f[p] = static_cast<float>(iso_p);
        axis_f[p] = static_cast<float>(axis_p);
        u0f[p] = static_cast<float>(u0);
        u1f[p] = static_cast<float>(u1);
        u2f[p] = static_cast<float>(u2);
      }
      if (kHeld) {
        cs[p] = a * cm;
        hw0[p] = e0;
        hw1[p] = e1;
        hw2[p] = e2;
      }
    }
    if (kKw) {
      const double dw0 = kWisV ? dv0 : w0[p + o] - w0[p], dw1 = kWisV ? dv1 : w1[p + o] - w1[p],
                   dw2 = kWisV ? dv2 : w2[p + o] - w2[p];
      const double q = k_axis * (u0 * dw0 + u1 * dw1 + u2 * dw2);
      kw0[p] = k_iso * dw0 + q * u0;
      kw1[p] = k_iso * dw1 + q * u1;
      kw2[p] = k_iso * dw2 + q * u2;
    }
  }
  return irregular == 0;
}

template <bool kMatrix, bool kKw, bool kHeld, bool kAlong, bool kKnownLength = false,
          bool kSingle = false, bool kWisV = false>
inline __attribute__((always_inline)) void forceLoop(const ForceSweepIn& in,
                                                     const ForceSweepOut& out) {
  if (forceLoopOnce<kMatrix, kKw, kHeld, kAlong, kKnownLength, kSingle, kWisV, true>(in, out)) {
    return;
  }
  forceLoopOnce<kMatrix, kKw, kHeld, kAlong, kKnownLength, kSingle, kWisV, false>(in, out);
}

template <bool kMatrix, bool kKw, bool kSingle>
inline __attribute__((always_inline)) void forceLoopByDamping(const ForceSweepIn& in,
                                                              const ForceSweepOut& out) {
  if (!in.along) {
    forceLoop<kMatrix, kKw, false, false, false, kSingle>(in, out);
  } else if (in.held[0]) {
    forceLoop<kMatrix, kKw, true, true>(in, out);  // no float copies with held axes
  } else {
    forceLoop<kMatrix, kKw, false, true, false, kSingle>(in, out);
  }
}

CLOTH_SIM_VECTORISED
void forceSweepDispatch(const ForceSweepIn& in, const ForceSweepOut& out) {
  const bool single = out.iso_single != nullptr;
  if (!out.iso) {
    forceLoopByDamping<false, false, false>(in, out);
  } else if (in.w[0] == in.v[0] && in.w[1] == in.v[1] && in.w[2] == in.v[2] && in.length &&
             !in.along) {  // implicit_euler's, at a measured x
    if (single) {
      forceLoop<true, true, false, false, true, true, true>(in, out);
    } else {
      forceLoop<true, true, false, false, true, false, true>(in, out);
    }
  } else if (in.w[0]) {
    if (single) {
      forceLoopByDamping<true, true, true>(in, out);
    } else {
      forceLoopByDamping<true, true, false>(in, out);
    }
  } else if (single) {
    forceLoopByDamping<true, false, true>(in, out);
  } else {
    forceLoopByDamping<true, false, false>(in, out);
  }
}

/// The direction's sum of (l - L)^2 and largest strain, with eight partial
/// sums and maxima (a vectorised reduction in one pass with the lengths).
CLOTH_SIM_VECTORISED
void energyTerms(int slots, int offset, const double* __restrict x0, const double* __restrict x1,
                 const double* __restrict x2, const double* __restrict valid,
                 const double* __restrict rest, const double* __restrict inv_rest,
                 double* __restrict length, double* sum_sq, double* max_strain) {
  double sq[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  double top[8] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL, -HUGE_VAL,
                   -HUGE_VAL, -HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
  auto slot = [&](int p, int k) __attribute__((always_inline)) {
    const double d0 = x0[p + offset] - x0[p], d1 = x1[p + offset] - x1[p],
                 d2 = x2[p + offset] - x2[p];
    const double l = std::sqrt(d0 * d0 + d1 * d1 + d2 * d2);
    length[p] = l;
    const double m = valid[p], stretch = (l - rest[p]) * m, s = l * inv_rest[p] - 1.0;
    sq[k] += stretch * stretch;
    top[k] = std::max(top[k], m > 0.0 ? s : -HUGE_VAL);
  };
  int p = 0;
  for (; p + 8 <= slots; p += 8) {
    for (int k = 0; k < 8; ++k) slot(p + k, k);
  }
  for (; p < slots; ++p) slot(p, 0);
  *sum_sq += ((sq[0] + sq[1]) + (sq[2] + sq[3])) + ((sq[4] + sq[5]) + (sq[6] + sq[7]));
  for (double t : top) *max_strain = std::max(*max_strain, t);
}

}  // namespace

void PaddedTerms::addDifferences(double* y_split) const {
  sweeps::addDifferences(n_, offset_, padded_, data_, y_split);
}

void PaddedTerms::addDifferencesOfAll(const PaddedTerms* terms, int count, bool from_zero,
                                      double* y_split) {
  if (count > 0) addDifferencesOfAll(terms, count, from_zero, y_split, 0, terms[0].n_);
}

void PaddedTerms::addDifferencesOfAll(const PaddedTerms* terms, int count, bool from_zero,
                                      double* y_split, int first, int last) {
  if (count > kMaxDirections) {  // in turns of kMaxDirections
    addDifferencesOfAll(terms, kMaxDirections, from_zero, y_split, first, last);
    addDifferencesOfAll(terms + kMaxDirections, count - kMaxDirections, false, y_split, first,
                        last);
    return;
  }
  if (count <= 0 || last <= first) return;
  const int n = terms[0].n_;
  const double* t[kMaxDirections];
  int o[kMaxDirections];
  for (int c = 0; c < 3; ++c) {
    for (int k = 0; k < count; ++k) {
      t[k] = terms[k].data_ + c * terms[k].padded_ + first;
      o[k] = terms[k].offset_;
    }
    differencesOfAllDispatch(last - first, count, t, o, from_zero, y_split + c * n + first);
  }
}

void PaddedTerms::addSums(double* y_split) const {
  for (int c = 0; c < components_; ++c) {
    sweeps::addSums(n_, offset_, data_ + c * padded_, y_split + c * n_);
  }
}

// A missing second direction is a zero one: offset 0 on the first's terms
// (t[p] - t[p] = 0), so one loop serves odd counts too.
void PaddedTerms::sumDifferences(const double* m, const double* x_split, const PaddedTerms& a,
                                 const PaddedTerms* b, double* y_split, int first, int last) {
  const PaddedTerms& bb = b ? *b : a;
  if (last < 0) last = a.n_;
  sumTwoDirections(first, last, a.n_, m, x_split, a.data_, a.offset_, a.padded_, bb.data_,
                   b ? bb.offset_ : 0, bb.padded_, y_split);
}

void PaddedTerms::addPairDifferences(const PaddedTerms& a, const PaddedTerms* b, double* y_split,
                                     int first, int last) {
  const PaddedTerms& bb = b ? *b : a;
  if (last < 0) last = a.n_;
  addTwoDirections(first, last, a.n_, a.data_, a.offset_, a.padded_, bb.data_,
                   b ? bb.offset_ : 0, bb.padded_, y_split);
}

void forceSweep(const ForceSweepIn& in, const ForceSweepOut& out) { forceSweepDispatch(in, out); }

void forceSweep(const ForceSweepIn& in, const ForceSweepOut& out, int first, int last) {
  last = std::min(last, in.slots);
  if (last <= first) return;
  // Every array is indexed by slot (p, and p + offset for the upper end's
  // node): slot `first` becomes slot 0.
  auto from = [first](auto* p) { return p ? p + first : p; };
  ForceSweepIn part = in;
  ForceSweepOut to = out;
  part.slots = last - first;
  for (int c = 0; c < 3; ++c) {
    part.x[c] = from(in.x[c]);
    part.v[c] = from(in.v[c]);
    part.w[c] = from(in.w[c]);
    part.held[c] = from(in.held[c]);
    part.rest_dir[c] = from(in.rest_dir[c]);
    to.f[c] = from(out.f[c]);
    to.kw[c] = from(out.kw[c]);
    to.u[c] = from(out.u[c]);
    to.hw[c] = from(out.hw[c]);
    to.u_single[c] = from(out.u_single[c]);
  }
  part.valid = from(in.valid);
  part.rest_length = from(in.rest_length);
  part.length = from(in.length);
  to.iso = from(out.iso);
  to.axis = from(out.axis);
  to.c = from(out.c);
  to.iso_single = from(out.iso_single);
  to.axis_single = from(out.axis_single);
  forceSweepDispatch(part, to);
}

void energySweep(int slots, int offset, const double* const x[3], const double* valid,
                 const double* rest_length, const double* inv_rest_length, double* sum_sq,
                 double* max_strain, double* length) {
  thread_local std::vector<double> lengths;
  if (!length) {
    lengths.resize(std::max(slots, 0));
    length = lengths.data();
  }
  energyTerms(slots, offset, x[0], x[1], x[2], valid, rest_length, inv_rest_length, length,
              sum_sq, max_strain);
}

}  // namespace sweeps
}  // namespace cloth_sim
