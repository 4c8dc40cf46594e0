// Open3D's global registration as a peer of the default's search in `make bench-accuracy`
// (issue 39, item 5; docs/accuracy.md, "Peers"): FPFH features, RANSAC on feature matches, then
// ICP, the recipe of Open3D's own global-registration tutorial (0.16,
// docs/tutorial/pipelines/global_registration.ipynb), through its C++ API.
//
//   lmalign_peer_open3d_global --source S --target T [--voxel-m V] [--seed N] [--no-icp]
//
// S and T are any map lmalign reads (landmark positions only: Open3D sees a point cloud). One JSON
// object on stdout: T_target_source (4x4, p_target = T * p_source), the CPU seconds of the
// registration (normals, features, RANSAC, ICP; not reading the maps), the RANSAC and ICP fitness
// and inlier RMSE (m), and the parameters used.
//
// The tutorial's parameters are in multiples of a voxel size v: normals within 2v (30 neighbours
// at most), FPFH within 5v (100 at most), mutual feature matches, RANSAC on 3 matches with the
// edge-length (0.9) and distance (1.5v) checkers, at most 100,000 iterations at confidence 0.999,
// then point-to-plane ICP within 0.4v. Landmark maps are already sparse, so nothing is
// downsampled; v defaults to the target's median distance to its 4th nearest landmark (the
// spacing a tutorial voxel grid would leave), or --voxel-m. One thread (OpenMP) and a fixed seed:
// the same answer at every run, and CPU time comparable with the default's single-thread time.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <exception>
#include <string>
#include <vector>

#include <open3d/geometry/KDTreeFlann.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/pipelines/registration/CorrespondenceChecker.h>
#include <open3d/pipelines/registration/Feature.h>
#include <open3d/pipelines/registration/Registration.h>
#include <open3d/pipelines/registration/TransformationEstimation.h>
#include <open3d/utility/Logging.h>
#include <open3d/utility/Random.h>

#include "lmalign/map/map_io.hpp"

namespace {

namespace reg = open3d::pipelines::registration;
using open3d::geometry::KDTreeFlann;
using open3d::geometry::KDTreeSearchParamHybrid;
using open3d::geometry::PointCloud;

struct Args {
  std::string source, target;
  double voxel_m = 0.0;  // 0: from the target's spacing
  int seed = 1;
  bool icp = true;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string key = argv[i];
    if (key == "--no-icp") {
      a.icp = false;
      continue;
    }
    if (i + 1 >= argc) throw std::runtime_error(key + ": expected a value after it");
    const std::string value = argv[++i];
    if (key == "--source") {
      a.source = value;
    } else if (key == "--target") {
      a.target = value;
    } else if (key == "--voxel-m") {
      a.voxel_m = std::stod(value);
      if (!(a.voxel_m > 0.0)) throw std::runtime_error("--voxel-m: expected a positive length");
    } else if (key == "--seed") {
      a.seed = std::stoi(value);
    } else {
      throw std::runtime_error("unknown option " + key +
                               " (expected --source, --target, --voxel-m, --seed, --no-icp)");
    }
  }
  if (a.source.empty() || a.target.empty())
    throw std::runtime_error("expected --source MAP --target MAP");
  return a;
}

/// The median distance from a point to its k-th nearest other point (m).
double median_kth_distance(const PointCloud& cloud, int k) {
  const KDTreeFlann tree(cloud);
  std::vector<double> d;
  d.reserve(cloud.points_.size());
  std::vector<int> index;
  std::vector<double> dist2;
  for (const Eigen::Vector3d& p : cloud.points_) {
    if (tree.SearchKNN(p, k + 1, index, dist2) == k + 1) d.push_back(std::sqrt(dist2[k]));
  }
  if (d.empty()) throw std::runtime_error("the target has too few landmarks for a spacing");
  std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

double cpu_seconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

int run(const Args& a) {
  open3d::utility::SetVerbosityLevel(open3d::utility::VerbosityLevel::Error);
  omp_set_num_threads(1);
  open3d::utility::random::Seed(a.seed);
  PointCloud source, target;
  source.points_ = lmalign::read_map(a.source).positions();
  target.points_ = lmalign::read_map(a.target).positions();
  if (source.points_.size() < 4 || target.points_.size() < 4)
    throw std::runtime_error("a map has fewer than 4 landmarks");

  const double t0 = cpu_seconds();
  const double v = a.voxel_m > 0.0 ? a.voxel_m : median_kth_distance(target, 4);
  for (PointCloud* cloud : {&source, &target})
    cloud->EstimateNormals(KDTreeSearchParamHybrid(2.0 * v, 30));
  const auto source_fpfh = reg::ComputeFPFHFeature(source, KDTreeSearchParamHybrid(5.0 * v, 100));
  const auto target_fpfh = reg::ComputeFPFHFeature(target, KDTreeSearchParamHybrid(5.0 * v, 100));
  const reg::CorrespondenceCheckerBasedOnEdgeLength edge_length(0.9);
  const reg::CorrespondenceCheckerBasedOnDistance distance(1.5 * v);
  const reg::RegistrationResult ransac = reg::RegistrationRANSACBasedOnFeatureMatching(
      source, target, *source_fpfh, *target_fpfh, true, 1.5 * v,
      reg::TransformationEstimationPointToPoint(false), 3, {edge_length, distance},
      reg::RANSACConvergenceCriteria(100000, 0.999));
  reg::RegistrationResult result = ransac;
  if (a.icp) {
    result = reg::RegistrationICP(source, target, 0.4 * v, ransac.transformation_,
                                  reg::TransformationEstimationPointToPlane());
  }
  const double cpu_s = cpu_seconds() - t0;

  std::printf(
      "{\"peer\": \"open3d_fpfh_ransac_icp\", \"open3d\": \"0.16\", \"T_target_source\": [");
  for (int r = 0; r < 4; ++r) {
    std::printf("%s[%.17g, %.17g, %.17g, %.17g]", r ? ", " : "", result.transformation_(r, 0),
                result.transformation_(r, 1), result.transformation_(r, 2),
                result.transformation_(r, 3));
  }
  std::printf(
      "], \"cpu_s\": %.6f, \"voxel_m\": %.9g, \"seed\": %d, \"icp\": %s, \"source_landmarks\": "
      "%zu, "
      "\"target_landmarks\": %zu, \"ransac_fitness\": %.9g, \"ransac_inlier_rmse_m\": %.9g, "
      "\"fitness\": %.9g, \"inlier_rmse_m\": %.9g}\n",
      cpu_s, v, a.seed, a.icp ? "true" : "false", source.points_.size(), target.points_.size(),
      ransac.fitness_, ransac.inlier_rmse_, result.fitness_, result.inlier_rmse_);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parse(argc, argv));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lmalign_peer_open3d_global: %s\n", e.what());
    return 2;
  }
}
