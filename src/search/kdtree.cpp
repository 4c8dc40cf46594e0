#include "lmalign/search/kdtree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace lmalign {

namespace {

// The tree is complete and balanced: 2^depth leaves of at most leaf_size points each, split at
// the median on the axis of largest spread, stored implicitly in heap order (children of node i
// are 2i + 1 and 2i + 2; leaf j is node 2^depth - 1 + j). Depth <= 31 for n < 2^31.
constexpr int kMaxDepth = 32;

// 12 bytes per internal node: every left point has coordinate <= left_max on `axis`, every
// right point >= right_min -- the bounds of the two halves, rounded outwards to float so that
// they remain bounds (+-inf beyond the float range: no bound).
struct Node {
  float left_max = 0.0f;
  float right_min = 0.0f;
  std::uint32_t axis = 0;
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
  // `idx`/`d2` may already hold `n` entries, sorted, distinct (the seeds). Only candidates with
  // d2 <= limit_d2 are kept (a seeded search takes the default, +inf).
  Best(PointIndex* idx, double* d2, std::size_t cap, std::size_t n,
       double limit_d2 = std::numeric_limits<double>::infinity())
      : idx_(idx), d2_(d2), cap_(cap), n_(std::min(n, cap)), bound_(limit_d2) {
    if (n_ == cap_) bound_ = d2_[n_ - 1];
  }

  std::size_t size() const { return n_; }
  // Squared distance a candidate must not exceed to be considered (the limit until full).
  double bound() const { return bound_; }

  // Keeps (d, i) if it is among the `cap` first in the total order (and within the limit). An
  // entry already held (same index, hence the same key) is not added twice.
  void offer(double d, PointIndex i) {
    if (d > bound_ || (n_ == cap_ && d == bound_ && i >= idx_[n_ - 1])) return;
    // Insertion from the back: shift the held entries that come after (d, i) one place down
    // (the last one falls off when full). An entry already held (same index, hence the same key:
    // a seed) stops the insertion. (A branch-free count of the place mispredicts less but costs
    // more instructions, which is what two threads sharing a core pay for: docs/performance.md.)
    std::size_t pos = n_ < cap_ ? n_ : cap_ - 1;
    while (pos > 0 && (d2_[pos - 1] > d || (d2_[pos - 1] == d && idx_[pos - 1] > i))) --pos;
    if (pos > 0 && d2_[pos - 1] == d && idx_[pos - 1] == i) return;  // held already (a seed)
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
  double bound_;
};

}  // namespace

struct KdTree::Impl {
  Points3 points;
  std::vector<PointIndex> perm;           // leaf slots -> point index
  std::vector<Node> nodes;                // 2^depth - 1 internal nodes, heap order
  std::vector<std::uint32_t> leaf_begin;  // 2^depth + 1 slot offsets
  int depth = 0;
  Vec3 box_min = Vec3::Zero(), box_max = Vec3::Zero();  // bounding box of all points

  void build(std::uint32_t node, int level, std::uint32_t lo, std::uint32_t hi) {
    if (level == depth) {
      leaf_begin[node - static_cast<std::uint32_t>(nodes.size())] = lo;
      return;
    }
    int axis = 0;
    if (hi > lo) {
      Vec3 lo_c = points[perm[lo]], hi_c = lo_c;
      for (std::uint32_t i = lo + 1; i < hi; ++i) {
        lo_c = lo_c.cwiseMin(points[perm[i]]);
        hi_c = hi_c.cwiseMax(points[perm[i]]);
      }
      const Vec3 spread = hi_c - lo_c;
      if (spread[1] > spread[axis]) axis = 1;
      if (spread[2] > spread[axis]) axis = 2;
    }
    // The left half gets the larger share, so every leaf ends with at most leaf_size points.
    const std::uint32_t mid = lo + (hi - lo + 1) / 2;
    const Points3& pts = points;
    if (hi - lo > 1) {
      std::nth_element(perm.begin() + lo, perm.begin() + mid, perm.begin() + hi,
                       [&pts, axis](PointIndex x, PointIndex y) {
                         const double cx = pts[x][axis], cy = pts[y][axis];
                         return cx < cy || (cx == cy && x < y);
                       });
    }
    double left_max = -std::numeric_limits<double>::infinity();
    double right_min = std::numeric_limits<double>::infinity();
    for (std::uint32_t i = lo; i < mid; ++i) left_max = std::max(left_max, pts[perm[i]][axis]);
    for (std::uint32_t i = mid; i < hi; ++i) right_min = std::min(right_min, pts[perm[i]][axis]);
    nodes[node] = {float_at_least(left_max), float_at_most(right_min),
                   static_cast<std::uint32_t>(axis)};
    build(2 * node + 1, level + 1, lo, mid);
    build(2 * node + 2, level + 1, mid, hi);
  }

