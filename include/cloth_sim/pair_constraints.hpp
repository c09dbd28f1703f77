// Self-contact pairs held at their gap inside an implicit solve: linear
// constraints n . sum_k w_k x_k = gap between a point and a triangle (or two
// edges) of the cloth, imposed by projection like the pins (Baraff & Witkin
// 1998's filter, extended to rows that couple nodes).
//
// Why rows and not one hold per node: held each on its own (a pin along the
// filter's push), the nodes of a pair get reactions that need not be equal
// and opposite. They then inject momentum, and with stiff springs their
// neighbours follow at the pushed nodes' velocity: a fling at stretch 1e8
// gained 4e-3 J in a re-solve where the filter had taken 2e-4 J out, at any
// step size. One row per pair has a single multiplier lambda: the reaction
// is lambda w_k n on node k, so momentum is kept and, with the gap held, the
// pair does no work (an inelastic contact, with the solve's own inertia
// behind each side instead of the nodes' masses alone).
//
// Rows are restricted to what each node may do (S_k w_k n, S_k its filter
// projector: zero at a pin, the tangent plane at a collider contact), so the
// projection onto the rows' null space commutes with the node filter and the
// product is a projector: v - C^T G^-1 C v with G = C C^T, sparse (rows share
// a node where pairs do) and factored by a sparse LDL^T. Only independent
// rows are kept (a pivoted LDL^T of G picks them): nearly dependent rows (a
// point-triangle and an edge-edge pair at one contact, a pair whose nodes a
// table holds) made G ill-conditioned; regularised instead, or picked by a
// sparse QR's column threshold, the projection was idempotent only to 1e-7,
// and along a contact's stiff normal that leak kept CG on a folded cloth on
// a table at a relative residual of 0.8 after 1000 iterations. (Held as
// dense orthonormal bases per group of pairs, a folded cloth lying on itself
// made one group of 200 rows over 1200 unknowns: a 100-step drop took 95 s.)
#pragma once

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "cloth_sim/pair_gap.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// One pair (PairGap: four nodes' relative position along n) held with its
/// gap at `target`.
struct PairConstraint : PairGap {
  double target = 0.0;
};

class PairProjection {
 public:
  void assign(std::vector<PairConstraint> pairs);
  void clear() { assign({}); }
  bool empty() const { return pairs_.empty(); }
  const std::vector<PairConstraint>& pairs() const { return pairs_; }

  /// Restricts the rows to the nodes' allowed directions (`projector(i)`:
  /// the node's filter, I free, 0 pinned) and factors G.
  void restrict(const std::function<Mat3(int)>& projector);

  /// v <- v - C^T G^-1 C v, C the restricted rows: the part of v (3n,
  /// node-major) that changes no pair's gap.
  void project(VecX& v) const;
  /// The same for v split by component (v[c * num_nodes + i]).
  void projectSplit(double* v, int num_nodes) const;
  /// Adds to v (3n velocities) the smallest change, in the rows' range, after
  /// which each pair's gap at the positions base + scale v is its `target`
  /// (least squares where the rows are dependent). Inputs: base (3n), scale > 0.
  void meet(const VecX& base, double scale, VecX& v) const;
  /// Every pair's multiplier in a reaction r = C^T lambda (3n: what the
  /// rows supplied to each node, plus anything the rows' restriction takes
  /// out, such as a pin's or a table's own reaction): lambda = G^-1 C r with
  /// C the restricted rows (S_k w_k n)_k, exact where rows share nodes; > 0
  /// where the pair pushes its sides apart, < 0 where it holds them
  /// together. One entry per pair, 0 for a row not kept (dependent, or with
  /// no free node). (Read row by row, c . r / |c|^2, rows sharing a node
  /// took each other's load: a pair pulling with -1.05 N read +0.01.)
  std::vector<double> multipliers(const VecX& reaction) const;

  /// The restricted rows kept (independent; by restrict's last call): nodes
  /// and their 3-vectors, zero entries left out.
  struct Row {
    std::vector<int> nodes;
    std::vector<Vec3> c;
  };
  const std::vector<Row>& rows() const { return rows_; }

 private:
  /// G^-1 y in place (y: one entry a row).
  void solveGram(Eigen::VectorXd& y) const;
  /// C v: each kept row's value on v (3n).
  Eigen::VectorXd rowValues(const VecX& v) const;
  std::vector<PairConstraint> pairs_;
  std::vector<Row> rows_;
  std::vector<int> kept_;  ///< per kept row, its pair
  /// G's factor; shared by copies (a copy's restrict makes its own)
  std::shared_ptr<const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>> gram_;
};

}  // namespace cloth_sim
