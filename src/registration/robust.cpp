#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/uncertainty.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/score.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

std::string to_string(RobustKernel kernel) { return name_of(kRobustKernelNames, kernel); }

RobustKernel parse_robust_kernel(const std::string& name) {
  return parse_enum(kRobustKernelNames, "robust kernel", name);
}

double robust_weight(RobustKernel kernel, double residual_m, double scale_m) {
  if (kernel == RobustKernel::kNone || std::isinf(scale_m)) return 1.0;
  const double r = std::abs(residual_m);
  const double u2 = (r / scale_m) * (r / scale_m);
  switch (kernel) {
    case RobustKernel::kNone:
      return 1.0;
    case RobustKernel::kHuber:
      return r <= scale_m ? 1.0 : scale_m / r;
    case RobustKernel::kCauchy:
      return cauchy_weight(u2);
    case RobustKernel::kGemanMcClure:
      return 1.0 / ((1.0 + u2) * (1.0 + u2));
  }
  return 1.0;
}

double estimate_overlap_ratio(std::vector<double> residuals_sq_m2, double min_ratio,
                              double lambda) {
  if (!(min_ratio > 0.0 && min_ratio <= 1.0)) {
    throw InvalidArgument("estimate_overlap_ratio: min_ratio must be in (0, 1], got " +
                          std::to_string(min_ratio));
  }
  if (!(lambda >= 0.0)) throw InvalidArgument("estimate_overlap_ratio: lambda must be >= 0");
  const std::size_t n = residuals_sq_m2.size();
  if (n < 2) return 1.0;
  std::sort(residuals_sq_m2.begin(), residuals_sq_m2.end());
  std::vector<double> prefix(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + residuals_sq_m2[i];
  double best = std::numeric_limits<double>::infinity();
  double best_ratio = 1.0;
  const int first = static_cast<int>(std::ceil(min_ratio * 100.0 - 1e-9));
  for (int step = first; step <= 100; ++step) {
    const double xi = step / 100.0;
    const std::size_t m = std::max<std::size_t>(
        1, std::min(n, static_cast<std::size_t>(std::ceil(xi * static_cast<double>(n) - 1e-9))));
    const double e = prefix[m] / static_cast<double>(m);
    const double psi = e / std::pow(xi, 1.0 + lambda);
    if (psi < best) {
      best = psi;
      best_ratio = xi;
    }
  }
  return best_ratio;
}

void trim_correspondences(Correspondences& correspondences, double ratio) {
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    throw InvalidArgument("trim_correspondences: ratio must be in (0, 1], got " +
                          std::to_string(ratio));
  }
  const std::size_t n = correspondences.size();
  const std::size_t keep =
      std::min(n, static_cast<std::size_t>(std::ceil(ratio * static_cast<double>(n) - 1e-9)));
  if (keep >= n) return;
  std::stable_sort(correspondences.begin(), correspondences.end(),
                   [](const Correspondence& a, const Correspondence& b) {
                     if (a.distance_sq_m2 != b.distance_sq_m2) {
                       return a.distance_sq_m2 < b.distance_sq_m2;
                     }
                     return a.source_index < b.source_index;
                   });
  correspondences.resize(keep);
  std::sort(correspondences.begin(), correspondences.end(),
            [](const Correspondence& a, const Correspondence& b) {
              return a.source_index < b.source_index;
            });
}

void keep_mutual(const Points3& moved_source, const Points3& target_points,
                 Correspondences& correspondences) {
  if (correspondences.empty()) return;
  const KdTree source_tree(moved_source);
  Correspondences kept;
  kept.reserve(correspondences.size());
  for (const Correspondence& c : correspondences) {
    PointIndex nearest = 0;
    double d2 = 0.0;
    if (source_tree.nearest(target_points[c.target_index], &nearest, &d2) &&
        nearest == c.source_index) {
      kept.push_back(c);
    }
  }
  correspondences.swap(kept);
}