  // The float prefilter of the leaf scans: float copies of the coordinates, relative to the
  // centre of the bounding box, in leaf-slot order (12 bytes per point). A point whose float
  // distance exceeds a threshold provably lies beyond the exact bound (see threshold()), so the
  // exact double distance is computed only for the few that pass: the offers to `best`, and so
  // the result, are exactly those of the plain scan.
  std::vector<float> fx, fy, fz;  // slot -> coordinate - centre (padded by 4 slots of +inf)
  Vec3 centre = Vec3::Zero();
  double rel_max = 0.0;  // largest |p - centre| over the points and axes
  // Beyond this (relative coordinates), float copies could overflow: exact scans only.
  static constexpr double kFilterMax = 1e30;

  // What a query needs for the prefilter.
  struct Query {
    Vec3 q;
    float qf[3];
    bool filter;   // false: exact scans only (query or points too far from the centre)
    double slack;  // absolute allowance for the float rounding: 2^-21 (rel_max + |q - centre|)
    // Bit i set: point i is a seed, held by `best` already (or beyond it): not offered again.
    const std::uint64_t* seed_marks = nullptr;
    // The float threshold of the last leaf scan and the bound it was made for: the bound often
    // does not change from one leaf to the next, and the threshold costs a square root.
    double thr_bound = -1.0;
    float thr = 0.0f;
    bool is_seed(PointIndex i) const {
      return seed_marks != nullptr && ((seed_marks[i >> 6] >> (i & 63)) & 1u) != 0;
    }
  };
  Query make_query(const Vec3& q) const {
    Query Q;
    Q.q = q;
    const Vec3 rel = q - centre;
    const double q_max = rel.cwiseAbs().maxCoeff();
    Q.filter = rel_max <= kFilterMax && q_max <= kFilterMax;
    for (int d = 0; d < 3; ++d) Q.qf[d] = Q.filter ? static_cast<float>(rel[d]) : 0.0f;
    Q.slack = (rel_max + q_max) * 0x1p-21;
    return Q;
  }
  // A float threshold that the float squared distance of every point within `bound` (exact,
  // squared, m^2) stays below. Each float coordinate is within 2^-24 relative of its exact value,
  // so each float difference is within 2^-23 (rel_max + |q - c|) of the exact one, the Euclidean
  // norm within sqrt(3) times that, and the three products and two sums add at most 5 roundings
  // of 2^-24 relative: `slack` (8 times 2^-24 (rel_max + |q - c|)) and the relative factors
  // (1 + 2^-20 on the distance, 1 + 2^-19 on its square) cover all of it with room. Underflow
  // only lowers the float distance (safe). The test that the prefilter never drops a point:
  // KdTreeTotalOrder.FloatPrefilterKeepsEveryPointWithinTheBound (it fails without either).
  static float threshold(double bound, double slack) {
    if (!(bound < std::numeric_limits<double>::infinity())) {
      return std::numeric_limits<float>::infinity();
    }
    const double r = std::sqrt(bound) * (1.0 + 0x1p-20) + slack;
    // Round-to-nearest loses at most 2^-24 relative: the factor 1 + 2^-19 keeps it above. Among
    // subnormal floats rounding is absolute (up to 2^-150 per operation), so the threshold is
    // at least 4 FLT_MIN = 2^-124 (squared distances under 2^-124 m^2 always pass).
    const double t = r * r * (1.0 + 0x1p-19);
    return t < static_cast<double>(std::numeric_limits<float>::max())
               ? static_cast<float>(std::max(t, 0x1p-124))
               : std::numeric_limits<float>::infinity();
  }

