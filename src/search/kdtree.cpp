#include "lmalign/search/kdtree.hpp"

#include <limits>
#include <string>

// Equal distances: lower index first (deterministic neighbour order).
#define NANOFLANN_FIRST_MATCH
#include <nanoflann.hpp>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {

struct PointsAdaptor {
  const Points3* points;
  std::size_t kdtree_get_point_count() const { return points->size(); }
  double kdtree_get_pt(std::size_t i, std::size_t dim) const { return (*points)[i][dim]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};

using Tree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointsAdaptor>,
                                        PointsAdaptor, 3, PointIndex>;

}  // namespace

struct KdTree::Impl {
  Points3 points;
  PointsAdaptor adaptor;
  std::unique_ptr<Tree> tree;
};

KdTree::KdTree(Points3 points, std::size_t leaf_size) : impl_(std::make_unique<Impl>()) {
  if (points.size() >= std::numeric_limits<PointIndex>::max()) {
    throw InvalidArgument("kd-tree: too many points (" + std::to_string(points.size()) + ")");
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      throw InvalidArgument("kd-tree: point " + std::to_string(i) + " is not finite");
    }
  }
  if (leaf_size == 0) throw InvalidArgument("kd-tree: leaf_size must be >= 1");
  impl_->points = std::move(points);
  impl_->adaptor.points = &impl_->points;
  if (!impl_->points.empty()) {
    impl_->tree = std::make_unique<Tree>(3, impl_->adaptor,
                                         nanoflann::KDTreeSingleIndexAdaptorParams(leaf_size));
    impl_->tree->buildIndex();
  }
}

KdTree::~KdTree() = default;
KdTree::KdTree(KdTree&&) noexcept = default;
KdTree& KdTree::operator=(KdTree&&) noexcept = default;

std::size_t KdTree::size() const { return impl_->points.size(); }
const Points3& KdTree::points() const { return impl_->points; }

std::size_t KdTree::knn(const Vec3& query, std::size_t k, PointIndex* indices,
                        double* distances_sq_m2) const {
  if (!impl_->tree || k == 0) return 0;
  const std::size_t kk = std::min(k, impl_->points.size());
  nanoflann::KNNResultSet<double, PointIndex, std::size_t> result(kk);
  result.init(indices, distances_sq_m2);
  impl_->tree->findNeighbors(result, query.data(), nanoflann::SearchParams());
  return result.size();
}

bool KdTree::nearest(const Vec3& query, PointIndex* index, double* distance_sq_m2) const {
  return knn(query, 1, index, distance_sq_m2) == 1;
}

}  // namespace lmalign
