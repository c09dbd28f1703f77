// Broad phase of the node-against-collider contact detection (docs/design.md,
// "Contact"): which nodes' exact queries (firstContact, closest) can find
// anything this pass, so that detection costs the nodes near colliders
// rather than every node.
//
// The nodes are grouped in fixed patches of the grid (kPatchSide x
// kPatchSide nodes; 1 x kPatchSide^2 consecutive nodes when no grid is
// known). Each pass, one min/max sweep gives every patch a box around its
// nodes' start positions and one around their end positions. A collider is
// queried in its own frame, where a node's path is the segment from
// pose0^-1 x0 to pose1^-1 x1 (firstContact's path): both boxes are carried
// into that frame and the patch's swept box is their hull, tested against
// the shape's box (sphere, capsule, box) or half-space (plane) inflated by
// the thickness. A patch that stays out of it cannot hold a node within the
// thickness of that collider at any time of the step: its nodes get no
// query for it. The test is conservative (a slack well above round-off),
// and a patch with a non-finite coordinate counts as near everything, so
// the exact queries see every node that could answer, in the same order.
#pragma once

#include <cstdint>
#include <vector>

#include "cloth_sim/collider.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim {

class ContactBroadPhase {
 public:
  /// Grid nodes on each side of a patch.
  static constexpr int kPatchSide = 8;

  /// Lays the patches on a rows x cols grid (node i = row * cols + col); a
  /// call whose rows x cols is not the number of nodes of the next build
  /// falls back to runs of consecutive nodes.
  void setGrid(int rows, int cols);

  /// A pass over the paths x0 -> x1 (3n vectors).
  void build(const CollidersOverStep& colliders, const VecX& x0, const VecX& x1);
  /// A pass over the predicted paths x0 -> x0 + h v0 + h^2 g (ContactSet::begin).
  void buildPredicted(const CollidersOverStep& colliders, const VecX& x0, const VecX& v0,
                      const Vec3& gravity, double h);

  /// The nodes whose patch may come near some collider, ascending.
  const std::vector<int>& candidates() const { return candidates_; }
  /// Whether node i's patch may come within the thickness of collider k.
  bool mayTouch(int node, int collider) const {
    return near_[static_cast<size_t>(patch_of_[node]) * num_colliders_ + collider] != 0;
  }
  /// Patches of the last build, and those near some collider.
  int numPatches() const { return static_cast<int>(patch_near_any_.size()); }
  int numNearPatches() const;
  /// The patch holding node i (after a build).
  int patchOf(int node) const { return patch_of_[node]; }

 private:
  /// A patch's boxes: around the start and the end positions of its nodes.
  struct PatchBoxes {
    Vec3 lo0, hi0, lo1, hi1;
    bool finite = true;
  };
  /// Patch layout for n nodes (a grid if setGrid's matches, else runs).
  void layOut(int num_nodes);
  /// The patch boxes around every node's start x0[i] and end endOf(i).
  template <class EndOf>
  void sweep(const VecX& x0, const EndOf& end_of);
  /// Near flags of every patch and collider, then the candidates.
  void classify(const CollidersOverStep& colliders);
  /// Whether the swept box of `b` comes within the thickness of collider k.
  bool near(const PatchBoxes& b, const CollidersOverStep& colliders, size_t k) const;

  int grid_rows_ = 0, grid_cols_ = 0;  ///< as set (0: none)
  int rows_ = 0, cols_ = 0;            ///< the layout in use: rows_ x cols_ nodes
  int side_rows_ = 0, side_cols_ = 0;  ///< a patch's extent in that layout
  int patch_cols_ = 0;                 ///< patches per layout row band
  int num_nodes_ = -1;
  size_t num_colliders_ = 0;
  std::vector<int> patch_of_;          ///< per node
  std::vector<PatchBoxes> boxes_;      ///< per patch
  std::vector<std::uint8_t> near_;     ///< per patch x collider
  std::vector<std::uint8_t> patch_near_any_;  ///< per patch
  std::vector<int> candidates_;
};

}  // namespace cloth_sim
