#include <random>

#include <gtest/gtest.h>
#include <omp.h>

#include "lmalign/core/error.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

CorrespondenceOptions weighted(int k, double max_distance_m = 1e300) {
  CorrespondenceOptions o;
  o.kind = CorrespondenceKind::kWeightedKnn;
  o.k = k;
  o.max_distance_m = max_distance_m;
  return o;
}

TEST(WeightedKnn, PicksLargestWeightAmongKNearest) {
  // Target on a line at x = 1, 2, 3, 4; query at 0.
  const KdTree tree(Points3{Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(3, 0, 0), Vec3(4, 0, 0)});
  const Points3 src = {Vec3(0, 0, 0)};
  Correspondences out;

  CorrespondenceFinder(tree, {1, 5, 9, 100}, weighted(3)).find(src, out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].target_index, 2u);  // weight 9 is the largest among the 3 nearest
  EXPECT_DOUBLE_EQ(out[0].distance_sq_m2, 9.0);

  // Equal weights: the nearer candidate wins.
  CorrespondenceFinder(tree, {1, 7, 7, 7}, weighted(4)).find(src, out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].target_index, 1u);

  // The max distance removes candidates before the argmax.
  CorrespondenceFinder(tree, {1, 5, 9, 100}, weighted(4, 2.5)).find(src, out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].target_index, 1u);

  // No positive weight among the candidates: no correspondence.
  CorrespondenceFinder(tree, {0, 0, 3, 3}, weighted(2)).find(src, out);
  EXPECT_TRUE(out.empty());
}

TEST(WeightedKnn, KEqualOneIsNearest) {
  const Points3 target = test::room_points(2000, 3);
  const KdTree tree(target);
  const Points3 src =
      transform_points(pose_from_xyz_rpy_deg(0.1, -0.2, 0.05, 2, 1, 8), test::room_points(1500, 4));
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.1, 10.0);
  std::vector<double> w(target.size());
  for (double& x : w) x = u(rng);

  Correspondences nearest, k1;
  CorrespondenceOptions base;
  CorrespondenceFinder(tree, {}, base).find(src, nearest);
  CorrespondenceFinder(tree, w, weighted(1)).find(src, k1);
  ASSERT_EQ(nearest.size(), src.size());
  ASSERT_EQ(k1.size(), nearest.size());
  for (std::size_t i = 0; i < nearest.size(); ++i) {
    EXPECT_EQ(k1[i].source_index, nearest[i].source_index);
    EXPECT_EQ(k1[i].target_index, nearest[i].target_index);
    EXPECT_EQ(k1[i].distance_sq_m2, nearest[i].distance_sq_m2);
  }
  // And with k = 5 the choice differs for some points (the test above is not vacuous).
  Correspondences k5;
  CorrespondenceFinder(tree, w, weighted(5)).find(src, k5);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < k5.size(); ++i)
    differ += k5[i].target_index != nearest[i].target_index;
  EXPECT_GT(differ, src.size() / 4);
}

TEST(CorrespondenceFinder, IdenticalForAnyThreadCount) {
  const Points3 target = test::room_points(5000, 6);
  const KdTree tree(target);
  const Points3 src = test::room_points(4000, 7);
  std::vector<double> w(target.size());
  for (std::size_t i = 0; i < w.size(); ++i) w[i] = static_cast<double>(i % 7);
  const int saved = omp_get_max_threads();
  Correspondences one, many;
  omp_set_num_threads(1);
  CorrespondenceFinder(tree, w, weighted(5, 0.3)).find(src, one);
  omp_set_num_threads(4);
  CorrespondenceFinder(tree, w, weighted(5, 0.3)).find(src, many);
  omp_set_num_threads(saved);
  ASSERT_EQ(one.size(), many.size());
  ASSERT_FALSE(one.empty());
  for (std::size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i].source_index, many[i].source_index);
    EXPECT_EQ(one[i].target_index, many[i].target_index);
  }
}

TEST(CorrespondenceFinder, RejectsBadOptionsAndWeights) {
  const KdTree tree(Points3{Vec3(0, 0, 0), Vec3(1, 0, 0)});
  std::string why;
  CorrespondenceOptions o = weighted(0);
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("k must be"), std::string::npos) << why;
  o = weighted(3, std::nan(""));
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_NE(why.find("max_distance_m"), std::string::npos) << why;
  EXPECT_THROW(CorrespondenceFinder(tree, {1.0}, weighted(2)), InvalidArgument);  // size
  EXPECT_THROW(CorrespondenceFinder(tree, {1.0, -1.0}, weighted(2)), InvalidArgument);
  EXPECT_THROW(CorrespondenceFinder(tree, {1.0, std::nan("")}, weighted(2)), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
