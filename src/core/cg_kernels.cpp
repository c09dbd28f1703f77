#include "cloth_sim/cg_kernels.hpp"

#include "vectorised.hpp"

namespace cloth_sim {
namespace cg_kernels {

namespace {

/// The eight partial sums folded pairwise.
inline double fold(const double* s) {
  return ((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7]));
}

}  // namespace

CLOTH_SIM_VECTORISED
double dot(int n, const double* __restrict a, const double* __restrict b) {
  double s[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    for (int k = 0; k < 8; ++k) s[k] += a[i + k] * b[i + k];
  }
  for (; i < n; ++i) s[0] += a[i] * b[i];
  return fold(s);
}

CLOTH_SIM_VECTORISED
double updateSolution(int n, double alpha, const double* __restrict p,
                      const double* __restrict q, double* __restrict x, double* __restrict r) {
  double s[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    for (int k = 0; k < 8; ++k) {
      x[i + k] += alpha * p[i + k];
      const double ri = r[i + k] - alpha * q[i + k];
      r[i + k] = ri;
      s[k] += ri * ri;
    }
  }
  for (; i < n; ++i) {
    x[i] += alpha * p[i];
    r[i] -= alpha * q[i];
    s[0] += r[i] * r[i];
  }
  return fold(s);
}

CLOTH_SIM_VECTORISED
double subtractAndSquare(int n, const double* __restrict q, double* __restrict r) {
  double s[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    for (int k = 0; k < 8; ++k) {
      const double ri = r[i + k] - q[i + k];
      r[i + k] = ri;
      s[k] += ri * ri;
    }
  }
  for (; i < n; ++i) {
    r[i] -= q[i];
    s[0] += r[i] * r[i];
  }
  return fold(s);
}

CLOTH_SIM_VECTORISED
double blockJacobi(int m, const double* const inv[6], const double* __restrict r,
                   double* __restrict z) {
  const double *__restrict a0 = inv[0], *__restrict a1 = inv[1], *__restrict a2 = inv[2],
               *__restrict a3 = inv[3], *__restrict a4 = inv[4], *__restrict a5 = inv[5];
  const double *__restrict r0 = r, *__restrict r1 = r + m, *__restrict r2 = r + 2 * m;
  double *__restrict z0 = z, *__restrict z1 = z + m, *__restrict z2 = z + 2 * m;
  double s[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int i = 0;
  for (; i + 8 <= m; i += 8) {
    for (int k = 0; k < 8; ++k) {
      const int j = i + k;
      const double x = r0[j], y = r1[j], w = r2[j];
      const double zx = a0[j] * x + a3[j] * y + a4[j] * w;
      const double zy = a3[j] * x + a1[j] * y + a5[j] * w;
      const double zz = a4[j] * x + a5[j] * y + a2[j] * w;
      z0[j] = zx;
      z1[j] = zy;
      z2[j] = zz;
      s[k] += x * zx + y * zy + w * zz;
    }
  }
  for (; i < m; ++i) {
    const double x = r0[i], y = r1[i], w = r2[i];
    z0[i] = a0[i] * x + a3[i] * y + a4[i] * w;
    z1[i] = a3[i] * x + a1[i] * y + a5[i] * w;
    z2[i] = a4[i] * x + a5[i] * y + a2[i] * w;
    s[0] += x * z0[i] + y * z1[i] + w * z2[i];
  }
  return fold(s);
}

CLOTH_SIM_VECTORISED
void updateDirection(int n, double beta, const double* __restrict z, double* __restrict p) {
  for (int i = 0; i < n; ++i) p[i] = z[i] + beta * p[i];
}

CLOTH_SIM_VECTORISED
void updateDirectionWithSingle(int n, double beta, const double* __restrict z,
                               double* __restrict p, float* __restrict p_single) {
  for (int i = 0; i < n; ++i) {
    const double pi = z[i] + beta * p[i];
    p[i] = pi;
    p_single[i] = static_cast<float>(pi);
  }
}

CLOTH_SIM_VECTORISED
void copyWithSingle(int n, const double* __restrict z, double* __restrict p,
                    float* __restrict p_single) {
  for (int i = 0; i < n; ++i) {
    p[i] = z[i];
    p_single[i] = static_cast<float>(z[i]);
  }
}

CLOTH_SIM_VECTORISED
bool allFinite(int n, const double* __restrict x) {
  // x - x is 0 for a finite x and NaN otherwise; eight partial sums, as dot.
  double s[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    for (int k = 0; k < 8; ++k) s[k] += x[i + k] - x[i + k];
  }
  for (; i < n; ++i) s[0] += x[i] - x[i];
  return ((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7])) == 0.0;
}

CLOTH_SIM_VECTORISED
void scaleAdd(int n, double a, const double* __restrict x, double b, double* __restrict y) {
  if (b == 0.0) {
    for (int i = 0; i < n; ++i) y[i] = a * x[i];
  } else {
    for (int i = 0; i < n; ++i) y[i] = a * x[i] + b * y[i];
  }
}

namespace {

/// Four doubles; the compiler's vector extension, so that each partial sum's
/// multiply-add is the one dot's loop compiles to (a loop over several
/// vectors at once was vectorised across them, without multiply-adds for
/// some counts: other results than dot's).
typedef double Lanes __attribute__((vector_size(32)));

inline Lanes loadLanes(const double* p) {
  Lanes v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}

template <int kCount>
inline __attribute__((always_inline)) void dotsOf(int n, const double* const* v,
                                                  const double* __restrict b, double* out) {
  Lanes lo[kCount], hi[kCount];  // partial sums 0..3 and 4..7, as dot's s[8]
  for (int j = 0; j < kCount; ++j) lo[j] = hi[j] = Lanes{0.0, 0.0, 0.0, 0.0};
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    const Lanes b_lo = loadLanes(b + i), b_hi = loadLanes(b + i + 4);
    for (int j = 0; j < kCount; ++j) {
      lo[j] += loadLanes(v[j] + i) * b_lo;
      hi[j] += loadLanes(v[j] + i + 4) * b_hi;
    }
  }
  for (int j = 0; j < kCount; ++j) {
    double s[8] = {lo[j][0], lo[j][1], lo[j][2], lo[j][3], hi[j][0], hi[j][1], hi[j][2], hi[j][3]};
    for (int t = i; t < n; ++t) s[0] += v[j][t] * b[t];
    out[j] = fold(s);
  }
}

template <int kCount>
inline __attribute__((always_inline)) void combineOf(int n, const double* const* v,
                                                     const double* c, double* __restrict y) {
  // As scaleAdd's a x + b y with b = 1 compiles: c[j] v[j] + t with
  // multiply-adds where they exist. The first product plus zero is rounded
  // as y = a x rounds it, and is no product the next add could fuse instead.
  for (int i = 0; i < n; ++i) {
    double t = c[0] * v[0][i] + 0.0;
    for (int j = 1; j < kCount; ++j) t = c[j] * v[j][i] + t;
    y[i] = t;
  }
}

}  // namespace

CLOTH_SIM_VECTORISED
void dots(int n, int count, const double* const* v, const double* b, double* out) {
  withCount<kMaxVectors>(count, [&](auto k) __attribute__((always_inline)) {
    dotsOf<decltype(k)::value>(n, v, b, out);
  });
}

CLOTH_SIM_VECTORISED
void combine(int n, int count, const double* const* v, const double* c, double* y) {
  withCount<kMaxVectors>(count, [&](auto k) __attribute__((always_inline)) {
    combineOf<decltype(k)::value>(n, v, c, y);
  });
}

}  // namespace cg_kernels
}  // namespace cloth_sim
