#include "lmalign/search/kdtree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {

constexpr std::uint32_t kLeafBit = 0x80000000u;
// Deepest tree: 2 log2(n) + 8 levels of sliding-midpoint splits, then at most log2(n) median
// splits (n < 2^31): 101.
constexpr int kMaxDepth = 104;

// 16 bytes. Nodes are stored in pre-order, so the left child of node i is node i + 1. An internal
// node splits its points on one axis: every left point has coordinate <= left_max, every right
// point >= right_min: the bounds of the two halves on that axis, rounded outwards to float (so
// they remain bounds; +-inf when out of float range, i.e. no bound).
struct Node {
  float left_max = 0.0f;
  float right_min = 0.0f;
  std::uint32_t a = 0;  // internal: index of the right child; leaf: first slot of `perm`
  std::uint32_t b = 0;  // internal: split axis (0..2); leaf: one past the last slot | kLeafBit
};

// The smallest float >= x, and the largest float <= x (infinite beyond the float range).
float float_at_least(double x) {
  if (!(x <= static_cast<double>(std::numeric_limits<float>::max()))) {
    return std::numeric_limits<float>::infinity();
  }
  if (x < -static_cast<double>(std::numeric_limits<float>::max())) {
    return -std::numeric_limits<float>::max();
  }
  float f = static_cast<float>(x);
  if (static_cast<double>(f) < x) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}
float float_at_most(double x) { return -float_at_least(-x); }

// The best `cap` candidates seen so far, sorted in the total order (d2, index). Writes straight
// into the caller's arrays.
class Best {
 public:
  // `idx`/`d2` may already hold `n` entries, sorted, distinct (the seeds).
  Best(PointIndex* idx, double* d2, std::size_t cap, std::size_t n)
      : idx_(idx), d2_(d2), cap_(cap), n_(std::min(n, cap)) {
    if (n_ == cap_) bound_ = d2_[n_ - 1];
  }

  std::size_t size() const { return n_; }
  // Squared distance a candidate must not exceed to be considered (+inf until full).
  double bound() const { return bound_; }

  // Keeps (d, i) if it is among the `cap` first in the total order. An entry already held (same
  // index, hence the same key) is not added twice.
  void offer(double d, PointIndex i) {
    if (n_ == cap_ && (d > bound_ || (d == bound_ && i >= idx_[n_ - 1]))) return;
    // Position: how many held entries come first (branch-free count; the held keys are distinct).
    std::size_t pos = 0;
    for (std::size_t j = 0; j < n_; ++j) {
      pos += static_cast<std::size_t>((d2_[j] < d) | ((d2_[j] == d) & (idx_[j] < i)));
    }
    if (pos < n_ && d2_[pos] == d && idx_[pos] == i) return;  // held already (a seed)
    const std::size_t last = n_ < cap_ ? n_ : cap_ - 1;
    for (std::size_t j = last; j > pos; --j) {
      d2_[j] = d2_[j - 1];
      idx_[j] = idx_[j - 1];
    }
    d2_[pos] = d;
    idx_[pos] = i;
    if (n_ < cap_) ++n_;
    if (n_ == cap_) bound_ = d2_[n_ - 1];
  }

 private:
  PointIndex* idx_;
  double* d2_;
  std::size_t cap_;
  std::size_t n_ = 0;
  double bound_ = std::numeric_limits<double>::infinity();
};

}  // namespace

struct KdTree::Impl {
  Points3 points;
  std::vector<PointIndex> perm;  // leaf slots -> point index
  std::vector<Node> nodes;
  Vec3 box_min = Vec3::Zero(), box_max = Vec3::Zero();  // bounding box of all points
  std::size_t leaf_size = 8;
  int max_depth = 64;