  // Offers every point of leaf j within the bound to `best`, in slot order.
  void scan_leaf(std::uint32_t leaf, Query& Q, Best& best) const {
    double bound = best.bound();
    // The exact test and offer of the point in slot s.
    auto offer_slot = [&](std::uint32_t s) {
      const PointIndex i = perm[s];
      if (Q.is_seed(i)) return;
      const double d = squared_distance(Q.q, points[i]);
      if (d <= bound) {
        best.offer(d, i);
        bound = best.bound();
      }
    };
    const std::uint32_t begin = leaf_begin[leaf], end = leaf_begin[leaf + 1];
    if (!Q.filter || !(bound < std::numeric_limits<double>::infinity())) {
      for (std::uint32_t s = begin; s < end; ++s) offer_slot(s);
      return;
    }
    if (bound != Q.thr_bound) {
      Q.thr = threshold(bound, Q.slack);
      Q.thr_bound = bound;
    }
    const float thr = Q.thr;
    for (std::uint32_t s0 = begin; s0 < end; s0 += 32) {
      const std::uint32_t count = std::min<std::uint32_t>(32, end - s0);
      std::uint32_t mask = 0;
#if defined(__SSE2__)
      const __m128 qx = _mm_set1_ps(Q.qf[0]), qy = _mm_set1_ps(Q.qf[1]), qz = _mm_set1_ps(Q.qf[2]);
      const __m128 t = _mm_set1_ps(thr);
      for (std::uint32_t j = 0; j < count; j += 4) {
        // (The arrays are padded: reading up to 3 slots past the last point is safe, and those
        // bits are masked off below.)
        const __m128 dx = _mm_sub_ps(_mm_loadu_ps(fx.data() + s0 + j), qx);
        const __m128 dy = _mm_sub_ps(_mm_loadu_ps(fy.data() + s0 + j), qy);
        const __m128 dz = _mm_sub_ps(_mm_loadu_ps(fz.data() + s0 + j), qz);
        const __m128 d =
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
        mask |= static_cast<std::uint32_t>(_mm_movemask_ps(_mm_cmple_ps(d, t))) << j;
      }
#else
      for (std::uint32_t j = 0; j < count; ++j) {
        const float dx = fx[s0 + j] - Q.qf[0], dy = fy[s0 + j] - Q.qf[1], dz = fz[s0 + j] - Q.qf[2];
        mask |= static_cast<std::uint32_t>(dx * dx + dy * dy + dz * dz <= thr) << j;
      }
#endif
      if (count < 32) mask &= (std::uint32_t{1} << count) - 1;
      for (; mask != 0; mask &= mask - 1) {
        offer_slot(s0 + static_cast<std::uint32_t>(__builtin_ctz(mask)));
      }
    }
  }

  // Depth-first, nearer half first, with an explicit stack of deferred far halves. `off` holds,
  // per axis, the signed offset from the query to the current cell (0 inside); the cell's lower
  // bound is its squared norm. Every offset is q[d] - c with c a coordinate bound of the cell,
  // and rounding is monotone, so that bound never exceeds the computed squared distance of a
  // point in the cell: pruning with '>' is exact, and cells at exactly the bound are visited (a
  // tie with a lower index may be there).
  struct Deferred {
    std::uint32_t node;
    int level;
    double cell_d2;
    double off[3];
  };
  static double norm2(const double* off) {
    return off[0] * off[0] + off[1] * off[1] + off[2] * off[2];
  }

