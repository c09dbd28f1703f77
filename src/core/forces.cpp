#include "cloth_sim/forces.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

#include "cloth_sim/spring_sweeps.hpp"
#include "parallel.hpp"

namespace cloth_sim {

SpringParams springParams(const Model& model, const Spring& s) {
  const SpringGroup& g = model.groups[static_cast<int>(s.type)];
  SpringParams p;
  p.stiffness = g.stiffness;
  p.damping = g.damping;
  p.rest_length = s.rest_length;
  p.damping_model = model.damping_model;
  p.rest_direction = s.rest_direction;
  return p;
}

void springAxes(const Model& model, const VecX& x, std::vector<Vec3>& axes) {
  axes.resize(model.springs.size());
  for (size_t k = 0; k < model.springs.size(); ++k) {
    const Spring& s = model.springs[k];
    const Vec3 d = x.segment<3>(3 * s.j) - x.segment<3>(3 * s.i);
    axes[k] = springDirection(d, d.norm(), s.rest_length, s.rest_direction);
  }
}

namespace {

/// The sweeps' work arrays (x, v, w and the held axes by component, the
/// padded per-slot terms, the sums by component), kept per thread so a step
/// allocates nothing once sized.
struct SweepBuffers {
  std::vector<double> x, v, w, held;
  VecX f, kw;  ///< swapped out whole where the caller takes them split
  std::vector<sweeps::PaddedTerms> f_terms, kw_terms;  ///< per direction
  // The slots' lengths measureEnergy took (direction d's from d n) at
  // `measured_x` of `measured_layout`, whose split is still in x while
  // `x_is_measured`: implicit_euler's next assembly is at that x (the energy
  // check measures the step's end, the next step starts there) and reads
  // them instead of taking every spring's square root again.
  std::vector<double> lengths;
  VecX measured_x;
  std::shared_ptr<const SpringLayout> measured_layout;
  bool x_is_measured = false;
  // Each direction's sweep, set up before the sweeps run (on any thread).
  std::vector<sweeps::ForceSweepIn> sweep_in;
  std::vector<sweeps::ForceSweepOut> sweep_out;
};

SweepBuffers& sweepBuffers() {
  thread_local SweepBuffers buffers;
  return buffers;
}

/// f_c = m g_c - air_drag v_c on split vectors. Not a vectorised clone: no
/// fused multiply-add, the rounding of the unsplit m g - (drag v) it replaced.
void externalForcesSplit(const Model& model, const double* v, double* f) {
  const int n = model.numNodes();
  for (int c = 0; c < 3; ++c) {
    const double g = model.has_gravity ? model.gravity[c] : 0.0;
    double* fc = f + static_cast<size_t>(c) * n;
    for (int i = 0; i < n; ++i) fc[i] = model.mass[i] * g;
    if (model.air_drag > 0.0) {
      const double* vc = v + static_cast<size_t>(c) * n;
      for (int i = 0; i < n; ++i) fc[i] -= model.air_drag * vc[i];
    }
  }
}

/// f(x, v) = the external forces plus the springs' over their directions;
/// with A, A's couplings b K + a D too; with w, K w into dfdx_w. With
/// `split_out`, f and dfdx_w come out split by component.
void springSweeps(const Model& model, const VecX& x, const VecX& v, double a, double b,
                  bool project_compression, SystemMatrix* A, VecX& f, const VecX* w,
                  VecX* dfdx_w, const std::vector<Vec3>* damping_axes, bool split_out,
                  int threads) {
  const SpringLayout& layout = *model.layout;
  const int n = layout.num_nodes;
  const size_t size = 3 * static_cast<size_t>(n);
  SweepBuffers& buf = sweepBuffers();
  const bool along = model.damping_model == DampingModel::AlongSpring;
  // At the x the energy check measured last: its split and lengths (the
  // loop that reads lengths is implicit_euler's assembly's).
  const bool measured = A && w == &v && !along && buf.x_is_measured &&
                        buf.measured_layout == model.layout && x.size() == buf.measured_x.size() &&
                        std::memcmp(x.data(), buf.measured_x.data(), x.size() * sizeof(double)) == 0;
  if (!measured) {
    buf.x.resize(size);
    sweeps::splitComponents(x, buf.x.data());
    buf.x_is_measured = false;
  }
  buf.v.resize(size);
  buf.f.resize(size);
  f.resize(x.size());
  sweeps::splitComponents(v, buf.v.data());
  externalForcesSplit(model, buf.v.data(), buf.f.data());
  // K w of the velocities themselves (implicit_euler's h K v0): no second split.
  const bool w_is_v = w == &v;
  if (w) {
    buf.kw.resize(size);
    if (layout.directions.empty()) buf.kw.setZero();
    if (!w_is_v) {
      buf.w.resize(size);
      sweeps::splitComponents(*w, buf.w.data());
    }
  }
  const double* w_split = w_is_v ? buf.v.data() : buf.w.data();
  const bool held = along && damping_axes;
  if (held) {  // per spring to per slot: direction d's axes at held[3 d n + c n + node]
    buf.held.resize(layout.directions.size() * size);
    for (size_t k = 0; k < layout.slot.size(); ++k) {
      const SpringSlot& s = layout.slot[k];
      for (int c = 0; c < 3; ++c) buf.held[(3 * s.direction + c) * n + s.node] = (*damping_axes)[k][c];
    }
    if (A) A->useDampingAxes();
  }
  bool single_written = A && !layout.directions.empty();
  const int directions = static_cast<int>(layout.directions.size());
  buf.f_terms.resize(directions);
  if (w) buf.kw_terms.resize(directions);
  buf.sweep_in.resize(directions);
  buf.sweep_out.resize(directions);
  for (int d = 0; d < directions; ++d) {
    const SpringDirection& dir = layout.directions[d];
    const SpringGroup& g = model.groups[static_cast<int>(dir.type)];
    sweeps::ForceSweepIn& in = buf.sweep_in[d];
    in = sweeps::ForceSweepIn();
    in.slots = dir.slots;
    in.offset = dir.offset;
    for (int c = 0; c < 3; ++c) {
      in.x[c] = buf.x.data() + c * n;
      in.v[c] = buf.v.data() + c * n;
      if (w) in.w[c] = w_split + c * n;
      if (held) in.held[c] = buf.held.data() + (3 * d + c) * n;
      in.rest_dir[c] = dir.rest_dir[c].data();
    }
    in.valid = dir.valid.data();
    in.rest_length = dir.rest_length.data();
    if (measured) in.length = buf.lengths.data() + d * n;
    in.stiffness = g.stiffness;
    in.damping = g.damping;
    in.along = along;
    in.project_compression = project_compression;
    in.a = a;
    in.b = b;
    sweeps::ForceSweepOut& out = buf.sweep_out[d];
    out = sweeps::ForceSweepOut();
    buf.f_terms[d].ensure(n, dir.offset);
    if (w) buf.kw_terms[d].ensure(n, dir.offset);
    for (int c = 0; c < 3; ++c) {
      out.f[c] = buf.f_terms[d].term(c);
      if (w) out.kw[c] = buf.kw_terms[d].term(c);
    }
    if (A) {
      SystemMatrix::Coefficients& co = A->coefficients(d);
      out.iso = co.iso.data();
      out.axis = co.axis.data();
      for (int c = 0; c < 3; ++c) out.u[c] = co.u[c].data();
      if (held) {
        out.c = co.c.data();
        for (int c = 0; c < 3; ++c) out.hw[c] = co.w[c].data();
      }
      // Float copies where the last matrix took float products.
      float* single = A->singleCoefficients(d);
      single_written = single_written && single;
      if (single) {
        out.iso_single = single;
        out.axis_single = single + n;
        for (int c = 0; c < 3; ++c) out.u_single[c] = single + (2 + c) * n;
      }
    }
  }
  // Every direction's terms into the node sums in one pass each (the
  // external forces first, then the directions in turn, as one pass a
  // direction added them). With threads, each takes a range of slots in
  // every direction, then (after all terms are written) a range of nodes.
  const int parts = parallel::partsFor(threads, n);
  if (parts == 1) {
    for (int d = 0; d < directions; ++d) sweeps::forceSweep(buf.sweep_in[d], buf.sweep_out[d]);
    sweeps::PaddedTerms::addDifferencesOfAll(buf.f_terms.data(), directions, false, buf.f.data());
    if (w) {
      sweeps::PaddedTerms::addDifferencesOfAll(buf.kw_terms.data(), directions, true,
                                               buf.kw.data());
    }
  } else {
#pragma omp parallel num_threads(parts)
    {
      int first = 0, last = n;
      parallel::range(parallel::thread(), parallel::team(), n, &first, &last);
      for (int d = 0; d < directions; ++d) {
        sweeps::forceSweep(buf.sweep_in[d], buf.sweep_out[d], first, last);
      }
#pragma omp barrier
      sweeps::PaddedTerms::addDifferencesOfAll(buf.f_terms.data(), directions, false,
                                               buf.f.data(), first, last);
      if (w) {
        sweeps::PaddedTerms::addDifferencesOfAll(buf.kw_terms.data(), directions, true,
                                                 buf.kw.data(), first, last);
      }
    }
  }
  if (single_written) A->singleWritten();
  if (split_out) {  // the caller works on split vectors: no join
    f.swap(buf.f);
    if (w) dfdx_w->swap(buf.kw);
    return;
  }
  sweeps::joinComponents(buf.f.data(), n, f.data());
  if (w) sweeps::joinComponents(buf.kw.data(), n, dfdx_w->data());
}

}  // namespace

void computeForces(const Model& model, const VecX& x, const VecX& v, VecX& f,
                   const std::vector<Vec3>* damping_axes, int threads) {
  springSweeps(model, x, v, 0.0, 0.0, false, nullptr, f, nullptr, nullptr, damping_axes, false,
               threads);
}

void assembleSystem(const Model& model, const VecX& x, const VecX& v, double a, double b,
                    bool project_compression, SystemMatrix& A, VecX& f, const VecX* w,
                    VecX* dfdx_w, const std::vector<Vec3>* damping_axes, bool split_out,
                    int threads) {
  A.resize(model.layout);
  A.reset(model.mass, a * model.air_drag);
  if (dfdx_w) dfdx_w->resize(x.size());
  springSweeps(model, x, v, a, b, project_compression, &A, f, dfdx_w ? w : nullptr, dfdx_w,
               damping_axes, split_out, threads);
  if (project_compression && a >= 0.0 && b >= 0.0) {
    // Projected, a slot's block is b k ((1 - t) u u^T + t I) with t in [0, 1]
    // plus a c on I, an axis or a held axis: PSD, |iso| + |axis| + |c| =
    // b k + a c (forceLoop, spring_sweeps.cpp); a node ends at most two
    // slots of each direction.
    double bound = 0.0;
    for (const SpringDirection& dir : model.layout->directions) {
      const SpringGroup& g = model.groups[static_cast<int>(dir.type)];
      if (!(g.stiffness >= 0.0 && g.damping >= 0.0)) return;  // no word given
      bound += 2.0 * (b * g.stiffness + a * g.damping);
    }
    A.setPsdCouplingBound(bound);
  }
}

namespace {

/// roundOffTerms' sum for node i into s.
inline void addRoundOffTerms(const Model& model, const VecX& av, int i, RoundOffTerms& s) {
  const double m = model.mass[i], v2 = av.segment<3>(3 * i).squaredNorm();
  s.momentum_sq += m * m * v2;
  s.mass_sq += m * m;
  s.kinetic2 += m * v2;
  s.m_min = std::min(s.m_min, m);
}

/// Two partial sums (even and odd nodes) joined.
RoundOffTerms joinRoundOffTerms(RoundOffTerms t, const RoundOffTerms& u) {
  t.momentum_sq += u.momentum_sq;
  t.mass_sq += u.mass_sq;
  t.kinetic2 += u.kinetic2;
  t.m_min = std::min(t.m_min, u.m_min);
  return t;
}

}  // namespace

RoundOffTerms roundOffTerms(const Model& model, const VecX& av) {
  // Even and odd nodes: two chains of dependent adds instead of one.
  RoundOffTerms t, u;
  const int n = model.numNodes();
  for (int i = 0; i < n; ++i) addRoundOffTerms(model, av, i, i % 2 == 0 ? t : u);
  return joinRoundOffTerms(t, u);
}

namespace {

/// measureEnergy's one pass over the nodes: x split by component into
/// `split` and copied into `copy`, the kinetic and gravity energies and v's
/// round-off terms summed as kineticEnergy, gravityEnergy and roundOffTerms
/// sum them (the same partial sums, in the same order: the same results),
/// and whether x and v are finite.
void nodePass(const Model& model, const VecX& x, const VecX& v, double* split, double* copy,
              double* kinetic, double* gravity, RoundOffTerms* round_off, bool* finite) {
  const int n = model.numNodes();
  const double* m = model.mass.data();
  const double* w = v.data();
  const double* y = x.data();
  const double g0 = model.gravity[0], g1 = model.gravity[1], g2 = model.gravity[2];
  double e[4] = {0.0, 0.0, 0.0, 0.0}, p[4] = {0.0, 0.0, 0.0, 0.0};
  double nan[4] = {0.0, 0.0, 0.0, 0.0};  // u - u: 0 where finite, NaN elsewhere
  RoundOffTerms even, odd;
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    for (int k = 0; k < 4; ++k) {
      const int j = i + k;
      const double* u = w + 3 * j;
      const double* q = y + 3 * j;
      e[k] += m[j] * (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
      p[k] += m[j] * (g0 * q[0] + g1 * q[1] + g2 * q[2]);
      nan[k] += ((u[0] - u[0]) + (u[1] - u[1])) + ((u[2] - u[2]) + (q[0] - q[0])) +
                ((q[1] - q[1]) + (q[2] - q[2]));
      addRoundOffTerms(model, v, j, k % 2 == 0 ? even : odd);
    }
  }
  for (int j = i; j < n; ++j) {
    for (int c = 0; c < 3; ++c) nan[0] += (w[3 * j + c] - w[3 * j + c]) + (y[3 * j + c] - y[3 * j + c]);
  }
  *finite = ((nan[0] + nan[1]) + (nan[2] + nan[3])) == 0.0;
  for (; i < n; ++i) {
    e[0] += m[i] * v.segment<3>(3 * i).squaredNorm();
    p[0] += m[i] * model.gravity.dot(x.segment<3>(3 * i));
    addRoundOffTerms(model, v, i, i % 2 == 0 ? even : odd);
  }
  *round_off = joinRoundOffTerms(even, odd);
  for (int j = 0; j < n; ++j) {
    split[j] = y[3 * j];
    split[n + j] = y[3 * j + 1];
    split[2 * n + j] = y[3 * j + 2];
  }
  std::copy(y, y + 3 * static_cast<size_t>(n), copy);
  *kinetic = 0.5 * ((e[0] + e[1]) + (e[2] + e[3]));
  *gravity = model.has_gravity ? -((p[0] + p[1]) + (p[2] + p[3])) : 0.0;
}

}  // namespace

EnergyParts measureEnergy(const Model& model, const VecX& x, const VecX& v) {
  EnergyParts e;
  const SpringLayout& layout = *model.layout;
  const int n = layout.num_nodes;
  SweepBuffers& buf = sweepBuffers();
  buf.x.resize(3 * static_cast<size_t>(n));
  buf.measured_x.resize(x.size());
  nodePass(model, x, v, buf.x.data(), buf.measured_x.data(), &e.kinetic, &e.potential,
           &e.round_off, &e.finite);
  buf.lengths.resize(layout.directions.size() * static_cast<size_t>(n));
  const double* split[3] = {buf.x.data(), buf.x.data() + n, buf.x.data() + 2 * n};
  double sum[kNumSpringTypes] = {};  // of (l - L)^2, per group
  for (size_t d = 0; d < layout.directions.size(); ++d) {
    const SpringDirection& dir = layout.directions[d];
    sweeps::energySweep(dir.slots, dir.offset, split, dir.valid.data(), dir.rest_length.data(),
                        dir.inv_rest_length.data(), &sum[static_cast<int>(dir.type)],
                        &e.max_strain, buf.lengths.data() + d * n);
  }
  buf.measured_layout = model.layout;
  buf.x_is_measured = true;
  for (int t = 0; t < kNumSpringTypes; ++t) e.elastic += 0.5 * model.groups[t].stiffness * sum[t];
  return e;
}

double kineticEnergy(const Model& model, const VecX& v) {
  // Four partial sums: one is a chain of dependent adds (the energy check
  // measures every step).
  const int n = model.numNodes();
  const double* m = model.mass.data();
  const double* w = v.data();
  double e[4] = {0.0, 0.0, 0.0, 0.0};
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    for (int k = 0; k < 4; ++k) {
      const double* u = w + 3 * (i + k);
      e[k] += m[i + k] * (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    }
  }
  for (; i < n; ++i) e[0] += m[i] * v.segment<3>(3 * i).squaredNorm();
  return 0.5 * ((e[0] + e[1]) + (e[2] + e[3]));
}

double elasticEnergy(const Model& model, const VecX& x) {
  double e = 0.0;
  for (const Spring& s : model.springs) {
    e += springEnergy(x.segment<3>(3 * s.i), x.segment<3>(3 * s.j), springParams(model, s));
  }
  return e;
}

double gravityEnergy(const Model& model, const VecX& x) {
  if (!model.has_gravity) return 0.0;
  const int n = model.numNodes();
  const double* m = model.mass.data();
  const double* y = x.data();
  const double g0 = model.gravity[0], g1 = model.gravity[1], g2 = model.gravity[2];
  double e[4] = {0.0, 0.0, 0.0, 0.0};  // partial sums, as kineticEnergy
  int i = 0;
  for (; i + 4 <= n; i += 4) {
    for (int k = 0; k < 4; ++k) {
      const double* u = y + 3 * (i + k);
      e[k] += m[i + k] * (g0 * u[0] + g1 * u[1] + g2 * u[2]);
    }
  }
  for (; i < n; ++i) e[0] += m[i] * model.gravity.dot(x.segment<3>(3 * i));
  return -((e[0] + e[1]) + (e[2] + e[3]));
}

double maxStrain(const Model& model, const VecX& x) {
  double strain = 0.0;
  for (const Spring& s : model.springs) {
    strain = std::max(strain, (x.segment<3>(3 * s.j) - x.segment<3>(3 * s.i)).norm() / s.rest_length - 1.0);
  }
  return strain;
}

double springForceScale(const Model& model) {
  // Per group from its sum of L^2 (kept by buildModel): the Newton steppers
  // ask every step, and the springs never change.
  double sum = 0.0;
  for (const SpringGroup& g : model.groups) sum += g.stiffness * g.stiffness * g.rest_length_sq;
  return std::sqrt(sum);
}

namespace {

double residualRoundOff(const Model& model, double bh, const RoundOffTerms& t) {
  return 100.0 * std::numeric_limits<double>::epsilon() *
         (std::sqrt(t.momentum_sq) +
          bh * (std::sqrt(t.mass_sq * model.gravity.squaredNorm()) + springForceScale(model)));
}

}  // namespace

double residualRoundOff(const Model& model, double bh, const VecX& av) {
  return residualRoundOff(model, bh, roundOffTerms(model, av));
}

double energyRoundOff(const Model& model, double bh, const VecX& av) {
  return energyRoundOff(model, bh, roundOffTerms(model, av));
}

double energyRoundOff(const Model& model, double bh, const RoundOffTerms& t) {
  if (!(t.m_min > 0.0) || !std::isfinite(t.m_min)) return 0.0;  // no nodes, or massless
  const double r = residualRoundOff(model, bh, t);
  return std::sqrt(t.kinetic2 / t.m_min) * r + 0.5 * r * r / t.m_min;
}

}  // namespace cloth_sim