  // Sliding-midpoint construction: a node halves its cell (the region it covers, not the bounding
  // box of its points) on the cell's longest axis, the cut slid onto the points if it misses
  // them. Cells stay compact, which prunes well also for queries far from the data. Beyond
  // max_depth (degenerate distributions), the median is used: the depth stays O(log n).
  std::uint32_t build(std::uint32_t lo, std::uint32_t hi, int depth, Vec3 cell_lo, Vec3 cell_hi) {
    const auto id = static_cast<std::uint32_t>(nodes.size());
    nodes.emplace_back();
    if (hi - lo <= leaf_size || depth >= kMaxDepth) {  // (the depth bound never binds; see above)
      nodes[id].a = lo;
      nodes[id].b = hi | kLeafBit;
      return id;
    }
    Vec3 lo_c = points[perm[lo]], hi_c = lo_c;
    for (std::uint32_t i = lo + 1; i < hi; ++i) {
      lo_c = lo_c.cwiseMin(points[perm[i]]);
      hi_c = hi_c.cwiseMax(points[perm[i]]);
    }
    const Vec3 spread = hi_c - lo_c;
    if (!(spread.maxCoeff() > 0.0)) {  // all points equal: one (large) leaf, still exact
      nodes[id].a = lo;
      nodes[id].b = hi | kLeafBit;
      return id;
    }
    // The longest cell axis; among axes nearly as long, the one where the points spread most.
    const Vec3 span = cell_hi - cell_lo;
    const double max_span = span.maxCoeff();
    int dim = -1;
    for (int d = 0; d < 3; ++d) {
      if (span[d] >= (1.0 - 1e-5) * max_span && spread[d] > 0.0 &&
          (dim < 0 || spread[d] > spread[dim])) {
        dim = d;
      }
    }
    if (dim < 0) {  // the long axes have no spread: the axis of largest spread
      dim = 0;
      if (spread[1] > spread[dim]) dim = 1;
      if (spread[2] > spread[dim]) dim = 2;
    }
    const Points3& pts = points;
    const double cut = std::clamp(0.5 * (cell_lo[dim] + cell_hi[dim]), lo_c[dim], hi_c[dim]);
    std::uint32_t mid = static_cast<std::uint32_t>(
        std::partition(perm.begin() + lo, perm.begin() + hi,
                       [&pts, dim, cut](PointIndex x) { return pts[x][dim] < cut; }) -
        perm.begin());
    if (mid == lo) {  // cut slid onto the smallest coordinate: those points go left
      mid = static_cast<std::uint32_t>(
          std::partition(perm.begin() + lo, perm.begin() + hi,
                         [&pts, dim, cut](PointIndex x) { return pts[x][dim] <= cut; }) -
          perm.begin());
    }
    double child_cut = cut;
    if (depth >= max_depth || mid == lo || mid == hi) {
      mid = lo + (hi - lo) / 2;
      std::nth_element(perm.begin() + lo, perm.begin() + mid, perm.begin() + hi,
                       [&pts, dim](PointIndex x, PointIndex y) {
                         const double cx = pts[x][dim], cy = pts[y][dim];
                         return cx < cy || (cx == cy && x < y);
                       });
      child_cut = pts[perm[mid]][dim];
    }
    double left_max = points[perm[lo]][dim];
    for (std::uint32_t i = lo + 1; i < mid; ++i) left_max = std::max(left_max, points[perm[i]][dim]);
    double right_min = points[perm[mid]][dim];
    for (std::uint32_t i = mid + 1; i < hi; ++i) right_min = std::min(right_min, points[perm[i]][dim]);
    Vec3 left_hi = cell_hi, right_lo = cell_lo;
    left_hi[dim] = child_cut;
    right_lo[dim] = child_cut;
    build(lo, mid, depth + 1, cell_lo, left_hi);  // left child: id + 1
    const std::uint32_t right = build(mid, hi, depth + 1, right_lo, cell_hi);
    nodes[id].left_max = float_at_least(left_max);
    nodes[id].right_min = float_at_most(right_min);
    nodes[id].a = right;
    nodes[id].b = static_cast<std::uint32_t>(dim);
    return id;
  }

  // Depth-first, nearer child first, with an explicit stack of deferred far children. `off`
  // holds, per axis, the signed offset from the query to the current cell's extent (0 inside);
  // the cell's lower bound is its squared norm. Every offset is q[d] - c with c a coordinate bound
  // of the cell, and rounding is monotone, so that bound never exceeds the computed squared
  // distance of a point in the cell: pruning with '>' is exact, and cells at exactly the bound are
  // visited (a tie with a lower index may be there).
  struct Deferred {
    std::uint32_t node;
    double cell_d2;
    double off[3];
  };
  static double norm2(const double* off) {
    return off[0] * off[0] + off[1] * off[1] + off[2] * off[2];
  }

  // Offers every point of leaf slots [begin, end) to `best`: squared distances computed in
  // blocks (vectorised), then compared with the bound.
  // Offers every point of leaf slots [begin, end) to `best`.
  void scan_leaf(std::uint32_t begin, std::uint32_t end, const Vec3& q, Best& best) const {
    double bound = best.bound();
    for (std::uint32_t s = begin; s < end; ++s) {
      const PointIndex i = perm[s];
      const double d = squared_distance(q, points[i]);
      if (d <= bound) {
        best.offer(d, i);
        bound = best.bound();
      }
    }
  }