  void search(Query& Q, const double* off0, Best& best) const {
    const Vec3& q = Q.q;
    Deferred stack[kMaxDepth + 1];
    int top = 0;
    std::uint32_t node = 0;
    int level = 0;
    double off[3] = {off0[0], off0[1], off0[2]};
    double cell_d2 = norm2(off);
    const auto first_leaf = static_cast<std::uint32_t>(nodes.size());
    for (;;) {
      // Descend towards the query, deferring the far halves.
      while (cell_d2 <= best.bound()) {
        if (level == depth) {
          scan_leaf(node - first_leaf, Q, best);
          break;
        }
        const Node& nd = nodes[node];
        const std::uint32_t axis = nd.axis;
        const double qd = q[axis];
        // Offsets to each half along `axis`, 0 when the query is on that half's side of its
        // bound (the ancestors' offset along `axis`, if any, then still holds). Branch-free:
        // which half is nearer is unpredictable.
        const double to_left = std::max(qd - static_cast<double>(nd.left_max), 0.0);
        const double to_right = std::min(qd - static_cast<double>(nd.right_min), 0.0);
        const bool left_near = -to_right > to_left;
        const double off_far = left_near ? to_right : to_left;
        {
          // The far half is deferred only if it can still hold a candidate: the bound never
          // grows, so a half beyond it now stays beyond it (on the real pair, 28% of them).
          double far_off[3] = {off[0], off[1], off[2]};
          far_off[axis] = off_far != 0.0 ? off_far : far_off[axis];
          const double far_d2 = norm2(far_off);
          if (far_d2 <= best.bound()) {
            Deferred& far = stack[top++];
            far.node = left_near ? 2 * node + 2 : 2 * node + 1;
            far.level = level + 1;
            far.off[0] = far_off[0];
            far.off[1] = far_off[1];
            far.off[2] = far_off[2];
            far.cell_d2 = far_d2;
          }
        }
        // The near half's offset is 0 when the query lies within its bound (usually): then the
        // offsets, and so the cell's squared distance, stay as they are.
        const double off_near = left_near ? to_left : to_right;
        if (off_near != 0.0) {
          off[axis] = off_near;
          cell_d2 = norm2(off);
        }
        node = left_near ? 2 * node + 1 : 2 * node + 2;
        ++level;
      }
      // Resume at the most recent deferred half still within the bound.
      for (;;) {
        if (top == 0) return;
        const Deferred& d = stack[--top];
        if (d.cell_d2 <= best.bound()) {
          node = d.node;
          level = d.level;
          off[0] = d.off[0];
          off[1] = d.off[1];
          off[2] = d.off[2];
          cell_d2 = d.cell_d2;
          break;
        }
      }
    }
  }

  void build_filter() {
    const std::size_t n = points.size();
    centre = 0.5 * (box_min + box_max);
    rel_max = 0.5 * (box_max - box_min).maxCoeff();
    for (const Vec3& p : points) rel_max = std::max(rel_max, (p - centre).cwiseAbs().maxCoeff());
    const float pad = std::numeric_limits<float>::infinity();
    fx.assign(n + 4, pad);
    fy.assign(n + 4, pad);
    fz.assign(n + 4, pad);
    if (!(rel_max <= kFilterMax)) return;
    for (std::size_t s = 0; s < n; ++s) {
      const Vec3 rel = points[perm[s]] - centre;
      fx[s] = static_cast<float>(rel[0]);
      fy[s] = static_cast<float>(rel[1]);
      fz[s] = static_cast<float>(rel[2]);
    }
  }

  // Appends the points of the subtree at `node` within sqrt(r2) of q: cells pruned by their lower
  // bound, as in search() (the same offsets), leaves scanned exactly.
  void within(std::uint32_t node, int level, double* off, double r2, const Vec3& q,
              std::vector<PointIndex>* out) const {
    if (norm2(off) > r2) return;
    if (level == depth) {
      const std::uint32_t leaf = node - static_cast<std::uint32_t>(nodes.size());
      for (std::uint32_t s = leaf_begin[leaf]; s < leaf_begin[leaf + 1]; ++s) {
        if (squared_distance(q, points[perm[s]]) <= r2) out->push_back(perm[s]);
      }
      return;
    }
    const Node& nd = nodes[node];
    const std::uint32_t axis = nd.axis;
    const double keep = off[axis];
    const double to_left = std::max(q[axis] - static_cast<double>(nd.left_max), 0.0);
    const double to_right = std::min(q[axis] - static_cast<double>(nd.right_min), 0.0);
    off[axis] = to_left != 0.0 ? to_left : keep;
    within(2 * node + 1, level + 1, off, r2, q, out);
    off[axis] = to_right != 0.0 ? to_right : keep;
    within(2 * node + 2, level + 1, off, r2, q, out);
    off[axis] = keep;
  }

