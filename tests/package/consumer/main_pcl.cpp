// Consumer of the installed lmalign::pcl component (the header-only PCL drop-in): the
// weighted-kNN estimator picks, among the k = 2 nearest target points, the one with the larger
// weight. Exit 0 on success.
#include <cstdio>
#include <memory>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <lmalign/pcl.hpp>

int main() {
  auto target = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  target->push_back({0.0f, 0.0f, 0.0f});  // nearest to the source point, weight 1
  target->push_back({0.5f, 0.0f, 0.0f});  // second nearest, weight 10
  target->push_back({9.0f, 9.0f, 9.0f});
  auto source = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  source->push_back({0.1f, 0.0f, 0.0f});
  lmalign::WeightedKnnCorrespondenceEstimation<pcl::PointXYZ, pcl::PointXYZ, double> est(
      2, {1.0, 10.0, 1.0});
  est.setInputTarget(target);
  est.setInputSource(source);
  pcl::Correspondences c;
  est.determineCorrespondences(c);
  std::printf("consumer_pcl: %zu correspondence(s), source 0 -> target %d\n", c.size(),
              c.empty() ? -1 : c[0].index_match);
  return c.size() == 1 && c[0].index_match == 1 ? 0 : 1;
}
