// PCL's side of `make bench`: pcl::IterativeClosestPoint<PointXYZ, PointXYZ, double> on the real
// pair (desk_gt_a displaced by Table 1, onto desk_gt_b), N forced iterations. One configuration
// per process (--config):
//   pcl_icp             stock ICP (nearest-neighbour correspondences)
//   pcl_icp_dropin_k5   ICP with lmalign's drop-in weighted-kNN correspondences (k=5, the
//                       observation weights): the same correspondences as lmalign weighted k=5
//   pcl_paper_pipeline  the drop-in plus getFitnessScore() at every iteration from ICP's
//                       visualisation callback, as the paper's published code timed its runs
//                       (it also printed each score; we do not print)
// The timed section is setInputSource/Target + align(), which builds PCL's kd-tree of the
// target. Convergence is disabled (PCL's absolute-MSE threshold set to -1, and the similar-
// transforms count out of reach), so every run does exactly N iterations.
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>

#include "common.hpp"
#include "lmalign/pcl.hpp"

namespace lmalign::bench {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using PclIcp = pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ, double>;
// Exposes the iteration count (a protected member of pcl::Registration).
class Icp : public PclIcp {
 public:
  int iterations() const { return nr_iterations_; }
};

// Exactly `iterations` iterations: no convergence test can fire.
void force_iterations(PclIcp& icp, int iterations) {
  icp.setMaximumIterations(iterations);
  auto criteria = icp.getConvergeCriteria();
  criteria->setAbsoluteMSE(-1.0);
  criteria->setMaximumIterationsSimilarTransforms(1 << 30);
}

int run(const Args& args) {
  const RealPair pair = load_real_pair();
  const Cloud::Ptr source = to_pcl_cloud(pair.source);
  const Cloud::Ptr target = to_pcl_cloud(pair.target);
  const std::string& c = args.config;
  bool dropin = false, scored = false;
  std::string description;
  if (c == "pcl_icp") {
    description = "PCL IterativeClosestPoint, stock (nearest neighbour)";
  } else if (c == "pcl_icp_dropin_k5") {
    dropin = true;
    description = "PCL IterativeClosestPoint + lmalign drop-in weighted k=5 (observations)";
  } else if (c == "pcl_paper_pipeline") {
    dropin = scored = true;
    description =
        "PCL IterativeClosestPoint + drop-in weighted k=5 + getFitnessScore() every iteration "
        "(the paper's pipeline)";
  } else {
    std::fprintf(stderr, "bench_pcl: unknown --config %s\n", c.c_str());
    return 2;
  }

  auto once = [&]() {
    Icp icp;
    force_iterations(icp, args.iterations);
    if (dropin) {
      icp.setCorrespondenceEstimation(
          std::make_shared<
              WeightedKnnCorrespondenceEstimation<pcl::PointXYZ, pcl::PointXYZ, double>>(
              5, pair.target_weights));
    }
    std::vector<double> scores;
    std::function<PclIcp::UpdateVisualizerCallbackSignature> callback =
        [&](const Cloud&, const pcl::Indices&, const Cloud&, const pcl::Indices&) {
          scores.push_back(icp.getFitnessScore());
        };
    icp.setInputSource(source);
    icp.setInputTarget(target);
    if (scored) {
      // PCL calls the callback once at registration (a score of the initial pose, as in the
      // paper's code), then after every iteration.
      scores.reserve(static_cast<std::size_t>(args.iterations) + 1);
      icp.registerVisualizationCallback(callback);
    }
    Cloud aligned;
    icp.align(aligned);
    const double score = scored && !scores.empty() ? scores.back() : icp.getFitnessScore();
    return RunResult{icp.iterations(), score};
  };
  return measure(c, "pcl", description, args.reps, once,
                 {{"threads", "1"}, {"pcl_version", "\"" PCL_VERSION_PRETTY "\""}});
}

}  // namespace
}  // namespace lmalign::bench

int main(int argc, char** argv) {
  return lmalign::bench::run_main("bench_pcl", argc, argv, lmalign::bench::run);
}
