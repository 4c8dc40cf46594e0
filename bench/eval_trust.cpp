// Accuracy study of the uncertainty and the trust verdict (docs/accuracy.md): over the basin
// sweep of configs/basin.yaml (desk_gt_a displaced onto desk_gt_b, true transform identity),
// run the paper's base ICP and three robust presets (global_robust_obs, robust_obs, mutual), and
// for every result
//   - the 6x6 covariance on its inliers (nearest target within 5 cm) and its NEES against the
//     truth (for right-basin results: is the covariance calibrated?);
//   - and for the presets the NEES of the covariance the result itself carries (the estimator's,
//     Summary::estimator_covariance);
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
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/registration.hpp"
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
      // The paper's base ICP, and three presets that report their own covariance.
      static const char* const kPresets[kMethods] = {"base", "global_robust_obs", "robust_obs",
                                                     "mutual"};
      Isometry3 est[kMethods];
      PoseCovariance own[kMethods];
      SourceView view;
      view.positions = &displaced;
      view.covariances_m2 = &displaced_cov;
      for (int m = 0; m < kMethods; ++m) {
        const Summary s = align(find_preset(kPresets[m]), view, target);
        est[m] = s.registration.T_target_source;
        own[m] = s.estimator_covariance;
      }
      const char* const* names = kPresets;
      for (int m = 0; m < kMethods; ++m) {
        const Isometry3 T_map = est[m] * c.D;  // the recovered map-to-map transform
        const TransformError e = transform_error(T_map, Isometry3::Identity());
        PoseCovariance cov;
        const TrustVerdict v = judge_alignment(source, target.tree(), T_map, trust, &cov);
        if (m >= 1) {
          // The result's own covariance: a left perturbation of T, hence of T * D too.
          cov.covariance = own[m].covariance;
          cov.valid = own[m].valid;
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
