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
  const int n = mesh.num_nodes;
  for (int i = 0; i < n; ++i) {
    node_box_[i] = Box{node_box_[i].lo.array() - pad, node_box_[i].hi.array() + pad};
  }
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

  buildTable(tri_box_, &tri_table_);
  for (int i = 0; i < n; ++i) {
    const Box& box = node_box_[i];
    forCells(box, [&](long ix, long iy, long iz) {
      const unsigned bucket = cellHash(ix, iy, iz) & tri_table_.mask;
      for (int k = tri_table_.start[bucket]; k < tri_table_.start[bucket + 1]; ++k) {
        const int tri = tri_table_.ids[k];
        const Eigen::Vector3i& t = mesh.triangles[tri];
        if (t[0] == i || t[1] == i || t[2] == i || !box.overlaps(tri_box_[tri])) continue;
        kept_.point_triangle.emplace_back(i, tri);
      }
    });
  }
  buildTable(edge_box_, &edge_table_);
  for (size_t a = 0; a < mesh.edges.size(); ++a) {
    const Box& box = edge_box_[a];
    const int a0 = mesh.edges[a][0], a1 = mesh.edges[a][1];
    forCells(box, [&](long ix, long iy, long iz) {
      const unsigned bucket = cellHash(ix, iy, iz) & edge_table_.mask;
      for (int k = edge_table_.start[bucket]; k < edge_table_.start[bucket + 1]; ++k) {
        const int b = edge_table_.ids[k];
        if (b <= static_cast<int>(a)) continue;
        const int b0 = mesh.edges[b][0], b1 = mesh.edges[b][1];
        if (b0 == a0 || b0 == a1 || b1 == a0 || b1 == a1 || !box.overlaps(edge_box_[b])) continue;
        kept_.edge_edge.emplace_back(static_cast<int>(a), b);
      }
    });
  }
  // A pair shares several cells (and hashed buckets): keep it once.
  for (auto* pairs : {&kept_.point_triangle, &kept_.edge_edge}) {
    std::sort(pairs->begin(), pairs->end());
    pairs->erase(std::unique(pairs->begin(), pairs->end()), pairs->end());
  }
}

void SpatialHash::measureKept(const CollisionMesh& mesh) {
  const VecX& x = kept_reference_;
  auto at = [&](int i) { return x.segment<3>(3 * i); };
  kept_point_triangle_distance_.resize(kept_.point_triangle.size());
  for (size_t k = 0; k < kept_.point_triangle.size(); ++k) {
    const auto& [node, tri] = kept_.point_triangle[k];
    const Eigen::Vector3i& t = mesh.triangles[tri];
    kept_point_triangle_distance_[k] = pointTriangleDistance(at(node), at(t[0]), at(t[1]), at(t[2]));
  }
  kept_edge_edge_distance_.resize(kept_.edge_edge.size());
  for (size_t k = 0; k < kept_.edge_edge.size(); ++k) {
    const Eigen::Vector2i& a = mesh.edges[kept_.edge_edge[k].first];
    const Eigen::Vector2i& b = mesh.edges[kept_.edge_edge[k].second];
    kept_edge_edge_distance_[k] = edgeEdgeDistance(at(a[0]), at(a[1]), at(b[0]), at(b[1]));
  }
}

void SpatialHash::filterKept(const CollisionMesh& mesh, const VecX& x0, const VecX& x1,
                             double pad, const DistanceCull& cull, CandidatePairs* out) {
  padBoxes(mesh, pad);  // as a fresh query makes them (same arithmetic: same answer)
  const bool culling = cull.below >= 0.0;
  if (culling) {
    const int n = mesh.num_nodes;
    moved_.resize(n);
    for (int i = 0; i < n; ++i) {
      const auto ref = kept_reference_.segment<3>(3 * i);
      moved_[i] = std::sqrt(std::max((x0.segment<3>(3 * i) - ref).squaredNorm(),
                                     (x1.segment<3>(3 * i) - ref).squaredNorm()));
    }
  }
  // A pair is left out only when its bound clears `below` by more than the
  // round-off of the distances and displacements it is made of.
  const double below = cull.below * (1.0 + 1e-9) + 1e-12;
  auto leftOut = [&](double distance, double moved) {
    const double bound = distance - cull.factor * moved;
    if (!(bound > below)) return false;
    out->culled_bound = std::min(out->culled_bound, bound);
    return true;
  };
  for (size_t k = 0; k < kept_.point_triangle.size(); ++k) {
    const auto& [node, tri] = kept_.point_triangle[k];
    if (!node_box_[node].overlaps(tri_box_[tri])) continue;
    if (culling) {
      const Eigen::Vector3i& t = mesh.triangles[tri];
      const double moved = moved_[node] + std::max({moved_[t[0]], moved_[t[1]], moved_[t[2]]});
      if (leftOut(kept_point_triangle_distance_[k], moved)) continue;
    }
    out->point_triangle.emplace_back(node, tri);
  }
  for (size_t k = 0; k < kept_.edge_edge.size(); ++k) {
    const auto& [a, b] = kept_.edge_edge[k];
    if (!edge_box_[a].overlaps(edge_box_[b])) continue;
    if (culling) {
      const Eigen::Vector2i& ea = mesh.edges[a];
      const Eigen::Vector2i& eb = mesh.edges[b];
      const double moved = std::max(moved_[ea[0]], moved_[ea[1]]) + std::max(moved_[eb[0]], moved_[eb[1]]);
      if (leftOut(kept_edge_edge_distance_[k], moved)) continue;
    }
    out->edge_edge.emplace_back(a, b);
  }
}

}  // namespace cloth_sim
