// Broad phase for self-collision: a uniform grid hashed into a table
// (counting sort, so linear in the elements), over the boxes the nodes,
// triangles and edges sweep in one step. Gives the point–triangle and
// edge–edge pairs that may come close, without adjacent ones (sharing a
// node), each once. With a reuse margin, a table's pairs are found for boxes
// grown by it and kept: a later query whose boxes lie inside them (the
// filter's impulses, a re-solve, the end-of-step measure) filters the kept
// pairs instead of hashing again, with the same answer.
#pragma once

#include <utility>
#include <vector>

#include "cloth_sim/types.hpp"

namespace cloth_sim {

/// The cloth's collision primitives: its triangles and their unique edges.
struct CollisionMesh {
  int num_nodes = 0;
  std::vector<Eigen::Vector3i> triangles;
  std::vector<Eigen::Vector2i> edges;  ///< (i, j) with i < j, sorted, unique
};
/// The unique edges of `triangles` over `num_nodes` nodes.
CollisionMesh buildCollisionMesh(int num_nodes, const std::vector<Eigen::Vector3i>& triangles);

/// Candidate pairs for one step.
struct CandidatePairs {
  std::vector<std::pair<int, int>> point_triangle;  ///< (node, triangle), sorted
  std::vector<std::pair<int, int>> edge_edge;       ///< (edge a, edge b), a < b, sorted
  void clear() { point_triangle.clear(); edge_edge.clear(); }
};

/// An axis-aligned box.
struct Box {
  Vec3 lo, hi;
  bool overlaps(const Box& o) const {
    return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all();
  }
};

/// Box a node sweeps from x0 to x1 (3n vectors), grown by `pad` on every side.
Box sweptNodeBox(const VecX& x0, const VecX& x1, int node, double pad);

class SpatialHash {
 public:
  /// Inputs: mesh, the step's start and end positions x0, x1 (3n), `gap` >= 0.
  /// Output: every non-adjacent pair whose swept boxes, each grown by gap/2,
  /// overlap (so every pair that may come within `gap` during the linear
  /// motion), each once. Cost: linear in the elements plus the cells they
  /// cover plus the pairs found (then sorted).
  void findPairs(const CollisionMesh& mesh, const VecX& x0, const VecX& x1, double gap,
                 CandidatePairs* out);
  double cellSize() const { return cell_; }
  /// Hashing grows the boxes by `margin` >= 0 more (m) and keeps the pairs,
  /// so that queries moving no node's box beyond it reuse them (0: every
  /// query hashes). The answers do not depend on it, only the cost.
  void setReuseMargin(double margin) { margin_ = margin, kept_valid_ = false; }
  /// Queries answered so far by hashing, and by the kept pairs.
  long hashedQueries() const { return hashed_; }
  long reusedQueries() const { return reused_; }

 private:
  /// One table of elements by grid cell (a counting sort on the cell hash).
  struct Table {
    std::vector<int> start;  ///< bucket b holds ids[start[b] .. start[b + 1])
    std::vector<int> ids;
    unsigned mask = 0;
  };
  void buildTable(const std::vector<Box>& boxes, Table* table);
  /// Grows node_box_ by pad in place and builds tri_box_ and edge_box_ from it.
  void padBoxes(const CollisionMesh& mesh, double pad);
  /// Every non-adjacent pair whose boxes (node_box_ grown by pad) overlap,
  /// into kept_ (sorted, unique).
  void hashPairs(const CollisionMesh& mesh, double pad);
  /// The kept pairs whose boxes (the swept boxes of x0 -> x1 grown by pad)
  /// overlap, into out.
  void filterKept(const CollisionMesh& mesh, double pad, CandidatePairs* out);
  template <class Visit>
  void forCells(const Box& box, Visit visit) const;

  double cell_ = 1.0;
  std::vector<Box> node_box_, tri_box_, edge_box_;
  Table tri_table_, edge_table_;
  std::vector<unsigned> bucket_scratch_;
  double margin_ = 0.0;
  /// The last hashing's unpadded node boxes, their pad and its pairs.
  std::vector<Box> kept_node_box_;
  double kept_pad_ = 0.0;
  bool kept_valid_ = false;
  size_t kept_triangles_ = 0, kept_edges_ = 0;  ///< the mesh they were found on
  CandidatePairs kept_;
  long hashed_ = 0, reused_ = 0;
};

}  // namespace cloth_sim
