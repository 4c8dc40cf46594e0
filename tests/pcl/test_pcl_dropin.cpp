// The PCL drop-in (include/lmalign/pcl.hpp): its selection rule on hand-made clouds, and the
// same correspondences as lmalign's own weighted-kNN strategy on the real pair.
#include <cmath>
#include <memory>

#include <gtest/gtest.h>
#include <pcl/registration/correspondence_estimation.h>
#include <pcl/registration/icp.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/pcl.hpp"
#include "lmalign/registration/registration.hpp"
#include "pcl_support.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

using test::Cloud;
using DropIn = WeightedKnnCorrespondenceEstimation<pcl::PointXYZ, pcl::PointXYZ, double>;

Cloud::Ptr line_target() {  // x = 1, 2, 3, 4
  return test::to_cloud({Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(3, 0, 0), Vec3(4, 0, 0)});
}

pcl::Correspondences run(DropIn& est, const Cloud::Ptr& source, const Cloud::Ptr& target,
                         double max_distance = std::numeric_limits<double>::max()) {
  est.setInputSource(source);
  est.setInputTarget(target);
  pcl::Correspondences c;
  est.determineCorrespondences(c, max_distance);
  return c;
}

TEST(PclDropIn, PicksTheLargestWeightAmongTheKNearest) {
  const Cloud::Ptr src = test::to_cloud({Vec3(0, 0, 0)});
  DropIn est(3, {1, 5, 9, 100});
  pcl::Correspondences c = run(est, src, line_target());
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].index_query, 0);
  EXPECT_EQ(c[0].index_match, 2);  // weight 9: the largest among the 3 nearest
  EXPECT_FLOAT_EQ(c[0].distance, 9.0f);

  DropIn equal(4, {1, 7, 7, 7});  // equal weights: the nearer one
  c = run(equal, src, line_target());
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].index_match, 1);

  DropIn ranged(4, {1, 5, 9, 100});  // the max distance removes candidates first
  c = run(ranged, src, line_target(), 2.5);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].index_match, 1);

  DropIn zero(2, {0, 0, 3, 3});  // no positive weight among the candidates: none
  EXPECT_TRUE(run(zero, src, line_target()).empty());
}

TEST(PclDropIn, KOneWithoutWeightsIsPclsOwnEstimator) {
  const Cloud::Ptr target = test::to_cloud(test::room_points(2000, 5));
  const Cloud::Ptr source = test::to_cloud(
      transform_points(pose_from_xyz_rpy_deg(0.1, 0, 0.05, 2, 1, 5), test::room_points(1500, 6)));
  pcl::registration::CorrespondenceEstimation<pcl::PointXYZ, pcl::PointXYZ, double> stock;
  stock.setInputSource(source);
  stock.setInputTarget(target);
  pcl::Correspondences expected;
  stock.determineCorrespondences(expected, 0.3);
  DropIn est;  // k = 1, no weights
  const pcl::Correspondences got = run(est, source, target, 0.3);
  ASSERT_EQ(got.size(), expected.size());
  ASSERT_GT(got.size(), 1000u);
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].index_query, expected[i].index_query);
    EXPECT_EQ(got[i].index_match, expected[i].index_match);
    EXPECT_EQ(got[i].distance, expected[i].distance);
  }
}

TEST(PclDropIn, RejectsBadWeightsAndK) {
  EXPECT_THROW(DropIn(0, {}), InvalidArgument);
  EXPECT_THROW(DropIn(3, {1.0, -1.0}), InvalidArgument);
  EXPECT_THROW(DropIn(3, {1.0, std::nan("")}), InvalidArgument);
  DropIn wrong_size(2, {1.0, 2.0});
  const Cloud::Ptr src = test::to_cloud({Vec3(0, 0, 0)});
  EXPECT_THROW(run(wrong_size, src, line_target()), InvalidArgument);
}

TEST(PclDropIn, ReciprocalKeepsOnlyMutualChoices) {
  // Two sources near target 0; only the nearer one is target 0's nearest source.
  const Cloud::Ptr src = test::to_cloud({Vec3(1.1, 0, 0), Vec3(1.3, 0, 0)});
  DropIn est(1, {1, 1, 1, 1});
  est.setInputSource(src);
  est.setInputTarget(line_target());
  pcl::Correspondences c;
  est.determineReciprocalCorrespondences(c);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].index_query, 0);
  EXPECT_EQ(c[0].index_match, 0);
}

