// Broad phase for self-collision: a uniform grid hashed into a table
// (counting sort, so linear in the elements), over the boxes the nodes,
// triangles and edges sweep in one step. Gives the point–triangle and
// edge–edge pairs that may come close, without adjacent ones (sharing a
// node), each once. With a reuse margin, a table's pairs are found for boxes
// grown by it and kept: a later query whose boxes lie inside them (the
// filter's impulses, a re-solve, the end-of-step measure) filters the kept
// pairs instead of hashing again, with the same answer. Kept pairs also keep
// their distance at the hashing, which bounds how near they can be later
// (each point of a pair moves no further than its nodes do): a query may
// leave out the pairs that bound keeps beyond its reach (DistanceCull), so
// that the narrow phase computes no distance between parts of a flat cloth
// that are a mesh spacing apart.
#pragma once

#include <limits>
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
  /// The smallest distance bound among the pairs a DistanceCull left out
  /// (each > its `below`; infinity when none was)
  double culled_bound = std::numeric_limits<double>::infinity();
  void clear() {
    point_triangle.clear(), edge_edge.clear();
    culled_bound = std::numeric_limits<double>::infinity();
  }
};

/// Which pairs a query may leave out by distance. A kept pair's distance d
/// at the hashing's x0 (the reference) and its nodes' largest displacement
/// from there over the query's x0 and x1, da on one side and db on the
/// other, bound its distance anywhere along the linear motion x0 -> x1 from
/// below by d - da - db. The pair is left out when d - factor (da + db) >
/// below. Factor 1 is that bound; a caller whose test can move a pair's
/// measure further (a gap along a normal fixed at x0, read at x1) passes the
/// factor that covers it. Only with reuse on (SpatialHash::setReuseMargin):
/// hashed without it, nothing is left out.
struct DistanceCull {
  double below = -1.0;  ///< negative: leave nothing out
  double factor = 1.0;  ///< >= 1
  /// false: the caller does not read CandidatePairs::culled_bound, which is
  /// then only a lower bound of it, and the query stops at the first kept
  /// pair (by distance) that no node's motion so far can bring within reach.
  bool exact_bound = true;
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
  /// motion), each once, less those `cull` leaves out. Cost: linear in the
  /// elements plus the cells they cover plus the pairs found (then sorted);
  /// hashing with reuse on adds a distance per pair found.
  void findPairs(const CollisionMesh& mesh, const VecX& x0, const VecX& x1, double gap,
                 CandidatePairs* out, const DistanceCull& cull = {});
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
  void padNodeBoxes(double pad);
  /// tri_box_ and edge_box_ from node_box_ as it is.
  void mergeElementBoxes(const CollisionMesh& mesh);
  /// Every non-adjacent pair whose boxes (node_box_ grown by pad) overlap,
  /// into kept_ (sorted, unique).
  void hashPairs(const CollisionMesh& mesh, double pad);
  /// The kept pairs' distances at kept_reference_.
  void measureKept(const CollisionMesh& mesh);
  /// The kept pairs whose boxes (the swept boxes of x0 -> x1 grown by pad)
  /// overlap, less those `cull` leaves out, into out.
  void filterKept(const CollisionMesh& mesh, const VecX& x0, const VecX& x1, double pad,
                  const DistanceCull& cull, CandidatePairs* out);
  template <class Visit>
  void forCells(const Box& box, Visit visit) const;

  double cell_ = 1.0;
  std::vector<Box> node_box_, tri_box_, edge_box_;
  Table tri_table_, edge_table_;
  std::vector<unsigned> bucket_scratch_;
  std::vector<int> stamp_;  ///< per element: the query element that last found it (hashPairs)
  double margin_ = 0.0;
  /// Kept boxes reach this many more moves on along each node's motion.
  static constexpr double kAhead = 2.0;
  std::vector<Box> query_box_;  ///< a hashing query's own node boxes
  /// The last hashing's unpadded node boxes, their pad and its pairs.
  std::vector<Box> kept_node_box_;
  double kept_pad_ = 0.0;
  bool kept_valid_ = false;
  size_t kept_triangles_ = 0, kept_edges_ = 0;  ///< the mesh they were found on
  CandidatePairs kept_;
  VecX kept_reference_;  ///< the last hashing's x0
  std::vector<double> moved_;  ///< a query's node displacements from the reference
  /// The kept pairs with their distances there: in kept_'s order, and
  /// binned by distance (a counting sort: bin b holds [b w, (b + 1) w), the
  /// last the rest, NaN the first), so that a culling query whose reach is
  /// small scans only the near bins.
  struct KeptPair {
    double distance;
    int a, b;   ///< (node, triangle) or (edge, edge)
    int index;  ///< in kept_'s list
  };
  static constexpr int kDistanceBins = 64;
  double bin_width_ = 1.0;
  /// A lower bound of the distances in bin b.
  double binNearest(int b) const { return b * bin_width_ * (1.0 - 1e-9); }
  std::vector<KeptPair> point_triangle_measured_, edge_edge_measured_;
  std::vector<KeptPair> point_triangle_binned_, edge_edge_binned_;
  std::vector<int> point_triangle_bins_, edge_edge_bins_;  ///< kDistanceBins + 1 starts
  /// A culling query's bounds (filterKept).
  struct Cull {
    double below, factor;
    double reach;   ///< no pair's bound is below its distance less this
    double culled;  ///< the smallest bound left out so far
    bool exact_bound;
    /// Without the exact bound: whether the pair is left out whatever its
    /// nodes' moves (distance less reach taken into culled).
    bool beyondReach(double distance);
    /// Whether the pair is left out (its bound then taken into culled).
    bool leftOut(double distance, double moved);
  };
  /// The most a kept pair's nodes moved since the hashing, one side plus the other.
  double pointTriangleMoved(const CollisionMesh& mesh, int node, int tri) const;
  double edgeEdgeMoved(const CollisionMesh& mesh, int a, int b) const;
  /// filterKept with culling, node boxes padded: every kept pair in kept_'s
  /// order, or the near bins' pairs (element boxes merged as needed).
  void filterInOrder(const CollisionMesh& mesh, Cull* c, CandidatePairs* out);
  void filterByDistance(const CollisionMesh& mesh, Cull* c, CandidatePairs* out);
  /// Element boxes merged by filterByDistance: the query that last made each.
  std::vector<long> tri_box_query_, edge_box_query_;
  long box_query_ = 0;
  /// filterByDistance's answer as kept_ indices, and the query that last
  /// chose each kept pair (to list a large answer in kept_'s order).
  std::vector<int> chosen_;
  std::vector<long> point_triangle_chosen_, edge_edge_chosen_;
  long hashed_ = 0, reused_ = 0;
};

}  // namespace cloth_sim
