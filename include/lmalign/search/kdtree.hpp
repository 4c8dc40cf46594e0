// Nearest-neighbour search over a fixed 3-D point set: a kd-tree built once.
//
// The search is EXACT under one total order: a target point p comes before p' when
//   (d2(q, p), index(p)) < (d2(q, p'), index(p'))   lexicographically,
// where d2 is squared_distance() below, evaluated in double precision in a fixed order. The k
// nearest points are the first k in that order, always, whatever the tree's shape or the traversal:
// ties in distance resolve by the lower index, including at the k-th place. Two consequences that
// the exact neighbour reuse of the ICP loop relies on (docs/performance.md):
//   - the first k results of a (k + m)-query are exactly the results of a k-query;
//   - a squared distance recomputed with squared_distance() is bit-identical to the tree's.
// The leaf scans first test float copies of the coordinates against a threshold with a proven
// rounding allowance, and compute the exact distance only for the points that pass: the pruning
// never drops a point within the bound, so it changes the speed, never the result.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "lmalign/core/types.hpp"

namespace lmalign {

/// Index of a point in the set it was built from.
using PointIndex = std::uint32_t;

/// The squared Euclidean distance every lmalign search uses: ((dx dx + dy dy) + dz dz) with
/// d = a - b, in this order (m^2). Inline so that callers recompute exactly the tree's values.
inline double squared_distance(const Vec3& a, const Vec3& b) {
  const double dx = a[0] - b[0];
  const double dy = a[1] - b[1];
  const double dz = a[2] - b[2];
  return dx * dx + dy * dy + dz * dz;
}

/// An immutable kd-tree over a copy of `points`. Thread-safe for concurrent queries. Neighbours
/// come sorted by increasing squared distance, equal distances by increasing index (see above).
class KdTree {
 public:
  /// Builds the tree: complete and balanced, leaves of at most leaf_size points, median splits on
  /// the axis of largest spread (deterministic). The default, 32, costs the fewest instructions
  /// per ICP run on the real pair for k = 1 to 20 now that leaves are scanned with the float
  /// prefilter (docs/performance.md; 16 before it). Throws InvalidArgument if
  /// a point is not finite, leaf_size is 0, or there are 2^31 points or more. An empty set is
  /// allowed (every query then returns 0 neighbours).
  explicit KdTree(Points3 points, std::size_t leaf_size = 32);
  ~KdTree();
  KdTree(KdTree&&) noexcept;
  KdTree& operator=(KdTree&&) noexcept;
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  std::size_t size() const;
  /// The points, in the order given to the constructor (indices refer to this order).
  const Points3& points() const;

  /// The k nearest points to `query` (metres). Writes min(k, size()) results into `indices` and
  /// `distances_sq_m2` (squared distances, m^2), in the total order above, and returns how many.
  /// A query that is not finite returns 0.
  std::size_t knn(const Vec3& query, std::size_t k, PointIndex* indices,
                  double* distances_sq_m2) const;

  /// The k nearest points among those within `max_distance_m` of `query` (squared distance <=
  /// max_distance_m^2): exactly the leading entries of knn()'s result that lie within it, found
  /// without visiting what lies beyond (the search's bound starts at the limit). Returns how
  /// many (0 for a negative or NaN limit; +inf gives knn()).
  std::size_t knn_within(const Vec3& query, std::size_t k, double max_distance_m,
                         PointIndex* indices, double* distances_sq_m2) const;

  /// Exactly knn(), but starting from `num_seeds` known candidates: seed_indices (distinct, each
  /// < size()) with seed_distances_sq_m2 = squared_distance(query, point), sorted in the total
  /// order above -- e.g. the neighbours of a nearby earlier query, re-evaluated at `query`. The
  /// seeds only tighten the search bound from the start; the result is identical to knn().
  /// The seed arrays may be the output arrays (in place).
  /// `seed_marks`, optional: a scratch bit set of seed_mark_words() words, all zero, returned all
  /// zero (one per thread). With it the search skips the seeds when it meets them instead of
  /// computing their distances and offering them again: faster, the same result.
  std::size_t knn_seeded(const Vec3& query, std::size_t k, const PointIndex* seed_indices,
                         const double* seed_distances_sq_m2, std::size_t num_seeds,
                         PointIndex* indices, double* distances_sq_m2,
                         std::uint64_t* seed_marks = nullptr) const;
  /// Size in 64-bit words of knn_seeded()'s `seed_marks` scratch: one bit per point.
  std::size_t seed_mark_words() const;

  /// Every point within `radius_m` of `query` (squared_distance() <= radius_m^2), as indices in
  /// increasing order, replacing the contents of `out`. None for a query or radius that is not
  /// finite, or a negative radius.
  void within(const Vec3& query, double radius_m, std::vector<PointIndex>* out) const;

  /// The nearest point; false if the set is empty (or the query is not finite).
  bool nearest(const Vec3& query, PointIndex* index, double* distance_sq_m2) const;

  /// Heap bytes held by the tree (points, permutation, nodes, and the float copies of the
  /// coordinates that the leaf scans prune with): about 41 bytes per point.
  std::size_t memory_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lmalign