  std::size_t query(const Vec3& q, std::size_t k, const PointIndex* seed_idx, const double* seed_d2,
                    std::size_t num_seeds, PointIndex* indices, double* d2,
                    std::uint64_t* seed_marks = nullptr,
                    double limit_d2 = std::numeric_limits<double>::infinity()) const {
    if (points.empty() || k == 0 || !q.allFinite()) return 0;
    const std::size_t cap = std::min(k, points.size());
    const std::size_t seeded = std::min(num_seeds, cap);
    for (std::size_t j = 0; j < seeded; ++j) {  // (a no-op when seeding in place)
      indices[j] = seed_idx[j];
      d2[j] = seed_d2[j];
    }
    Query Q = make_query(q);
    // Marking the seeds spares the search their exact distances and offers when it meets them
    // (on the real pair 7.6 of the 12.8 offers per search were seeds). The marks are cleared
    // from a copy of the seed indices: the search overwrites them in place.
    constexpr std::size_t kMaxMarked = 64;
    PointIndex marked[kMaxMarked];
    const std::size_t num_marked = seed_marks != nullptr && seeded <= kMaxMarked ? seeded : 0;
    for (std::size_t j = 0; j < num_marked; ++j) {
      marked[j] = indices[j];
      seed_marks[marked[j] >> 6] |= std::uint64_t{1} << (marked[j] & 63);
    }
    if (num_marked > 0) Q.seed_marks = seed_marks;
    Best best(indices, d2, cap, seeded, limit_d2);
    double off[3];
    for (int d = 0; d < 3; ++d) {
      off[d] = q[d] < box_min[d] ? q[d] - box_min[d] : q[d] > box_max[d] ? q[d] - box_max[d] : 0.0;
    }
    search(Q, off, best);
    for (std::size_t j = 0; j < num_marked; ++j) seed_marks[marked[j] >> 6] = 0;
    return best.size();
  }
};

KdTree::KdTree(Points3 points, std::size_t leaf_size) : impl_(std::make_unique<Impl>()) {
  if (points.size() >= (std::size_t{1} << 31)) {
    throw InvalidArgument("kd-tree: too many points (" + std::to_string(points.size()) + ")");
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      throw InvalidArgument("kd-tree: point " + std::to_string(i) + " is not finite");
    }
  }
  if (leaf_size == 0) throw InvalidArgument("kd-tree: leaf_size must be >= 1");
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
  std::size_t leaves = 1;
  while (leaves * leaf_size < n) {
    leaves *= 2;
    ++impl_->depth;
  }
  impl_->nodes.resize(leaves - 1);
  impl_->leaf_begin.resize(leaves + 1);
  impl_->build(0, 0, 0, static_cast<std::uint32_t>(n));
  impl_->leaf_begin[leaves] = static_cast<std::uint32_t>(n);
  impl_->build_filter();
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
                               PointIndex* indices, double* distances_sq_m2,
                               std::uint64_t* seed_marks) const {
  return impl_->query(query, k, seed_indices, seed_distances_sq_m2, num_seeds, indices,
                      distances_sq_m2, seed_marks);
}

std::size_t KdTree::knn_within(const Vec3& query, std::size_t k, double max_distance_m,
                               PointIndex* indices, double* distances_sq_m2) const {
  if (!(max_distance_m >= 0.0)) return 0;
  return impl_->query(query, k, nullptr, nullptr, 0, indices, distances_sq_m2, nullptr,
                      max_distance_m * max_distance_m);
}

std::size_t KdTree::seed_mark_words() const { return (impl_->points.size() + 63) / 64; }

void KdTree::within(const Vec3& query, double radius_m, std::vector<PointIndex>* out) const {
  out->clear();
  if (impl_->points.empty() || !query.allFinite() || !(radius_m >= 0.0) ||
      !std::isfinite(radius_m)) {
    return;
  }
  double off[3];
  for (int d = 0; d < 3; ++d) {
    const double q = query[d];
    off[d] = q < impl_->box_min[d]   ? q - impl_->box_min[d]
             : q > impl_->box_max[d] ? q - impl_->box_max[d]
                                     : 0.0;
  }
  impl_->within(0, 0, off, radius_m * radius_m, query, out);
  std::sort(out->begin(), out->end());
}

bool KdTree::nearest(const Vec3& query, PointIndex* index, double* distance_sq_m2) const {
  return knn(query, 1, index, distance_sq_m2) == 1;
}

std::size_t KdTree::memory_bytes() const {
  return impl_->points.capacity() * sizeof(Vec3) + impl_->perm.capacity() * sizeof(PointIndex) +
         impl_->nodes.capacity() * sizeof(Node) +
         impl_->leaf_begin.capacity() * sizeof(std::uint32_t) +
         (impl_->fx.capacity() + impl_->fy.capacity() + impl_->fz.capacity()) * sizeof(float);
}

}  // namespace lmalign
