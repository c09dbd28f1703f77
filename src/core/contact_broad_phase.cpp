#include "cloth_sim/contact_broad_phase.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cloth_sim {

namespace {

/// Slack of the box tests relative to the coordinates' magnitude: far above
/// the round-off of the exact queries' distances (a few ulps), far below
/// anything that would keep a patch that is not near.
constexpr double kRelativeSlack = 1e-9;

/// The box (lo, hi), world, carried into the frame of `pose`: the box around
/// the rotated box (centre moved, half extents through |R^T|).
void toLocalBox(const Vec3& lo, const Vec3& hi, const Pose& pose, Vec3& out_lo, Vec3& out_hi) {
  const Vec3 centre = pose.toLocal(0.5 * (lo + hi));
  const Vec3 half = pose.rotation.transpose().cwiseAbs() * (0.5 * (hi - lo));
  out_lo = centre - half;
  out_hi = centre + half;
}

}  // namespace

void ContactBroadPhase::setGrid(int rows, int cols) {
  if (rows == grid_rows_ && cols == grid_cols_) return;
  grid_rows_ = rows;
  grid_cols_ = cols;
  num_nodes_ = -1;  // lay out again at the next build
}

void ContactBroadPhase::layOut(int num_nodes) {
  if (num_nodes == num_nodes_) return;
  num_nodes_ = num_nodes;
  if (grid_rows_ > 0 && grid_cols_ > 0 &&
      static_cast<long>(grid_rows_) * grid_cols_ == num_nodes) {
    rows_ = grid_rows_;
    cols_ = grid_cols_;
    side_rows_ = side_cols_ = kPatchSide;
  } else {  // no grid: runs of consecutive nodes
    rows_ = num_nodes > 0 ? 1 : 0;
    cols_ = num_nodes;
    side_rows_ = 1;
    side_cols_ = kPatchSide * kPatchSide;
  }
  patch_cols_ = (cols_ + side_cols_ - 1) / side_cols_;
  const int patch_rows = (rows_ + side_rows_ - 1) / side_rows_;
  patch_of_.resize(num_nodes);
  for (int r = 0; r < rows_; ++r) {
    for (int c = 0; c < cols_; ++c) {
      patch_of_[r * cols_ + c] = (r / side_rows_) * patch_cols_ + c / side_cols_;
    }
  }
  boxes_.resize(static_cast<size_t>(patch_rows) * patch_cols_);
  patch_near_any_.resize(boxes_.size());
}

template <class EndOf>
void ContactBroadPhase::sweep(const VecX& x0, const EndOf& end_of) {
  layOut(static_cast<int>(x0.size() / 3));
  const double inf = std::numeric_limits<double>::infinity();
  for (PatchBoxes& b : boxes_) {
    b.lo0 = b.lo1 = Vec3::Constant(inf);
    b.hi0 = b.hi1 = Vec3::Constant(-inf);
    b.finite = true;
  }
  // Row by row, each patch's stretch of the row in locals (no per-node
  // patch lookup, one write per stretch).
  for (int r = 0; r < rows_; ++r) {
    const int band = r / side_rows_;
    for (int pc = 0; pc < patch_cols_; ++pc) {
      PatchBoxes& b = boxes_[band * patch_cols_ + pc];
      Vec3 lo0 = b.lo0, hi0 = b.hi0, lo1 = b.lo1, hi1 = b.hi1;
      double sum = 0.0;  // non-finite iff some coordinate is (or they overflow)
      const int end = std::min(cols_, (pc + 1) * side_cols_);
      for (int i = r * cols_ + pc * side_cols_, last = r * cols_ + end; i < last; ++i) {
        const Vec3 p0 = x0.segment<3>(3 * i), p1 = end_of(i);
        lo0 = lo0.cwiseMin(p0);
        hi0 = hi0.cwiseMax(p0);
        lo1 = lo1.cwiseMin(p1);
        hi1 = hi1.cwiseMax(p1);
        sum += p0.sum() + p1.sum();
      }
      b.lo0 = lo0;
      b.hi0 = hi0;
      b.lo1 = lo1;
      b.hi1 = hi1;
      // min/max may drop a NaN: such a patch is kept near everything.
      b.finite = b.finite && std::isfinite(sum);
    }
  }
}

