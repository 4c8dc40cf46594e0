// Accuracy study of the uncertainty and the trust verdict (docs/accuracy.md): over the basin
// sweep of configs/basin.yaml (desk_gt_a displaced onto desk_gt_b, true transform identity),
// run the paper's base ICP and the global initialisation, and for every result
//   - the 6x6 covariance on its inliers (nearest target within 5 cm) and its NEES against the
//     truth (for right-basin results: is the covariance calibrated?);
//   - and for robust_obs and robust_p2d (point-to-distribution, with both maps' covariances) the
//     NEES of the covariance the result itself carries (RobustRegistrationResult::covariance);
//   - the trust verdict, against the truth (right basin: < 5 deg and < 10 cm): precision and
//     recall of "trustworthy".
// Prints one JSON object. Usage: lmalign_eval_trust [--samples S] (default: the config's)
#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "lmalign/core/first_exception.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/experiment/cases.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/global_init.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {
namespace {

struct Row {
  std::string method;
  double yaw_deg, translation_m;
  bool right_basin;
  bool trustworthy;
  double nees;
  double inlier_fraction;
  double near_fraction;
};

int run(int argc, char** argv) {
  std::string config_path = std::string(LMALIGN_SOURCE_DIR) + "/configs/basin.yaml";
  int samples = -1;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--samples")) samples = std::atoi(argv[i + 1]);
    if (!std::strcmp(argv[i], "--config")) config_path = argv[i + 1];
  }
  ConfigLoadOptions load;
  const char* env = std::getenv("LMALIGN_DATA");
  load.data_dir = env != nullptr && *env != '\0' ? env : LMALIGN_DEFAULT_DATA_DIR;
  ExperimentConfig config = load_experiment_config(config_path, load);
  if (samples > 0) {
    for (auto& e : config.experiments) e.basin.samples = static_cast<std::size_t>(samples);
  }
  const Map source_map = read_map(config.source.path);
  const Points3 source = source_map.positions();
  const std::vector<Mat3> source_cov = source_map.covariances_m2();
  const PreparedTarget target(read_map(config.target.path));
  const std::vector<Case> cases = expand_cases(config, source);
  const TrustOptions trust;
  constexpr int kMethods = 4;
  std::vector<Row> rows(cases.size() * kMethods);
  FirstException error;  // an exception may not leave the parallel loop
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(cases.size()); ++i) {
    error.capture([&] {
      const Case& c = cases[static_cast<std::size_t>(i)];
      const Points3 displaced = transform_points(c.D, source);
      std::vector<Mat3> displaced_cov = source_cov;
      for (Mat3& C : displaced_cov) C = c.D.linear() * C * c.D.linear().transpose();
      const RobustRegistrationResult ro =
          align_robust(displaced, target, robust_strategy_options(PaperStrategy::kRobustObs));
      const RobustRegistrationResult rp =
          align_robust(displaced, target, robust_strategy_options(PaperStrategy::kRobustP2D),
                       Isometry3::Identity(), &displaced_cov);
      const Isometry3 est[kMethods] = {
          align(displaced, target, RegistrationOptions::paper(PaperStrategy::kBase))
              .T_target_source,
          global_align(displaced, target).T_target_source, ro.T_target_source, rp.T_target_source};
      const char* names[kMethods] = {"base", "global", "robust_obs", "robust_p2d"};
      for (int m = 0; m < kMethods; ++m) {
        const Isometry3 T_map = est[m] * c.D;  // the recovered map-to-map transform
        const TransformError e = transform_error(T_map, Isometry3::Identity());
        PoseCovariance cov;
        const TrustVerdict v = judge_alignment(source, target.tree(), T_map, trust, &cov);
        if (m >= 2) {
          // The result's own covariance: a left perturbation of T, hence of T * D too.
          cov.covariance = (m == 2 ? ro : rp).covariance;
          cov.valid = !cov.covariance.isZero();
        }
        Row& r = rows[static_cast<std::size_t>(i) * kMethods + m];
        r.method = names[m];
        const Vec3 xyz = c.D.translation();
        r.yaw_deg = xyz_rpy_deg_from_pose(c.D)[5];
        r.translation_m = xyz.head<2>().norm();
        r.right_basin = e.rotation_deg < 5.0 && e.translation_m < 0.10;
        r.trustworthy = v.trustworthy;
        r.nees = nees(pose_error_twist(T_map, Isometry3::Identity()), cov);
        r.inlier_fraction = v.inlier_fraction;
        r.near_fraction = v.overlap_fraction;
      }
    });
  }
  error.rethrow();
  std::printf("{\"config\": \"%s\", \"runs\": [", config_path.c_str());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Row& r = rows[i];
    std::printf(
        "%s{\"method\": \"%s\", \"right_basin\": %s, \"trustworthy\": %s, \"nees\": %.6g, "
        "\"inlier_fraction\": %.6g, \"near_fraction\": %.6g}",
        i ? ", " : "", r.method.c_str(), r.right_basin ? "true" : "false",
        r.trustworthy ? "true" : "false", std::isfinite(r.nees) ? r.nees : -1.0, r.inlier_fraction,
        r.near_fraction);
  }
  std::printf("]}\n");
  return 0;
}

}  // namespace
}  // namespace lmalign

int main(int argc, char** argv) {
  try {
    return lmalign::run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "eval_trust: %s\n", e.what());
    return 2;
  }
}
