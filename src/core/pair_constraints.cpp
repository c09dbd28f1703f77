// Self-contact pairs held at their gap inside a solve (pair_constraints.hpp).
#include "cloth_sim/pair_constraints.hpp"

#include <algorithm>
#include <numeric>
#include <unordered_map>

namespace cloth_sim {

namespace {

/// Rows are kept while each adds a direction of at least this norm to those
/// before it (of the largest row's norm, about 1: weights of at most 1 on a
/// unit normal). A row dependent to within it is held by the others to
/// within that fraction of the motion.
constexpr double kIndependence = 1e-3;

/// A row is held only where closing its gap moves no node by more than this
/// many times the gap (the filter's own bound, self_collision.cpp's
/// kMaxReach): max_k |c_k| / |c|^2 at most this. Restricted to what the
/// contacts leave free, a pair between layers lying on a table keeps only
/// the tilt of its normal: held, its one row moved a node 4.4e7 m across
/// the table to meet its gap (the heap, s1, seed 2), and the filter then
/// made the whole cloth one impact zone. The filter keeps such a pair.
constexpr double kMaxRowReach = 4.0;

/// Pivoted (right-looking) Cholesky of the symmetric PSD G: takes the row
/// whose remaining diagonal, given the rows taken before, is largest, while
/// it is above `relative` times the first one taken. Output: the rows taken.
/// (Eigen's LDLT pivots on diagonals not yet updated: it took a repeated
/// row before an independent one, and the later one was lost.)
void pivotedRows(Eigen::MatrixXd G, double relative, std::vector<int>* taken) {
  const Eigen::Index m = G.rows();
  std::vector<char> done(static_cast<size_t>(m), 0);
  std::vector<Eigen::Index> nonzero;
  double first = 0.0;
  for (Eigen::Index step = 0; step < m; ++step) {
    Eigen::Index best = -1;
    for (Eigen::Index r = 0; r < m; ++r) {
      if (!done[r] && (best < 0 || G(r, r) > G(best, best))) best = r;
    }
    const double pivot = G(best, best);
    if (step == 0) first = pivot;
    if (!(pivot > relative * first) || !(first > 0.0)) break;
    done[best] = 1;
    taken->push_back(static_cast<int>(best));
    // G <- G - g g^T / pivot on the rows not taken (g: G's column `best`),
    // only where g is not zero: rows of pairs far apart never meet.
    nonzero.clear();
    for (Eigen::Index r = 0; r < m; ++r) {
      if (!done[r] && G(r, best) != 0.0) nonzero.push_back(r);
    }
    for (Eigen::Index c : nonzero) {
      const double gc = G(c, best) / pivot;
      for (Eigen::Index r : nonzero) G(r, c) -= G(r, best) * gc;
    }
  }
}

}  // namespace

void PairProjection::assign(std::vector<PairConstraint> pairs) {
  pairs_ = std::move(pairs);
  rows_.clear();
  kept_.clear();
  gram_.reset();
}

void PairProjection::restrict(const std::function<Mat3(int)>& projector) {
  rows_.clear();
  kept_.clear();
  gram_.reset();
  std::vector<Row> all(pairs_.size());
  double largest = 0.0;
  for (size_t r = 0; r < pairs_.size(); ++r) {
    const PairConstraint& p = pairs_[r];
    Row& row = all[r];
    for (int k = 0; k < 4; ++k) {
      const Vec3 c = projector(p.node[k]) * (p.w[k] * p.n);
      if (c.isZero(0.0)) continue;
      const auto at = std::find(row.nodes.begin(), row.nodes.end(), p.node[k]);
      if (at != row.nodes.end()) {
        row.c[at - row.nodes.begin()] += c;
      } else {
        row.nodes.push_back(p.node[k]);
        row.c.push_back(c);
      }
    }
    double norm2 = 0.0, widest = 0.0;
    for (const Vec3& c : row.c) norm2 += c.squaredNorm(), widest = std::max(widest, c.norm());
    if (!(widest <= kMaxRowReach * norm2)) {  // too little left free: not held
      row.nodes.clear();
      row.c.clear();
      continue;
    }
    largest = std::max(largest, norm2);
  }
  if (!(largest > 0.0)) return;  // no row has a free node: nothing held
  // The independent rows: a pivoted Cholesky of the whole G = C C^T.
  std::unordered_map<int, std::vector<std::pair<int, Vec3>>> incident;
  for (size_t r = 0; r < all.size(); ++r) {
    for (size_t k = 0; k < all[r].nodes.size(); ++k) {
      incident[all[r].nodes[k]].emplace_back(static_cast<int>(r), all[r].c[k]);
    }
  }
  const Eigen::Index m_all = static_cast<Eigen::Index>(all.size());
  Eigen::MatrixXd gram_all = Eigen::MatrixXd::Zero(m_all, m_all);
  for (const auto& [node, list] : incident) {
    for (const auto& [r, cr] : list) {
      for (const auto& [s, cs] : list) gram_all(r, s) += cr.dot(cs);
    }
  }
  pivotedRows(gram_all, kIndependence * kIndependence, &kept_);
  std::sort(kept_.begin(), kept_.end());
  for (int r : kept_) rows_.push_back(all[r]);
  if (rows_.empty()) return;
  // G = C C^T over the kept rows: rows r, s meet where they share a node.
  std::unordered_map<int, std::vector<std::pair<int, Vec3>>> by_node;
  for (size_t r = 0; r < rows_.size(); ++r) {
    for (size_t k = 0; k < rows_[r].nodes.size(); ++k) {
      by_node[rows_[r].nodes[k]].emplace_back(static_cast<int>(r), rows_[r].c[k]);
    }
  }
  std::vector<Eigen::Triplet<double>> entries;
  for (const auto& [node, list] : by_node) {
    for (const auto& [r, cr] : list) {
      for (const auto& [s, cs] : list) entries.emplace_back(r, s, cr.dot(cs));
    }
  }
  const int m = static_cast<int>(rows_.size());
  Eigen::SparseMatrix<double> G(m, m);
  G.setFromTriplets(entries.begin(), entries.end());
  auto gram = std::make_shared<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>(G);
  if (gram->info() != Eigen::Success) {  // not expected of independent rows
    rows_.clear();
    kept_.clear();
    return;
  }
  gram_ = gram;
}

void PairProjection::solveGram(Eigen::VectorXd& y) const { y = gram_->solve(y); }

Eigen::VectorXd PairProjection::rowValues(const VecX& v) const {
  Eigen::VectorXd y(static_cast<Eigen::Index>(rows_.size()));
  for (size_t r = 0; r < rows_.size(); ++r) {
    double sum = 0.0;
    for (size_t k = 0; k < rows_[r].nodes.size(); ++k) {
      sum += rows_[r].c[k].dot(v.segment<3>(3 * rows_[r].nodes[k]));
    }
    y[static_cast<Eigen::Index>(r)] = sum;
  }
  return y;
}

void PairProjection::project(VecX& v) const {
  if (rows_.empty()) return;
  Eigen::VectorXd y = rowValues(v);
  solveGram(y);
  for (size_t r = 0; r < rows_.size(); ++r) {
    for (size_t k = 0; k < rows_[r].nodes.size(); ++k) {
      v.segment<3>(3 * rows_[r].nodes[k]) -= y[static_cast<Eigen::Index>(r)] * rows_[r].c[k];
    }
  }
}

void PairProjection::projectSplit(double* v, int num_nodes) const {
  if (rows_.empty()) return;
  Eigen::VectorXd y(static_cast<Eigen::Index>(rows_.size()));
  for (size_t r = 0; r < rows_.size(); ++r) {
    double sum = 0.0;
    for (size_t k = 0; k < rows_[r].nodes.size(); ++k) {
      const int i = rows_[r].nodes[k];
      const Vec3& c = rows_[r].c[k];
      sum += c[0] * v[i] + c[1] * v[num_nodes + i] + c[2] * v[2 * num_nodes + i];
    }
    y[static_cast<Eigen::Index>(r)] = sum;
  }
  solveGram(y);
  for (size_t r = 0; r < rows_.size(); ++r) {
    const double yr = y[static_cast<Eigen::Index>(r)];
    for (size_t k = 0; k < rows_[r].nodes.size(); ++k) {
      const int i = rows_[r].nodes[k];
      const Vec3& c = rows_[r].c[k];
      v[i] -= yr * c[0];
      v[num_nodes + i] -= yr * c[1];
      v[2 * num_nodes + i] -= yr * c[2];
    }
  }
}

void PairProjection::meet(const VecX& base, double scale, VecX& v) const {
  if (rows_.empty()) return;
  Eigen::VectorXd miss(static_cast<Eigen::Index>(rows_.size()));
  for (size_t r = 0; r < rows_.size(); ++r) {
    const PairConstraint& p = pairs_[kept_[r]];
    Vec3 rel = Vec3::Zero();
    for (int k = 0; k < 4; ++k) {
      rel += p.w[k] * (base.segment<3>(3 * p.node[k]) + scale * v.segment<3>(3 * p.node[k]));
    }
    miss[static_cast<Eigen::Index>(r)] = p.target - p.n.dot(rel);
  }
  // A change C^T y (in the restricted rows' range) moves the gaps by C C^T y.
  solveGram(miss);
  for (size_t r = 0; r < rows_.size(); ++r) {
    for (size_t k = 0; k < rows_[r].nodes.size(); ++k) {
      v.segment<3>(3 * rows_[r].nodes[k]) += (miss[static_cast<Eigen::Index>(r)] / scale) * rows_[r].c[k];
    }
  }
}

std::vector<double> PairProjection::multipliers(const VecX& reaction) const {
  std::vector<double> out(pairs_.size(), 0.0);
  if (rows_.empty()) return out;
  Eigen::VectorXd y = rowValues(reaction);
  solveGram(y);
  for (size_t r = 0; r < rows_.size(); ++r) out[kept_[r]] = y[static_cast<Eigen::Index>(r)];
  return out;
}

}  // namespace cloth_sim
