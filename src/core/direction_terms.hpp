// One direction's coupling terms, the product's inner sweep, for the double
// product (system_matrix.cpp) and the float one (system_matrix_single.cpp):
// one body, inlined into each one's vectorised (target-cloned) function.
#pragma once

namespace cloth_sim {
namespace detail {

/// Per slot p < count of one direction (ends p and p + offset): the coupling
/// term t = S (x_p - x_{p+offset}), written to t0..t2 at p. Held damping
/// axes (c, w) are added where c is given.
template <class Real>
__attribute__((always_inline)) inline void directionTerms(
    int count, int offset, const Real* __restrict x0, const Real* __restrict x1,
    const Real* __restrict x2, const Real* __restrict iso, const Real* __restrict axis,
    const Real* __restrict u0, const Real* __restrict u1, const Real* __restrict u2,
    const Real* __restrict c, const Real* __restrict w0, const Real* __restrict w1,
    const Real* __restrict w2, Real* __restrict t0, Real* __restrict t1, Real* __restrict t2) {
  if (c) {
    for (int p = 0; p < count; ++p) {
      const Real d0 = x0[p] - x0[p + offset], d1 = x1[p] - x1[p + offset],
                 d2 = x2[p] - x2[p + offset];
      const Real a = axis[p] * (u0[p] * d0 + u1[p] * d1 + u2[p] * d2);
      const Real e = c[p] * (w0[p] * d0 + w1[p] * d1 + w2[p] * d2);
      t0[p] = iso[p] * d0 + a * u0[p] + e * w0[p];
      t1[p] = iso[p] * d1 + a * u1[p] + e * w1[p];
      t2[p] = iso[p] * d2 + a * u2[p] + e * w2[p];
    }
    return;
  }
  for (int p = 0; p < count; ++p) {
    const Real d0 = x0[p] - x0[p + offset], d1 = x1[p] - x1[p + offset],
               d2 = x2[p] - x2[p + offset];
    const Real a = axis[p] * (u0[p] * d0 + u1[p] * d1 + u2[p] * d2);
    t0[p] = iso[p] * d0 + a * u0[p];
    t1[p] = iso[p] * d1 + a * u1[p];
    t2[p] = iso[p] * d2 + a * u2[p];
  }
}

}  // namespace detail
}  // namespace cloth_sim
