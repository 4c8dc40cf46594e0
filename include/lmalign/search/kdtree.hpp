// Nearest-neighbour search over a fixed 3-D point set: a nanoflann kd-tree, built once.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "lmalign/core/types.hpp"

namespace lmalign {

/// Index of a point in the set it was built from.
using PointIndex = std::uint32_t;

/// An immutable kd-tree (nanoflann, L2) over a copy of `points`. Thread-safe for concurrent
/// queries. Neighbours come sorted by increasing distance. Results are deterministic for a given
/// point set (ties in distance resolve by the tree's fixed traversal, lower index first among the
/// tied points kept).
class KdTree {
 public:
  /// Builds the tree. Throws InvalidArgument if a point is not finite or there are more than
  /// 2^32 - 1 points. An empty set is allowed (every query then returns 0 neighbours).
  explicit KdTree(Points3 points, std::size_t leaf_size = 10);
  ~KdTree();
  KdTree(KdTree&&) noexcept;
  KdTree& operator=(KdTree&&) noexcept;
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  std::size_t size() const;
  const Points3& points() const;

  /// The k nearest points to `query` (metres). Writes min(k, size()) results into `indices` and
  /// `distances_sq_m2` (squared distances, m^2), nearest first, and returns how many.
  std::size_t knn(const Vec3& query, std::size_t k, PointIndex* indices,
                  double* distances_sq_m2) const;

  /// The nearest point; false if the set is empty.
  bool nearest(const Vec3& query, PointIndex* index, double* distance_sq_m2) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lmalign
