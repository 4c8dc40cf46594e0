// Correspondence strategies: which target landmark each (transformed) source landmark is paired
// with in one ICP iteration (method.md §3).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

/// A source-target pair. distance_sq_m2 is the squared distance at the time the pair was made
/// (PCL's pcl::Correspondence::distance, which PCL's convergence MSE averages).
struct Correspondence {
  PointIndex source_index = 0;
  PointIndex target_index = 0;
  double distance_sq_m2 = 0.0;
};
using Correspondences = std::vector<Correspondence>;

enum class CorrespondenceKind {
  /// Base ICP: the nearest target point (PCL CorrespondenceEstimation::determineCorrespondences).
  kNearest,
  /// The paper's Eq. 6: among the k nearest target points within the max distance, the one with
  /// the largest target weight; on equal weights the nearer one; none if no candidate has a
  /// positive weight. With k = 1 (and positive weights) identical to kNearest.
  kWeightedKnn,
};

std::string to_string(CorrespondenceKind kind);  ///< "nearest", "weighted_knn"

struct CorrespondenceOptions {
  CorrespondenceKind kind = CorrespondenceKind::kNearest;
  /// Neighbourhood size of kWeightedKnn (ignored by kNearest, which always takes 1). >= 1.
  int k = 5;
  /// Candidates farther than this (metres) are never paired. Infinite by default, as the paper.
  double max_distance_m = std::numeric_limits<double>::infinity();

  /// Ceres-style check: false and the bad field named in *why.
  bool is_valid(std::string* why = nullptr) const;
};

/// Reusable state for repeated searches of ONE source point set under changing transforms (the
/// ICP loop): buffers allocated on the first call and reused, a spatial (Morton) order of the
/// queries, and the exact neighbour-reuse cache.
///
/// The cache keeps, per source point, the k + m nearest target points found at a reference pose
/// and the distance of the last one. At a new pose it recomputes the distances of those
/// candidates; when the point has moved by less than (distance of the last candidate) - (new
/// k-th distance), no other target point can enter the k nearest, so the k nearest, their order
/// and their distances are exactly those of a fresh search (proof: docs/performance.md). Else
/// it searches the tree again (seeded with the old candidates).
///
/// A workspace binds to the first (finder, source point set) it is used with and rebinds, empty,
/// when either changes (checked by address and size): call clear() if the points of the same
/// vector were modified in place. Not thread-safe: one workspace per concurrent search.
class CorrespondenceWorkspace {
 public:
  CorrespondenceWorkspace();
  ~CorrespondenceWorkspace();
  CorrespondenceWorkspace(CorrespondenceWorkspace&&) noexcept;
  CorrespondenceWorkspace& operator=(CorrespondenceWorkspace&&) noexcept;
  CorrespondenceWorkspace(const CorrespondenceWorkspace&) = delete;
  CorrespondenceWorkspace& operator=(const CorrespondenceWorkspace&) = delete;

  /// Forgets every cached neighbour (keeps the buffers).
  void clear();
  /// Source points of the last call that were searched in the tree, and that reused the cache.
  std::size_t last_searched() const;
  std::size_t last_reused() const;
  /// Of the reused ones, those served by the fast path: the point stayed within half the gap
  /// between its k-th and (k + 1)-th neighbour distances at the reference position, so only its
  /// k nearest were re-evaluated (docs/performance.md).
  std::size_t last_fast() const;
  /// Heap bytes held (buffers and cache).
  std::size_t memory_bytes() const;

  struct State;  ///< implementation detail (correspondence.cpp)

 private:
  friend class CorrespondenceFinder;
  State* state_;
};

/// Finds correspondences against a fixed target. Queries run in parallel (OpenMP); the output is
/// identical for any thread count: pairs are listed in increasing source index.
class CorrespondenceFinder {
 public:
  /// `target` must outlive the finder. `target_weights` has one weight per target point (>= 0,
  /// finite); it may be empty for kNearest. Throws InvalidArgument on invalid options or
  /// mismatched/invalid weights.
  CorrespondenceFinder(const KdTree& target, std::vector<double> target_weights,
                       const CorrespondenceOptions& options);

  /// As the constructor, but borrows `target_weights` instead of copying it: it must outlive the
  /// finder and stay unchanged.
  static CorrespondenceFinder borrowing(const KdTree& target,
                                        const std::vector<double>& target_weights,
                                        const CorrespondenceOptions& options);

  /// Replaces `out` with the correspondences of `source_points` (already transformed into the
  /// target frame, metres). Source points that are not finite get no correspondence.
  void find(const Points3& source_points, Correspondences& out) const;

  /// The ICP loop's call: writes T_target_source * p for every source point into `moved` (the
  /// same values as transform_points()), then replaces `out` with the correspondences of `moved`.
  /// `out` and `moved` are bit-identical to transform_points() followed by find(moved, out),
  /// with or without `reuse` (reuse = false searches the tree for every point). Allocates nothing
  /// once the workspace, `moved` and `out` have grown to size.
  void find(const Points3& source_points, const Isometry3& T_target_source, Points3& moved,
            Correspondences& out, CorrespondenceWorkspace& workspace, bool reuse = true) const;

  /// For the source indices i in [begin, end): the squared distance from
  /// T_target_source * source_points[i] to its nearest target point, written to d2[i - begin]
  /// (+inf if there is none). Served from the workspace's cache where it provably holds, else by
  /// a fresh search whose neighbours are then cached (so the next find() at this pose reuses
  /// them). Bit-identical to KdTree::nearest() on the points of transform_points().
  void nearest_sq_distances(const Points3& source_points, const Isometry3& T_target_source,
                            std::size_t begin, std::size_t end, double* d2,
                            CorrespondenceWorkspace& workspace) const;

  const CorrespondenceOptions& options() const { return options_; }
  const KdTree& target() const { return *target_; }

 private:
  const std::vector<double>& weights() const {
    return borrowed_weights_ != nullptr ? *borrowed_weights_ : weights_;
  }
  struct Borrow {};
  CorrespondenceFinder(Borrow, const KdTree& target, const std::vector<double>& target_weights,
                       const CorrespondenceOptions& options);
  void init();
  std::size_t cache_width() const;
  void bind(const Points3& source_points, CorrespondenceWorkspace& workspace) const;

  const KdTree* target_;
  std::vector<double> weights_;
  const std::vector<double>* borrowed_weights_ = nullptr;
  CorrespondenceOptions options_;
  double max_distance_sq_m2_ = 0.0;
  // Unique in the process: a workspace's cached choices among tied weights are valid only for
  // the finder (hence the weights) that made them.
  std::uint64_t serial_ = 0;
};

}  // namespace lmalign