bool RobustRegistrationOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (k < 1 || k > 4096) return fail("k = " + std::to_string(k) + " (expected 1..4096)");
  if (max_distance_schedule_m.empty()) return fail("max_distance_schedule_m is empty");
  for (std::size_t i = 0; i < max_distance_schedule_m.size(); ++i) {
    const double d = max_distance_schedule_m[i];
    if (!(d > 0.0)) {
      return fail("max_distance_schedule_m[" + std::to_string(i) + "] = " + std::to_string(d) +
                  " (expected > 0)");
    }
    if (i > 0 && d > max_distance_schedule_m[i - 1]) {
      return fail("max_distance_schedule_m[" + std::to_string(i) + "] = " + std::to_string(d) +
                  " (expected non-increasing)");
    }
  }
  if (!(trim_ratio > 0.0 && trim_ratio <= 1.0)) {
    return fail("trim_ratio = " + std::to_string(trim_ratio) + " (expected in (0, 1])");
  }
  if (!(min_overlap_ratio > 0.0 && min_overlap_ratio <= 1.0)) {
    return fail("min_overlap_ratio = " + std::to_string(min_overlap_ratio) +
                " (expected in (0, 1])");
  }
  if (!(kernel_scale_m > 0.0) || !std::isfinite(kernel_scale_m)) {
    return fail("kernel_scale_m = " + std::to_string(kernel_scale_m) + " (expected finite > 0)");
  }
  if (!(kernel_scale_ratio >= 0.0) || !std::isfinite(kernel_scale_ratio)) {
    return fail("kernel_scale_ratio = " + std::to_string(kernel_scale_ratio) +
                " (expected finite >= 0)");
  }
  if (irls_iterations < 1) {
    return fail("irls_iterations = " + std::to_string(irls_iterations) + " (expected >= 1)");
  }
  if (max_iterations < 1) {
    return fail("max_iterations = " + std::to_string(max_iterations) + " (expected >= 1)");
  }
  if (max_iterations_per_level < 1) {
    return fail("max_iterations_per_level = " + std::to_string(max_iterations_per_level) +
                " (expected >= 1)");
  }
  if (!(settle_translation_m >= 0.0)) {
    return fail("settle_translation_m = " + std::to_string(settle_translation_m) +
                " (expected >= 0)");
  }
  if (!(settle_rotation_rad >= 0.0)) {
    return fail("settle_rotation_rad = " + std::to_string(settle_rotation_rad) +
                " (expected >= 0)");
  }
  if (yaw_hypotheses < 1) {
    return fail("yaw_hypotheses = " + std::to_string(yaw_hypotheses) + " (expected >= 1)");
  }
  if (global_schedule_m.empty()) return fail("global_schedule_m is empty");
  for (std::size_t i = 0; i < global_schedule_m.size(); ++i) {
    const double d = global_schedule_m[i];
    if (!(d > 0.0) || (i > 0 && d > global_schedule_m[i - 1])) {
      return fail("global_schedule_m[" + std::to_string(i) + "] = " + std::to_string(d) +
                  " (expected > 0 and non-increasing)");
    }
  }
  if (global_subsample < 1) {
    return fail("global_subsample = " + std::to_string(global_subsample) + " (expected >= 1)");
  }
  if (global_iterations < 1) {
    return fail("global_iterations = " + std::to_string(global_iterations) + " (expected >= 1)");
  }
  if (!(global_inlier_distance_m > 0.0)) {
    return fail("global_inlier_distance_m = " + std::to_string(global_inlier_distance_m) +
                " (expected > 0)");
  }
  if (min_correspondences < 3) {
    return fail("min_correspondences = " + std::to_string(min_correspondences) +
                " (expected >= 3)");
  }
  return true;
}