  void search(const Vec3& q, const double* off0, Best& best) const {
    Deferred stack[kMaxDepth + 1];
    int top = 0;
    std::uint32_t node_id = 0;
    double off[3] = {off0[0], off0[1], off0[2]};
    double cell_d2 = norm2(off);
    for (;;) {
      // Descend towards the query, deferring the far halves.
      while (cell_d2 <= best.bound()) {
        const Node& node = nodes[node_id];
        if (node.b & kLeafBit) {
          scan_leaf(node.a, node.b & ~kLeafBit, q, best);
          break;
        }
        const std::uint32_t dim = node.b;
        const double qd = q[dim];
        // Offsets to each half along `dim`, 0 when the query is on that half's side of its
        // bound (the ancestors' offset along `dim`, if any, then still holds).
        const double lo_off = qd - static_cast<double>(node.left_max);
        const double hi_off = qd - static_cast<double>(node.right_min);
        const double to_left = std::max(lo_off, 0.0);   // (branch-free: the outcome of these
        const double to_right = std::min(hi_off, 0.0);  // comparisons is unpredictable)
        const bool left_near = -to_right > to_left;
        Deferred& far = stack[top++];
        far.node = left_near ? node.a : node_id + 1;
        far.off[0] = off[0];
        far.off[1] = off[1];
        far.off[2] = off[2];
        const double off_far = left_near ? to_right : to_left;
        far.off[dim] = off_far != 0.0 ? off_far : far.off[dim];
        far.cell_d2 = norm2(far.off);
        const double off_near = left_near ? to_left : to_right;
        off[dim] = off_near != 0.0 ? off_near : off[dim];
        cell_d2 = norm2(off);
        node_id = left_near ? node_id + 1 : node.a;
      }
      // Resume at the nearest deferred half still within the bound.
      for (;;) {
        if (top == 0) return;
        const Deferred& d = stack[--top];
        if (d.cell_d2 <= best.bound()) {
          node_id = d.node;
          off[0] = d.off[0];
          off[1] = d.off[1];
          off[2] = d.off[2];
          cell_d2 = d.cell_d2;
          break;
        }
      }
    }
  }

  std::size_t query(const Vec3& q, std::size_t k, const PointIndex* seed_idx, const double* seed_d2,
                    std::size_t num_seeds, PointIndex* indices, double* d2) const {
    if (nodes.empty() || k == 0 || !q.allFinite()) return 0;
    const std::size_t cap = std::min(k, points.size());
    const std::size_t seeded = std::min(num_seeds, cap);
    for (std::size_t j = 0; j < seeded; ++j) {  // (a no-op when seeding in place)
      indices[j] = seed_idx[j];
      d2[j] = seed_d2[j];
    }
    Best best(indices, d2, cap, seeded);
    double off[3];
    for (int d = 0; d < 3; ++d) {
      off[d] = q[d] < box_min[d] ? q[d] - box_min[d] : q[d] > box_max[d] ? q[d] - box_max[d] : 0.0;
    }
    search(q, off, best);
    return best.size();
  }
};

KdTree::KdTree(Points3 points, std::size_t leaf_size) : impl_(std::make_unique<Impl>()) {
  if (points.size() >= static_cast<std::size_t>(kLeafBit) - 1) {
    throw InvalidArgument("kd-tree: too many points (" + std::to_string(points.size()) + ")");
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      throw InvalidArgument("kd-tree: point " + std::to_string(i) + " is not finite");
    }
  }
  if (leaf_size == 0) throw InvalidArgument("kd-tree: leaf_size must be >= 1");
  impl_->leaf_size = leaf_size;
  impl_->points = std::move(points);
  const std::size_t n = impl_->points.size();
  if (n == 0) return;
  impl_->perm.resize(n);
  for (std::size_t i = 0; i < n; ++i) impl_->perm[i] = static_cast<PointIndex>(i);
  impl_->box_min = impl_->box_max = impl_->points[0];
  for (const Vec3& p : impl_->points) {
    impl_->box_min = impl_->box_min.cwiseMin(p);
    impl_->box_max = impl_->box_max.cwiseMax(p);
  }
  impl_->nodes.reserve(2 * (n / std::max<std::size_t>(1, leaf_size / 2)) + 1);
  int log2n = 0;
  while ((std::size_t{1} << log2n) < n) ++log2n;
  impl_->max_depth = 2 * log2n + 8;
  impl_->build(0, static_cast<std::uint32_t>(n), 0, impl_->box_min, impl_->box_max);
  impl_->nodes.shrink_to_fit();
}

KdTree::~KdTree() = default;
KdTree::KdTree(KdTree&&) noexcept = default;
KdTree& KdTree::operator=(KdTree&&) noexcept = default;

std::size_t KdTree::size() const { return impl_->points.size(); }
const Points3& KdTree::points() const { return impl_->points; }

std::size_t KdTree::knn(const Vec3& query, std::size_t k, PointIndex* indices,
                        double* distances_sq_m2) const {
  return impl_->query(query, k, nullptr, nullptr, 0, indices, distances_sq_m2);
}

std::size_t KdTree::knn_seeded(const Vec3& query, std::size_t k, const PointIndex* seed_indices,
                               const double* seed_distances_sq_m2, std::size_t num_seeds,
                               PointIndex* indices, double* distances_sq_m2) const {
  return impl_->query(query, k, seed_indices, seed_distances_sq_m2, num_seeds, indices,
                      distances_sq_m2);
}

bool KdTree::nearest(const Vec3& query, PointIndex* index, double* distance_sq_m2) const {
  return knn(query, 1, index, distance_sq_m2) == 1;
}

std::size_t KdTree::memory_bytes() const {
  return impl_->points.capacity() * sizeof(Vec3) + impl_->perm.capacity() * sizeof(PointIndex) +
         impl_->nodes.capacity() * sizeof(Node);
}

}  // namespace lmalign
