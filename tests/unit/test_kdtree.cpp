#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {
namespace {

Points3 random_points(std::size_t n, std::uint32_t seed, double scale = 1.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, scale);
  Points3 p(n);
  for (auto& x : p) x = Vec3(g(rng), g(rng), 0.3 * g(rng));
  return p;
}

class KdTreeVsBruteForce : public ::testing::TestWithParam<std::size_t> {};

TEST_P(KdTreeVsBruteForce, SameNeighboursAndDistances) {
  const std::size_t k = GetParam();
  const Points3 pts = random_points(3000, 11);
  const KdTree tree(pts);
  const Points3 queries = random_points(300, 12, 1.5);
  std::vector<PointIndex> idx(k);
  std::vector<double> d2(k);
  std::vector<std::size_t> order(pts.size());
  for (const Vec3& q : queries) {
    const std::size_t found = tree.knn(q, k, idx.data(), d2.data());
    ASSERT_EQ(found, std::min(k, pts.size()));
    std::iota(order.begin(), order.end(), 0);
    std::partial_sort(order.begin(), order.begin() + found, order.end(),
                      [&](std::size_t a, std::size_t b) {
                        return (pts[a] - q).squaredNorm() < (pts[b] - q).squaredNorm();
                      });
    for (std::size_t j = 0; j < found; ++j) {
      EXPECT_EQ(idx[j], order[j]) << "rank " << j;
      EXPECT_NEAR(d2[j], (pts[order[j]] - q).squaredNorm(), 1e-12);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(K, KdTreeVsBruteForce, ::testing::Values(1u, 5u, 16u));

TEST(KdTree, KLargerThanSetReturnsAllSorted) {
  const Points3 pts = {Vec3(0, 0, 0), Vec3(3, 0, 0), Vec3(1, 0, 0)};
  const KdTree tree(pts);
  std::vector<PointIndex> idx(10);
  std::vector<double> d2(10);
  ASSERT_EQ(tree.knn(Vec3(0.1, 0, 0), 10, idx.data(), d2.data()), 3u);
  EXPECT_EQ(idx[0], 0u);
  EXPECT_EQ(idx[1], 2u);
  EXPECT_EQ(idx[2], 1u);
  EXPECT_NEAR(d2[2], 2.9 * 2.9, 1e-12);
}

TEST(KdTree, EmptyAndInvalid) {
  const KdTree empty{Points3{}};
  PointIndex i = 0;
  double d = 0;
  EXPECT_FALSE(empty.nearest(Vec3::Zero(), &i, &d));
  EXPECT_EQ(empty.size(), 0u);
  EXPECT_THROW(KdTree(Points3{Vec3(0, std::nan(""), 0)}), InvalidArgument);
}

TEST(KdTree, WithinIsEveryPointInTheBallInIndexOrder) {
  // Against a brute-force scan with the same squared distance, for radii from empty balls to
  // the whole set, and a point exactly on the sphere (squared distance 1 for radius 1: kept).
  Points3 pts = random_points(3000, 13);
  pts.push_back(Vec3(1.0, 0.0, 0.0));
  const KdTree tree(pts);
  std::vector<PointIndex> got;
  for (const double r : {0.0, 0.05, 0.3, 1.0, 10.0}) {
    for (const Vec3& q : random_points(50, 14, 1.5)) {
      tree.within(q, r, &got);
      std::vector<PointIndex> want;
      for (std::size_t i = 0; i < pts.size(); ++i) {
        if (squared_distance(q, pts[i]) <= r * r) want.push_back(static_cast<PointIndex>(i));
      }
      EXPECT_EQ(got, want) << "radius " << r;
    }
  }
  tree.within(Vec3::Zero(), 1.0, &got);
  EXPECT_NE(std::find(got.begin(), got.end(), static_cast<PointIndex>(pts.size() - 1)), got.end());
  // Not finite, or negative: nothing (and the previous contents are gone).
  tree.within(Vec3(std::nan(""), 0, 0), 1.0, &got);
  EXPECT_TRUE(got.empty());
  tree.within(Vec3::Zero(), -1.0, &got);
  EXPECT_TRUE(got.empty());
  tree.within(Vec3::Zero(), std::numeric_limits<double>::infinity(), &got);
  EXPECT_TRUE(got.empty());
  const KdTree empty{Points3{}};
  empty.within(Vec3::Zero(), 1.0, &got);
  EXPECT_TRUE(got.empty());
}

TEST(KdTree, KnnWithinIsTheLeadingPartOfKnnInsideTheLimit) {
  // For limits from an empty ball to beyond the k-th neighbour: the same indices and squared
  // distances as knn()'s leading entries within the limit, in the same order; a point exactly on
  // the limit is kept. A negative or NaN limit finds nothing; +inf is knn().
  Points3 pts = random_points(3000, 15);
  pts.push_back(Vec3(0.5, 0.0, 0.0));
  const KdTree tree(pts);
  const std::size_t k = 32;
  std::vector<PointIndex> idx(k), want_idx(k);
  std::vector<double> d2(k), want_d2(k);
  std::size_t partial = 0;  // queries whose ball held some but fewer than k of the k nearest
  for (const double r : {0.0, 0.02, 0.1, 0.3, 5.0, std::numeric_limits<double>::infinity()}) {
    for (const Vec3& q : random_points(60, 16, 1.5)) {
      const std::size_t all = tree.knn(q, k, want_idx.data(), want_d2.data());
      std::size_t inside = 0;
      while (inside < all && want_d2[inside] <= r * r) ++inside;
      const std::size_t got = tree.knn_within(q, k, r, idx.data(), d2.data());
      ASSERT_EQ(got, inside) << "radius " << r;
      for (std::size_t j = 0; j < got; ++j) {
        EXPECT_EQ(idx[j], want_idx[j]) << "radius " << r << ", rank " << j;
        EXPECT_EQ(d2[j], want_d2[j]);
      }
      if (inside > 0 && inside < all) ++partial;
    }
  }
  EXPECT_GT(partial, 20u);  // the limits above do cut the lists
  EXPECT_EQ(tree.knn_within(Vec3(0.5, 0.0, 0.0), 4, 0.0, idx.data(), d2.data()), 1u);
  EXPECT_EQ(idx[0], static_cast<PointIndex>(pts.size() - 1));
  const KdTree line(Points3{Vec3(2, 0, 0), Vec3(0, 0, 0), Vec3(1, 0, 0)});
  ASSERT_EQ(line.knn_within(Vec3::Zero(), 3, 1.0, idx.data(), d2.data()), 2u);
  EXPECT_EQ(idx[0], 1u);
  EXPECT_EQ(idx[1], 2u);
  EXPECT_EQ(d2[1], 1.0);
  EXPECT_EQ(tree.knn_within(Vec3::Zero(), k, -1.0, idx.data(), d2.data()), 0u);
  EXPECT_EQ(tree.knn_within(Vec3::Zero(), k, std::nan(""), idx.data(), d2.data()), 0u);
  const KdTree empty{Points3{}};
  EXPECT_EQ(empty.knn_within(Vec3::Zero(), k, 1.0, idx.data(), d2.data()), 0u);
}

}  // namespace
}  // namespace lmalign