RobustRegistrationResult align_robust(const Points3& source_points, const PreparedTarget& target,
                                      const RobustRegistrationOptions& options,
                                      const Isometry3& T_target_source_init) {
  const auto t_start = std::chrono::steady_clock::now();
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("robust registration options: " + why);
  if (!is_finite(T_target_source_init)) {
    throw InvalidArgument("robust registration: the initial guess is not finite");
  }
  if (source_points.empty()) throw InvalidArgument("robust registration: the source has no points");
  if (target.size() == 0) throw InvalidArgument("robust registration: the target has no points");
  for (std::size_t i = 0; i < source_points.size(); ++i) {
    if (!source_points[i].allFinite() ||
        !(source_points[i].cwiseAbs().maxCoeff() <= kMaxCoordinateM)) {
      throw InvalidArgument("robust registration: source point " + std::to_string(i) +
                            " is not finite or beyond kMaxCoordinateM");
    }
  }

  // A preset of the engine (pipeline.hpp).
  const Pipeline pipeline(robust_pipeline_spec(options));
  SourceView view;
  view.positions = &source_points;
  PipelineRequest request;
  request.initial_guess = T_target_source_init;
  const Summary s = pipeline.run(view, target, request);
  RobustRegistrationResult result;
  static_cast<RegistrationResult&>(result) = s.registration;
  result.inlier_ratio = s.at_estimate.inlier_ratio;
  result.overlap_ratio = s.at_estimate.overlap_ratio;
  result.final_max_distance_m = s.at_estimate.max_distance_m;
  result.inlier_rms_m = s.at_estimate.inlier_rms_m;
  result.covariance =
      s.estimator_covariance.valid ? s.estimator_covariance.covariance : Mat6::Zero();
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

PipelineSpec robust_pipeline_spec(const RobustRegistrationOptions& o) {
  PipelineSpec spec;
  spec.name = "robust";
  auto set = [&](const char* key, SettingValue v) {
    spec.settings.emplace_back(key, std::move(v));
  };
  auto integer = [](int v) { return static_cast<long long>(v); };
  if (o.global_search) {
    spec.initialiser = "yaw_centroid";
    set("init.yaw_hypotheses", integer(o.yaw_hypotheses));
    set("init.up_axis", to_string(o.up_axis));
    spec.scorer = "consensus";
    set("score.stride", integer(o.global_subsample));
    set("score.inlier_distance_m", o.global_inlier_distance_m);
  }
  if (o.selection == CorrespondenceKind::kWeightedKnn) {
    spec.matcher = "weighted_knn";
    set("match.k", integer(o.k));
    set("match.confidence", to_string(o.selection_weight));
  }
  if (o.mutual) spec.rejectors.push_back("mutual");
  if (o.trim_ratio < 1.0 || o.estimate_overlap) {
    spec.rejectors.push_back("trim");
    set("reject.trim_ratio", o.trim_ratio);
    set("reject.estimate_overlap", o.estimate_overlap);
    set("reject.min_overlap_ratio", o.min_overlap_ratio);
  }
  spec.kernel = to_string(o.kernel);
  set("kernel.confidence", to_string(o.estimation_weight));
  if (o.kernel != RobustKernel::kNone) {
    set("kernel.scale_m", o.kernel_scale_m);
    set("kernel.scale_ratio", o.kernel_scale_ratio);
    set("kernel.irls_iterations", integer(o.irls_iterations));
  }
  if (o.dof == DegreesOfFreedom::k4) {
    spec.estimator = "four_dof";
    set("estimate.up_axis", to_string(o.up_axis));
  }
  spec.schedule = "distance_levels";
  set("schedule.levels_m", o.max_distance_schedule_m);
  set("schedule.max_iterations", integer(o.max_iterations));
  set("schedule.max_iterations_per_level", integer(o.max_iterations_per_level));
  set("schedule.settle_translation_m", o.settle_translation_m);
  set("schedule.settle_rotation_rad", o.settle_rotation_rad);
  set("schedule.min_correspondences", integer(o.min_correspondences));
  set("schedule.hypothesis_levels_m", o.global_schedule_m);
  set("schedule.hypothesis_iterations", integer(o.global_iterations));
  return spec;
}

}  // namespace lmalign