void ContactBroadPhase::build(const CollidersOverStep& colliders, const VecX& x0,
                              const VecX& x1) {
  sweep(x0, [&x1](int i) { return Vec3(x1.segment<3>(3 * i)); });
  classify(colliders);
}

void ContactBroadPhase::buildPredicted(const CollidersOverStep& colliders, const VecX& x0,
                                       const VecX& v0, const Vec3& gravity, double h) {
  // The same prediction as ContactSet::begin's.
  sweep(x0, [&](int i) {
    return Vec3(x0.segment<3>(3 * i) + h * v0.segment<3>(3 * i) + h * h * gravity);
  });
  classify(colliders);
}

bool ContactBroadPhase::near(const PatchBoxes& b, const CollidersOverStep& colliders,
                             size_t k) const {
  const Collider& collider = (*colliders.colliders)[k];
  // The hull of the start box in the start frame and the end box in the end
  // frame holds every node's path segment in the collider's frame.
  Vec3 lo, hi, lo1, hi1;
  toLocalBox(b.lo0, b.hi0, colliders.start[k], lo, hi);
  toLocalBox(b.lo1, b.hi1, colliders.end[k], lo1, hi1);
  lo = lo.cwiseMin(lo1);
  hi = hi.cwiseMax(hi1);
  double scale = std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff());
  // Every test below is written as "far": a NaN anywhere leaves it near.
  if (collider.type() == Collider::Type::Plane) {
    const Vec3& n = collider.planeNormal();
    const double reach = colliders.thickness + kRelativeSlack * (1.0 + scale);
    const double lowest = n.dot(0.5 * (lo + hi)) - n.cwiseAbs().dot(0.5 * (hi - lo));
    return !(lowest > reach);
  }
  Vec3 shape_lo, shape_hi;  // the shape's box, own frame
  switch (collider.type()) {
    case Collider::Type::Sphere:
      shape_hi = Vec3::Constant(collider.radius());
      shape_lo = -shape_hi;
      break;
    case Collider::Type::Capsule:
      shape_lo = collider.segment().cwiseMin(Vec3::Zero()) - Vec3::Constant(collider.radius());
      shape_hi = collider.segment().cwiseMax(Vec3::Zero()) + Vec3::Constant(collider.radius());
      break;
    case Collider::Type::Box:
    default:
      shape_hi = collider.halfExtents();
      shape_lo = -shape_hi;
      break;
  }
  scale = std::max({scale, shape_lo.cwiseAbs().maxCoeff(), shape_hi.cwiseAbs().maxCoeff()});
  const double reach = colliders.thickness + kRelativeSlack * (1.0 + scale);
  for (int a = 0; a < 3; ++a) {
    if (lo[a] > shape_hi[a] + reach || hi[a] < shape_lo[a] - reach) return false;
  }
  return true;
}

void ContactBroadPhase::classify(const CollidersOverStep& colliders) {
  num_colliders_ = colliders.empty() ? 0 : colliders.colliders->size();
  near_.assign(boxes_.size() * num_colliders_, 0);
  for (size_t p = 0; p < boxes_.size(); ++p) {
    bool any = false;
    for (size_t k = 0; k < num_colliders_; ++k) {
      const bool is_near = !boxes_[p].finite || near(boxes_[p], colliders, k);
      near_[p * num_colliders_ + k] = is_near;
      any = any || is_near;
    }
    patch_near_any_[p] = any;
  }
  // The near patches' nodes in ascending order: row by row, each row's
  // stretch of every near patch of its band.
  candidates_.clear();
  for (int r = 0; r < rows_; ++r) {
    const int band = r / side_rows_;
    for (int pc = 0; pc < patch_cols_; ++pc) {
      if (!patch_near_any_[band * patch_cols_ + pc]) continue;
      const int end = std::min(cols_, (pc + 1) * side_cols_);
      for (int c = pc * side_cols_; c < end; ++c) candidates_.push_back(r * cols_ + c);
    }
  }
}

int ContactBroadPhase::numNearPatches() const {
  return static_cast<int>(std::count(patch_near_any_.begin(), patch_near_any_.end(), 1));
}

}  // namespace cloth_sim
