// The vector operations of conjugateGradient on vectors split by component
// (x of every node, then y, then z: the layout of SystemMatrix's product),
// fused so that each iteration passes over its vectors three times instead of
// seven, in loops the compiler vectorises (built for x86-64-v3 and the
// baseline, as the spring sweeps). Sums keep eight partial sums, so results
// differ from a sequential sum by round-off only.
#pragma once

namespace cloth_sim {
namespace cg_kernels {

/// a . b over n entries.
double dot(int n, const double* a, const double* b);
/// x += alpha p and r -= alpha q; returns r . r (the new residual's square).
double updateSolution(int n, double alpha, const double* p, const double* q, double* x,
                      double* r);
/// r -= q; returns r . r (as dot sums it).
double subtractAndSquare(int n, const double* q, double* r);
/// z = D^-1 r for m nodes, D^-1 given as symmetric blocks split by entry
/// (inv[0..5][i]: xx, yy, zz, xy, xz, yz of node i); returns r . z.
double blockJacobi(int m, const double* const inv[6], const double* r, double* z);
/// p = z + beta p.
void updateDirection(int n, double beta, const double* z, double* p);
/// The same, and p's float copy into p_single (for a float product).
void updateDirectionWithSingle(int n, double beta, const double* z, double* p, float* p_single);
/// p = z, and p's float copy into p_single.
void copyWithSingle(int n, const double* z, double* p, float* p_single);
/// Whether every entry is finite (the steppers' check of every step, too).
bool allFinite(int n, const double* x);
/// y = a x + b y (b = 0: y = a x, whatever y held).
void scaleAdd(int n, double a, const double* x, double b, double* y);

/// The most vectors dots() and combine() take at once.
constexpr int kMaxVectors = 8;
/// out[k] = v[k] . b for k < count (<= kMaxVectors): count dots in one pass
/// over b, each summed as dot() sums it (the same result).
void dots(int n, int count, const double* const* v, const double* b, double* out);
/// y = sum_k c[k] v[k] (count from 1 to kMaxVectors) in one pass, summed in
/// the order of scaleAdd(c[0] v[0], b 0) then scaleAdd(c[k] v[k], b 1) for
/// k = 1, 2, ... (the same result).
void combine(int n, int count, const double* const* v, const double* c, double* y);

}  // namespace cg_kernels
}  // namespace cloth_sim