TEST(PclDropIn, WorksInsidePclsIcp) {
  const Points3 tgt = {Vec3(0, 0, 0), Vec3(1, 0, 0),       Vec3(0, 1, 0),      Vec3(0, 0, 1),
                       Vec3(1, 1, 0), Vec3(0.3, 0.7, 0.2), Vec3(0.9, 0.2, 0.6)};
  const Isometry3 T = pose_from_xyz_rpy_deg(0.02, -0.01, 0.01, 0.5, 0, 1);
  pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ, double> icp;
  icp.setCorrespondenceEstimation(std::make_shared<DropIn>(1, std::vector<double>(7, 1.0)));
  icp.setInputSource(test::to_cloud(transform_points(T.inverse(), tgt)));
  icp.setInputTarget(test::to_cloud(tgt));
  Cloud out;
  icp.align(out);
  EXPECT_LT(icp.getFitnessScore(), 1e-8);
  const Eigen::Matrix4d err = icp.getFinalTransformation() - T.matrix();
  EXPECT_LT(err.cwiseAbs().maxCoeff(), 1e-4);
}

// The real pair: at several poses, the drop-in (float, PCL's kd-tree) and lmalign's strategy
// (double, lmalign's kd-tree) on the same float-representable coordinates choose the same target
// landmark for every source landmark. The only index differences allowed are between duplicate
// landmarks (identical positions: an exact distance tie that the two trees order differently);
// squared distances agree to float precision.
TEST(PclDropIn, SameCorrespondencesAsLmalignOnTheRealPair) {
  LMALIGN_REQUIRE_FILE(test::pair_file("desk_gt_a.txt"));
  const Map a = read_map(test::pair_file("desk_gt_a.txt"));
  const Map b = read_map(test::pair_file("desk_gt_b.txt"));
  const PreparedTarget prepared(b);
  const Cloud::Ptr target = test::to_cloud(b.positions());
  const Points3 target_d = test::from_cloud(*target);
  const KdTree tree(target_d);
  const std::vector<int> canon = test::canonical_indices(target_d);
  std::size_t index_only = 0, compared = 0;
  for (const Isometry3& D :
       {Isometry3(Isometry3::Identity()), pose_from_xyz_rpy_deg(0, 1, 0.4, 10, 0, 22.5),
        pose_from_xyz_rpy_deg(0, 0, 0, 0, 0, 50), pose_from_xyz_rpy_deg(0.5, -0.5, 0, 0, 0, 0)}) {
    const Cloud::Ptr source = test::to_cloud(transform_points(D, a.positions()));
    const Points3 source_d = test::from_cloud(*source);
    for (WeightKind st : all_weight_kinds()) {
      const std::vector<double>& w = prepared.weights(st);
      CorrespondenceOptions co;
      co.kind = CorrespondenceKind::kWeightedKnn;  // k = 5 everywhere; base: k = 1
      co.k = st == WeightKind::kUniform ? 1 : 5;
      Correspondences ours;
      CorrespondenceFinder(tree, w, co).find(source_d, ours);
      DropIn est(co.k, w);
      const pcl::Correspondences theirs = run(est, source, target);
      ASSERT_EQ(ours.size(), theirs.size()) << to_string(st);
      for (std::size_t i = 0; i < ours.size(); ++i) {
        ASSERT_EQ(static_cast<int>(ours[i].source_index), theirs[i].index_query);
        const int mine = static_cast<int>(ours[i].target_index);
        const int pcls = theirs[i].index_match;
        ASSERT_EQ(canon[static_cast<std::size_t>(mine)], canon[static_cast<std::size_t>(pcls)])
            << to_string(st) << " source " << ours[i].source_index;
        index_only += mine != pcls;
        EXPECT_NEAR(theirs[i].distance, ours[i].distance_sq_m2, 1e-6 * ours[i].distance_sq_m2);
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 16u * 3050u);
  EXPECT_LT(index_only, compared / 100);  // duplicates are rare
}

}  // namespace
}  // namespace lmalign
