// Uniform-grid spatial hash for the self-collision broad phase.
#include "cloth_sim/spatial_hash.hpp"

#include <algorithm>
#include <cmath>

#include "cloth_sim/collision_geometry.hpp"

namespace cloth_sim {

CollisionMesh buildCollisionMesh(int num_nodes, const std::vector<Eigen::Vector3i>& triangles) {
  CollisionMesh mesh;
  mesh.num_nodes = num_nodes;
  mesh.triangles = triangles;
  std::vector<std::pair<int, int>> e;
  e.reserve(3 * triangles.size());
  for (const Eigen::Vector3i& t : triangles) {
    for (int k = 0; k < 3; ++k) {
      const int a = t[k], b = t[(k + 1) % 3];
      e.emplace_back(std::min(a, b), std::max(a, b));
    }
  }
  std::sort(e.begin(), e.end());
  e.erase(std::unique(e.begin(), e.end()), e.end());
  for (const auto& [a, b] : e) mesh.edges.emplace_back(a, b);
  return mesh;
}

Box sweptNodeBox(const VecX& x0, const VecX& x1, int node, double pad) {
  const Vec3 a = x0.segment<3>(3 * node), b = x1.segment<3>(3 * node);
  return Box{a.cwiseMin(b).array() - pad, a.cwiseMax(b).array() + pad};
}

namespace {

// Inlined: called out of line it was 6 % of a self-collision step at small dt
// (padBoxes merges every triangle's and edge's box at each query).
__attribute__((always_inline)) inline Box merge(const Box& a, const Box& b) {
  return Box{a.lo.cwiseMin(b.lo), a.hi.cwiseMax(b.hi)};
}

unsigned cellHash(long ix, long iy, long iz) {
  // Teschner et al. 2003's primes.
  // Unsigned arithmetic: wrapping is defined (signed overflow would not be).
  const auto u = [](long i) { return static_cast<unsigned long>(i); };
  return static_cast<unsigned>((u(ix) * 73856093UL) ^ (u(iy) * 19349663UL) ^ (u(iz) * 83492791UL));
}

}  // namespace

template <class Visit>
void SpatialHash::forCells(const Box& box, Visit visit) const {
  // Clamped before the cast to long (out of range is undefined): far-away
  // cells then share a cell index, which only adds candidates.
  constexpr double kFar = 1e15;
  const Eigen::Array3d lo = (box.lo / cell_).array().floor().max(-kFar).min(kFar);
  const Eigen::Array3d hi = (box.hi / cell_).array().floor().max(-kFar).min(kFar);
  for (long ix = long(lo.x()); ix <= long(hi.x()); ++ix)
    for (long iy = long(lo.y()); iy <= long(hi.y()); ++iy)
      for (long iz = long(lo.z()); iz <= long(hi.z()); ++iz) visit(ix, iy, iz);
}

void SpatialHash::buildTable(const std::vector<Box>& boxes, Table* table) {
  // Count the (element, cell) entries, size the table to twice that (a
  // power of two), then place the ids by bucket: two passes, no hashing map.
  size_t entries = 0;
  for (const Box& b : boxes) forCells(b, [&](long, long, long) { ++entries; });
  size_t size = 16;
  while (size < 2 * entries) size *= 2;
  table->mask = static_cast<unsigned>(size - 1);
  table->start.assign(size + 1, 0);
  bucket_scratch_.clear();
  for (const Box& b : boxes) {
    forCells(b, [&](long ix, long iy, long iz) {
      const unsigned bucket = cellHash(ix, iy, iz) & table->mask;
      bucket_scratch_.push_back(bucket);
      ++table->start[bucket + 1];
    });
  }
  for (size_t k = 0; k < size; ++k) table->start[k + 1] += table->start[k];
  table->ids.resize(entries);
  std::vector<int> fill(table->start.begin(), table->start.end() - 1);
  size_t entry = 0;
  for (size_t id = 0; id < boxes.size(); ++id) {
    forCells(boxes[id], [&](long, long, long) {
      table->ids[fill[bucket_scratch_[entry++]]++] = static_cast<int>(id);
    });
  }
}

void SpatialHash::findPairs(const CollisionMesh& mesh, const VecX& x0, const VecX& x1,
                            double gap, CandidatePairs* out, const DistanceCull& cull) {
  out->clear();
  const int n = mesh.num_nodes;
  const double pad = 0.5 * gap;
  node_box_.resize(n);
  for (int i = 0; i < n; ++i) node_box_[i] = sweptNodeBox(x0, x1, i, 0.0);
  if (margin_ > 0.0 && kept_valid_ && kept_node_box_.size() == node_box_.size() &&
      kept_triangles_ == mesh.triangles.size() && kept_edges_ == mesh.edges.size()) {
    // Inside the kept boxes grown by their pad: every pair this query finds
    // is a kept one.
    double beyond = 0.0;
    for (int i = 0; i < n; ++i) {
      beyond = std::max({beyond, (kept_node_box_[i].lo - node_box_[i].lo).maxCoeff(),
                         (node_box_[i].hi - kept_node_box_[i].hi).maxCoeff()});
    }
    if (pad + beyond <= kept_pad_) {
      ++reused_;
      filterKept(mesh, x0, x1, pad, cull, out);
      return;
    }
  }
  ++hashed_;
  if (margin_ == 0.0) {
    hashPairs(mesh, pad);
    std::swap(*out, kept_);
    kept_valid_ = false;
    return;
  }
  // Kept boxes reach on along each node's motion for kAhead more such
  // moves: a cloth moving steadily is hashed every few steps, not at every
  // step's first query (its travel beyond the margin).
  query_box_ = node_box_;
  for (int i = 0; i < n; ++i) {
    const Vec3 ahead = x1.segment<3>(3 * i) + kAhead * (x1.segment<3>(3 * i) - x0.segment<3>(3 * i));
    node_box_[i] = Box{node_box_[i].lo.cwiseMin(ahead), node_box_[i].hi.cwiseMax(ahead)};
  }
  kept_node_box_ = node_box_;
  kept_pad_ = pad + margin_;
  kept_triangles_ = mesh.triangles.size();
  kept_edges_ = mesh.edges.size();
  hashPairs(mesh, kept_pad_);
  kept_reference_ = x0;
  measureKept(mesh);
  kept_valid_ = true;
  std::swap(node_box_, query_box_);  // the query's own, unpadded, for filterKept to pad
  filterKept(mesh, x0, x1, pad, cull, out);
}

void SpatialHash::padBoxes(const CollisionMesh& mesh, double pad) {
  padNodeBoxes(pad);
  mergeElementBoxes(mesh);
}

void SpatialHash::padNodeBoxes(double pad) {
  for (Box& b : node_box_) b = Box{b.lo.array() - pad, b.hi.array() + pad};
}

void SpatialHash::mergeElementBoxes(const CollisionMesh& mesh) {
  tri_box_.resize(mesh.triangles.size());
  for (size_t k = 0; k < mesh.triangles.size(); ++k) {
    const Eigen::Vector3i& t = mesh.triangles[k];
    tri_box_[k] = merge(merge(node_box_[t[0]], node_box_[t[1]]), node_box_[t[2]]);
  }
  edge_box_.resize(mesh.edges.size());
  for (size_t k = 0; k < mesh.edges.size(); ++k) {
    edge_box_[k] = merge(node_box_[mesh.edges[k][0]], node_box_[mesh.edges[k][1]]);
  }
}

void SpatialHash::hashPairs(const CollisionMesh& mesh, double pad) {
  kept_.clear();
  const int n = mesh.num_nodes;
  padBoxes(mesh, pad);
  if (mesh.triangles.empty()) return;
  double extent = 0.0, largest = 0.0;
  for (const Box& b : tri_box_) {
    const double e = (b.hi - b.lo).maxCoeff();
    extent += e;
    largest = std::max(largest, e);
  }
  // Cells about a triangle's box: each element then covers a few cells. A
  // fast element's box is capped at 8 cells a side by growing the cell.
  cell_ = std::max({extent / mesh.triangles.size(), largest / 8.0, 1e-9});

  // A pair shares several cells (and hashed buckets): each query element
  // takes a pair once (a stamp on the element found), then sorts its own
  // few. The lists come out sorted and unique, as one sort of every pair
  // with its repeats made them, at a fraction of the cost where boxes cover
  // many cells (the heap at dt 0.1: 40 % of a step sorted repeats).
  buildTable(tri_box_, &tri_table_);
  stamp_.assign(mesh.triangles.size(), -1);
  for (int i = 0; i < n; ++i) {
    const Box& box = node_box_[i];
    const size_t first = kept_.point_triangle.size();
    forCells(box, [&](long ix, long iy, long iz) {
      const unsigned bucket = cellHash(ix, iy, iz) & tri_table_.mask;
      for (int k = tri_table_.start[bucket]; k < tri_table_.start[bucket + 1]; ++k) {
        const int tri = tri_table_.ids[k];
        if (stamp_[tri] == i) continue;
        stamp_[tri] = i;
        const Eigen::Vector3i& t = mesh.triangles[tri];
        if (t[0] == i || t[1] == i || t[2] == i || !box.overlaps(tri_box_[tri])) continue;
        kept_.point_triangle.emplace_back(i, tri);
      }
    });
    std::sort(kept_.point_triangle.begin() + first, kept_.point_triangle.end());
  }
  buildTable(edge_box_, &edge_table_);
  stamp_.assign(mesh.edges.size(), -1);
  for (size_t a = 0; a < mesh.edges.size(); ++a) {
    const Box& box = edge_box_[a];
    const int a0 = mesh.edges[a][0], a1 = mesh.edges[a][1];
    const size_t first = kept_.edge_edge.size();
    forCells(box, [&](long ix, long iy, long iz) {
      const unsigned bucket = cellHash(ix, iy, iz) & edge_table_.mask;
      for (int k = edge_table_.start[bucket]; k < edge_table_.start[bucket + 1]; ++k) {
        const int b = edge_table_.ids[k];
        if (b <= static_cast<int>(a) || stamp_[b] == static_cast<int>(a)) continue;
        stamp_[b] = static_cast<int>(a);
        const int b0 = mesh.edges[b][0], b1 = mesh.edges[b][1];
        if (b0 == a0 || b0 == a1 || b1 == a0 || b1 == a1 || !box.overlaps(edge_box_[b])) continue;
        kept_.edge_edge.emplace_back(static_cast<int>(a), b);
      }
    });
    std::sort(kept_.edge_edge.begin() + first, kept_.edge_edge.end());
  }
}

void SpatialHash::measureKept(const CollisionMesh& mesh) {
  const VecX& x = kept_reference_;
  auto at = [&](int i) { return x.segment<3>(3 * i); };
  point_triangle_measured_.resize(kept_.point_triangle.size());
  for (size_t k = 0; k < kept_.point_triangle.size(); ++k) {
    const auto& [node, tri] = kept_.point_triangle[k];
    const Eigen::Vector3i& t = mesh.triangles[tri];
    point_triangle_measured_[k] = {pointTriangleDistance(at(node), at(t[0]), at(t[1]), at(t[2])),
                                   node, tri, static_cast<int>(k)};
  }
  edge_edge_measured_.resize(kept_.edge_edge.size());
  for (size_t k = 0; k < kept_.edge_edge.size(); ++k) {
    const auto& [ea, eb] = kept_.edge_edge[k];
    const Eigen::Vector2i& a = mesh.edges[ea];
    const Eigen::Vector2i& b = mesh.edges[eb];
    edge_edge_measured_[k] = {edgeEdgeDistance(at(a[0]), at(a[1]), at(b[0]), at(b[1])), ea, eb,
                              static_cast<int>(k)};
  }
  // Bins an eighth of the kept pad wide: a query's reach is about its pad.
  bin_width_ = std::max(kept_pad_ / 8.0, 1e-12);
  auto binOf = [&](double d) {
    if (std::isnan(d)) return 0;  // never left out: scanned first
    if (!(d < kDistanceBins * bin_width_)) return kDistanceBins - 1;
    return std::min(static_cast<int>(d / bin_width_), kDistanceBins - 1);
  };
  // A counting sort into the bins.
  auto place = [&](const std::vector<KeptPair>& measured, std::vector<KeptPair>* binned,
                   std::vector<int>* start) {
    start->assign(kDistanceBins + 1, 0);
    for (const KeptPair& p : measured) ++(*start)[binOf(p.distance) + 1];
    for (int b = 0; b < kDistanceBins; ++b) (*start)[b + 1] += (*start)[b];
    std::vector<int> fill(start->begin(), start->end() - 1);
    binned->resize(measured.size());
    for (const KeptPair& p : measured) (*binned)[fill[binOf(p.distance)]++] = p;
  };
  place(point_triangle_measured_, &point_triangle_binned_, &point_triangle_bins_);
  place(edge_edge_measured_, &edge_edge_binned_, &edge_edge_bins_);
}

bool SpatialHash::Cull::beyondReach(double distance) {
  if (exact_bound || !(distance - reach > below)) return false;
  culled = std::min(culled, distance - reach);
  return true;
}

bool SpatialHash::Cull::leftOut(double distance, double moved) {
  const double bound = distance - factor * moved;
  if (!(bound > below)) return false;
  culled = std::min(culled, bound);
  return true;
}

void SpatialHash::filterKept(const CollisionMesh& mesh, const VecX& x0, const VecX& x1,
                             double pad, const DistanceCull& cull, CandidatePairs* out) {
  if (!(cull.below >= 0.0)) {
    padBoxes(mesh, pad);  // as a fresh query makes them (same arithmetic: same answer)
    for (const auto& [node, tri] : kept_.point_triangle) {
      if (node_box_[node].overlaps(tri_box_[tri])) out->point_triangle.emplace_back(node, tri);
    }
    for (const auto& [a, b] : kept_.edge_edge) {
      if (edge_box_[a].overlaps(edge_box_[b])) out->edge_edge.emplace_back(a, b);
    }
    return;
  }
  const int n = mesh.num_nodes;
  moved_.resize(n);
  double most_moved = 0.0;
  padNodeBoxes(pad);
  for (int i = 0; i < n; ++i) {
    const auto ref = kept_reference_.segment<3>(3 * i);
    moved_[i] = std::sqrt(std::max((x0.segment<3>(3 * i) - ref).squaredNorm(),
                                   (x1.segment<3>(3 * i) - ref).squaredNorm()));
    most_moved = std::max(most_moved, moved_[i]);
  }
  // A pair is left out only when its bound clears `below` by more than the
  // round-off of the distances and displacements it is made of. No pair's
  // bound is below its distance less `reach` (neither side moved more than
  // most_moved; rounding is monotone).
  Cull c;
  c.below = cull.below * (1.0 + 1e-9) + 1e-12;
  c.factor = cull.factor;
  c.reach = cull.factor * (most_moved + most_moved);
  c.exact_bound = cull.exact_bound;
  c.culled = out->culled_bound;
  // The pairs in the bins before the first that lies wholly beyond reach:
  // when they are many (a cloth moving far since the hashing), one pass in
  // kept order, its boxes merged at once and its answer in order, is cheaper.
  int near = 1;
  while (near < kDistanceBins && !(binNearest(near) - c.reach > c.below)) ++near;
  const size_t near_pairs = point_triangle_bins_[near] + edge_edge_bins_[near];
  if (4 * near_pairs > kept_.point_triangle.size() + kept_.edge_edge.size()) {
    filterInOrder(mesh, &c, out);
  } else {
    filterByDistance(mesh, &c, out);
  }
  out->culled_bound = c.culled;
}

double SpatialHash::pointTriangleMoved(const CollisionMesh& mesh, int node, int tri) const {
  const Eigen::Vector3i& t = mesh.triangles[tri];
  return moved_[node] + std::max({moved_[t[0]], moved_[t[1]], moved_[t[2]]});
}

double SpatialHash::edgeEdgeMoved(const CollisionMesh& mesh, int a, int b) const {
  const Eigen::Vector2i& ea = mesh.edges[a];
  const Eigen::Vector2i& eb = mesh.edges[b];
  return std::max(moved_[ea[0]], moved_[ea[1]]) + std::max(moved_[eb[0]], moved_[eb[1]]);
}

void SpatialHash::filterInOrder(const CollisionMesh& mesh, Cull* c, CandidatePairs* out) {
  mergeElementBoxes(mesh);
  for (const KeptPair& p : point_triangle_measured_) {
    if (c->beyondReach(p.distance) || !node_box_[p.a].overlaps(tri_box_[p.b])) continue;
    if (!c->leftOut(p.distance, pointTriangleMoved(mesh, p.a, p.b))) {
      out->point_triangle.emplace_back(p.a, p.b);
    }
  }
  for (const KeptPair& p : edge_edge_measured_) {
    if (c->beyondReach(p.distance) || !edge_box_[p.a].overlaps(edge_box_[p.b])) continue;
    if (!c->leftOut(p.distance, edgeEdgeMoved(mesh, p.a, p.b))) out->edge_edge.emplace_back(p.a, p.b);
  }
}

void SpatialHash::filterByDistance(const CollisionMesh& mesh, Cull* c, CandidatePairs* out) {
  // Element boxes merged when a pair first needs one (the same boxes).
  ++box_query_;
  tri_box_.resize(mesh.triangles.size());
  tri_box_query_.resize(mesh.triangles.size(), -1);
  edge_box_.resize(mesh.edges.size());
  edge_box_query_.resize(mesh.edges.size(), -1);
  auto triBox = [&](int k) -> const Box& {
    if (tri_box_query_[k] != box_query_) {
      const Eigen::Vector3i& t = mesh.triangles[k];
      tri_box_[k] = merge(merge(node_box_[t[0]], node_box_[t[1]]), node_box_[t[2]]);
      tri_box_query_[k] = box_query_;
    }
    return tri_box_[k];
  };
  auto edgeBox = [&](int k) -> const Box& {
    if (edge_box_query_[k] != box_query_) {
      edge_box_[k] = merge(node_box_[mesh.edges[k][0]], node_box_[mesh.edges[k][1]]);
      edge_box_query_[k] = box_query_;
    }
    return edge_box_[k];
  };
  // Bin by bin, nearest first. From a bin whose nearest distance less reach
  // clears below, every pair is left out: the scan stops there (with the
  // exact bound only once that also cannot lower the smallest bound so far).
  auto scan = [&](const std::vector<KeptPair>& binned, const std::vector<int>& bins, auto&& visit) {
    for (int b = 0; b < kDistanceBins; ++b) {
      const double nearest = binNearest(b) - c->reach;
      if (b > 0 && nearest > c->below && (!c->exact_bound || nearest >= c->culled)) {
        c->culled = std::min(c->culled, nearest);  // (exact bound: no change)
        return;
      }
      for (int k = bins[b]; k < bins[b + 1]; ++k) visit(binned[k]);
    }
  };
  // The answer in kept_'s order (pair order): a few chosen indices sorted,
  // many listed by a pass over the kept pairs.
  auto emit = [&](const std::vector<std::pair<int, int>>& kept, std::vector<long>* chosen_at,
                  std::vector<std::pair<int, int>>* answer) {
    if (chosen_.size() * 16 < kept.size()) {
      std::sort(chosen_.begin(), chosen_.end());
      for (int k : chosen_) answer->push_back(kept[k]);
    } else {
      chosen_at->resize(kept.size(), -1);
      for (int k : chosen_) (*chosen_at)[k] = box_query_;
      for (size_t k = 0; k < kept.size(); ++k) {
        if ((*chosen_at)[k] == box_query_) answer->push_back(kept[k]);
      }
    }
  };
  chosen_.clear();
  scan(point_triangle_binned_, point_triangle_bins_, [&](const KeptPair& p) {
    if (c->beyondReach(p.distance) || !node_box_[p.a].overlaps(triBox(p.b))) return;
    if (!c->leftOut(p.distance, pointTriangleMoved(mesh, p.a, p.b))) chosen_.push_back(p.index);
  });
  emit(kept_.point_triangle, &point_triangle_chosen_, &out->point_triangle);
  chosen_.clear();
  scan(edge_edge_binned_, edge_edge_bins_, [&](const KeptPair& p) {
    if (c->beyondReach(p.distance) || !edgeBox(p.a).overlaps(edgeBox(p.b))) return;
    if (!c->leftOut(p.distance, edgeEdgeMoved(mesh, p.a, p.b))) chosen_.push_back(p.index);
  });
  emit(kept_.edge_edge, &edge_edge_chosen_, &out->edge_edge);
}

}  // namespace cloth_sim
