#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/uncertainty.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/estimation.hpp"
#include "lmalign/registration/score.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

std::string to_string(RobustKernel kernel) {
  switch (kernel) {
    case RobustKernel::kNone:
      return "none";
    case RobustKernel::kHuber:
      return "huber";
    case RobustKernel::kCauchy:
      return "cauchy";
    case RobustKernel::kGemanMcClure:
      return "geman_mcclure";
  }
  return "?";
}

RobustKernel parse_robust_kernel(const std::string& name) {
  if (name == "none") return RobustKernel::kNone;
  if (name == "huber") return RobustKernel::kHuber;
  if (name == "cauchy") return RobustKernel::kCauchy;
  if (name == "geman_mcclure") return RobustKernel::kGemanMcClure;
  throw InvalidArgument("unknown robust kernel '" + name +
                        "' (expected none, huber, cauchy or geman_mcclure)");
}

std::string to_string(EstimationCost cost) {
  switch (cost) {
    case EstimationCost::kPointToPoint:
      return "point_to_point";
    case EstimationCost::kPointToDistribution:
      return "point_to_distribution";
  }
  return "?";
}

EstimationCost parse_estimation_cost(const std::string& name) {
  if (name == "point_to_point" || name == "p2p") return EstimationCost::kPointToPoint;
  if (name == "point_to_distribution" || name == "p2d") {
    return EstimationCost::kPointToDistribution;
  }
  throw InvalidArgument("unknown estimation cost '" + name +
                        "' (expected point_to_point|p2p or point_to_distribution|p2d)");
}

std::string to_string(KernelResidual residual) {
  switch (residual) {
    case KernelResidual::kEuclidean:
      return "euclidean";
    case KernelResidual::kMahalanobis:
      return "mahalanobis";
  }
  return "?";
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
      return 1.0 / (1.0 + u2);
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
  if (global_initialisation) {
    std::string inner;
    if (!global.is_valid(&inner)) return fail("global." + inner);
  }
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
  if (cost == EstimationCost::kPointToDistribution) {
    if (dof != DegreesOfFreedom::k6) {
      return fail(
          "cost = point_to_distribution needs dof = 6 (the 4-DoF point-to-distribution "
          "estimate is not implemented)");
    }
    std::string inner;
    if (!p2d.is_valid(&inner)) return fail("p2d." + inner);
    if (!(p2d_max_level_distance_m > 0.0)) {
      return fail("p2d_max_level_distance_m = " + std::to_string(p2d_max_level_distance_m) +
                  " (expected > 0)");
    }
    if (!(kernel_scale_sigma > 0.0) || !std::isfinite(kernel_scale_sigma)) {
      return fail("kernel_scale_sigma = " + std::to_string(kernel_scale_sigma) +
                  " (expected finite > 0)");
    }
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

RobustRegistrationOptions robust_strategy_options(PaperStrategy strategy, int k) {
  RobustRegistrationOptions o;
  o.k = k;
  switch (strategy) {
    case PaperStrategy::kShrink:
      break;
    case PaperStrategy::kShrinkCauchy:
      o.kernel = RobustKernel::kCauchy;
      break;
    case PaperStrategy::kTrimmed:
      o.estimate_overlap = true;
      break;
    case PaperStrategy::kMutual:
      o.mutual = true;
      break;
    case PaperStrategy::kRobustObs:
      o.kernel = RobustKernel::kCauchy;
      o.estimation_weight = WeightKind::kObservations;
      break;
    case PaperStrategy::kRobustObsKnn:
      o.kernel = RobustKernel::kCauchy;
      o.estimation_weight = WeightKind::kObservations;
      o.selection = CorrespondenceKind::kWeightedKnn;
      o.selection_weight = WeightKind::kObservations;
      break;
    case PaperStrategy::kRobustObs4Dof:
      o.kernel = RobustKernel::kCauchy;
      o.estimation_weight = WeightKind::kObservations;
      o.dof = DegreesOfFreedom::k4;
      break;
    case PaperStrategy::kGlobal:
      o.kernel = RobustKernel::kCauchy;
      o.estimation_weight = WeightKind::kObservations;
      o.global_initialisation = true;
      break;
    case PaperStrategy::kGlobalRobustObs:
      o.kernel = RobustKernel::kCauchy;
      o.estimation_weight = WeightKind::kObservations;
      o.global_search = true;
      break;
    case PaperStrategy::kP2D:
      o.cost = EstimationCost::kPointToDistribution;
      break;
    case PaperStrategy::kRobustP2D:
      o.kernel = RobustKernel::kCauchy;
      o.estimation_weight = WeightKind::kObservations;
      o.cost = EstimationCost::kPointToDistribution;
      break;
    case PaperStrategy::kAdaptive:
      throw InvalidArgument(
          "robust_strategy_options: 'adaptive' is the adaptive pipeline (use align_adaptive(), "
          "registration/adaptive.hpp, or run_strategy(), registration/strategy.hpp)");
    default:
      throw InvalidArgument("robust_strategy_options: '" + to_string(strategy) +
                            "' is one of the paper's strategies (use align())");
  }
  return o;
}

RobustRegistrationOptions with_limits(RobustRegistrationOptions options, int max_iterations,
                                      double max_distance_m) {
  if (max_iterations < 1) {
    throw InvalidArgument("with_limits: max_iterations = " + std::to_string(max_iterations) +
                          " (expected >= 1)");
  }
  if (!(max_distance_m > 0.0)) {
    throw InvalidArgument("with_limits: max_distance_m = " + std::to_string(max_distance_m) +
                          " (expected > 0 metres, or inf)");
  }
  options.max_iterations = max_iterations;
  options.max_iterations_per_level = std::min(options.max_iterations_per_level, max_iterations);
  if (std::isfinite(max_distance_m)) {
    std::vector<double> capped{max_distance_m};
    for (double d : options.max_distance_schedule_m) {
      if (d < max_distance_m) capped.push_back(d);
    }
    options.max_distance_schedule_m = capped;
  }
  return options;
}

namespace {

/// Source points within `distance_m` of a target point at T (the global search's score).
std::size_t consensus(const Points3& source_points, const KdTree& tree, const Isometry3& T,
                      double distance_m) {
  std::size_t n = 0;
  const double d2max = distance_m * distance_m;
  for (const Vec3& p : source_points) {
    PointIndex idx = 0;
    double d2 = 0.0;
    if (tree.nearest(T * p, &idx, &d2) && d2 <= d2max) ++n;
  }
  return n;
}

RobustRegistrationResult align_global(const Points3& source_points, const PreparedTarget& target,
                                      const RobustRegistrationOptions& options,
                                      const Isometry3& T_init,
                                      std::chrono::steady_clock::time_point t_start,
                                      const std::vector<Mat3>* source_cov) {
  // Hypotheses: the guess itself, then yaws about the moved source's centroid with the centroid
  // moved onto the target's centroid.
  Vec3 cs = Vec3::Zero();
  for (const Vec3& p : source_points) cs += T_init * p;
  cs /= static_cast<double>(source_points.size());
  Vec3 ct = Vec3::Zero();
  for (const Vec3& p : target.points()) ct += p;
  ct /= static_cast<double>(target.size());
  std::vector<Isometry3> hypotheses{T_init};
  for (int h = 0; h < options.yaw_hypotheses; ++h) {
    const double yaw = 2.0 * M_PI * h / options.yaw_hypotheses;
    Isometry3 H = Isometry3::Identity();
    H.linear() = rotation_about_up(options.up_axis, yaw);
    H.translation() = ct - H.linear() * cs;
    hypotheses.push_back(H * T_init);
  }
  RobustRegistrationOptions coarse = options;
  coarse.global_search = false;
  coarse.max_distance_schedule_m = options.global_schedule_m;
  coarse.max_iterations = options.global_iterations;
  coarse.max_iterations_per_level =
      std::max(1, options.global_iterations / static_cast<int>(options.global_schedule_m.size()));
  Points3 sub;
  std::vector<Mat3> sub_cov;
  for (std::size_t i = 0; i < source_points.size();
       i += static_cast<std::size_t>(options.global_subsample)) {
    sub.push_back(source_points[i]);
    if (source_cov != nullptr) sub_cov.push_back((*source_cov)[i]);
  }
  std::size_t best = 0;
  std::size_t best_score = 0;
  Isometry3 best_T = T_init;
  int iterations = 0;
  for (std::size_t h = 0; h < hypotheses.size(); ++h) {
    const RobustRegistrationResult r =
        align_robust(sub, target, coarse, hypotheses[h], source_cov ? &sub_cov : nullptr);
    iterations += r.iterations;
    const std::size_t score =
        consensus(sub, target.tree(), r.T_target_source, options.global_inlier_distance_m);
    if (h == 0 || score > best_score) {
      best = h;
      best_score = score;
      best_T = r.T_target_source;
    }
  }
  // The full run starts again at an unlimited distance from the chosen estimate: skipping that
  // level (the coarse run used a subsample) ended in a wrong minimum on the real pair.
  RobustRegistrationOptions local = options;
  local.global_search = false;
  RobustRegistrationResult result = align_robust(source_points, target, local, best_T, source_cov);
  result.initial_score_m2 = fitness_score(source_points, target.tree(), T_init).mean_sq_m2;
  result.iterations += iterations;
  (void)best;
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace

RobustRegistrationResult align_robust(const Points3& source_points, const PreparedTarget& target,
                                      const RobustRegistrationOptions& options,
                                      const Isometry3& T_target_source_init,
                                      const std::vector<Mat3>* source_covariances_m2) {
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

  const bool p2d = options.cost == EstimationCost::kPointToDistribution;
  if (p2d) {
    if (source_covariances_m2 == nullptr) {
      throw InvalidArgument(
          "robust registration: the point-to-distribution cost needs the source landmark "
          "covariances (none given)");
    }
    if (source_covariances_m2->size() != source_points.size()) {
      throw InvalidArgument(
          "robust registration: " + std::to_string(source_covariances_m2->size()) +
          " source covariances for " + std::to_string(source_points.size()) + " source points");
    }
    for (std::size_t i = 0; i < source_covariances_m2->size(); ++i) {
      if (!(*source_covariances_m2)[i].allFinite()) {
        throw InvalidArgument("robust registration: source covariance " + std::to_string(i) +
                              " is not finite");
      }
    }
    (void)target.covariances_m2();  // throws if the target has none
  }
  const std::vector<Mat3>* source_cov = p2d ? source_covariances_m2 : nullptr;

  if (options.global_search) {
    return align_global(source_points, target, options, T_target_source_init, t_start, source_cov);
  }
  const std::vector<Mat3> no_covariances;
  const std::vector<Mat3>& target_cov = p2d ? target.covariances_m2() : no_covariances;
  const double floor2 = options.p2d.covariance_floor_m * options.p2d.covariance_floor_m;
  // The residual the IRLS kernel sees for pair i under the full estimate T_full (see
  // KernelResidual): Euclidean metres, or the Mahalanobis distance rescaled to metres.
  auto kernel_residual = [&](const Correspondence& c, const Vec3& r, const Isometry3& T_full,
                             bool p2d_here) {
    if (!p2d_here || options.kernel_residual == KernelResidual::kEuclidean) return r.norm();
    const Mat3 R = T_full.linear();
    Mat3 M = target_cov[c.target_index] + R * (*source_cov)[c.source_index] * R.transpose();
    M.diagonal().array() += floor2;
    const double m2 = r.dot(M.ldlt().solve(r));
    return std::sqrt(std::max(0.0, m2)) * options.kernel_scale_m / options.kernel_scale_sigma;
  };

  const std::vector<double> no_weights;
  const std::vector<double>& selection_weights =
      options.selection == CorrespondenceKind::kWeightedKnn
          ? target.weights(options.selection_weight)
          : no_weights;
  const std::vector<double>* confidence = options.estimation_weight == WeightKind::kUniform
                                              ? nullptr
                                              : &target.weights(options.estimation_weight);
  // One finder per level (borrowed weights; stable addresses for the workspace binding).
  std::vector<CorrespondenceFinder> finders;
  finders.reserve(options.max_distance_schedule_m.size());
  for (double d : options.max_distance_schedule_m) {
    CorrespondenceOptions copt;
    copt.kind = options.selection;
    copt.k = options.k;
    copt.max_distance_m = d;
    finders.push_back(CorrespondenceFinder::borrowing(target.tree(), selection_weights, copt));
  }

  RobustRegistrationResult result;
  result.initial_score_m2 =
      fitness_score(source_points, target.tree(), T_target_source_init).mean_sq_m2;

  // With global initialisation the guess is ignored: the robust loop refines global_align()'s
  // (which needs 3 points a side; with fewer, the loop ends with no_correspondences anyway).
  Isometry3 T = options.global_initialisation && source_points.size() >= 3 && target.size() >= 3
                    ? global_align(source_points, target, options.global).T_target_source
                    : T_target_source_init;
  Points3 moved;
  Correspondences corr;
  std::vector<double> weights;
  std::vector<double> residuals_sq;
  std::size_t level = 0;
  int level_iterations = 0;
  CorrespondenceWorkspace workspace;
  const std::size_t min_corr = static_cast<std::size_t>(options.min_correspondences);
  const Points3& tp = target.points();

  for (;;) {
    const double d_level = options.max_distance_schedule_m[level];
    finders[level].find(source_points, T, moved, corr, workspace, true);
    // Mutual and trimming act once the distance gate is finite: at an unlimited level they would
    // shrink the basin (measured on the real pair; docs/accuracy.md).
    const bool gated = std::isfinite(d_level);
    if (options.mutual && gated) keep_mutual(moved, tp, corr);
    double ratio = gated ? options.trim_ratio : 1.0;
    if (gated && options.estimate_overlap && corr.size() >= 2) {
      residuals_sq.clear();
      for (const Correspondence& c : corr) residuals_sq.push_back(c.distance_sq_m2);
      ratio = estimate_overlap_ratio(residuals_sq, options.min_overlap_ratio);
    }
    if (ratio < 1.0) trim_correspondences(corr, ratio);
    result.overlap_ratio = ratio;
    if (corr.size() < min_corr) {
      result.termination = TerminationReason::kNoCorrespondences;
      result.num_correspondences = corr.size();
      break;
    }

    // IRLS on fixed correspondences: weights from the residuals under the current increment.
    const double scale = std::max(options.kernel_scale_m, options.kernel_scale_ratio * d_level);
    const bool p2d_level = p2d && d_level <= options.p2d_max_level_distance_m;
    Isometry3 increment = Isometry3::Identity();
    Isometry3 T_p2d = T;  // the point-to-distribution estimate itself (not composed: see below)
    EstimationReport report;
    weights.assign(corr.size(), 1.0);
    const int irls = options.kernel == RobustKernel::kNone ? 1 : options.irls_iterations;
    for (int it = 0; it < irls; ++it) {
      for (std::size_t i = 0; i < corr.size(); ++i) {
        const Vec3 r = increment * moved[corr[i].source_index] - tp[corr[i].target_index];
        const double c = confidence ? (*confidence)[corr[i].target_index] : 1.0;
        weights[i] =
            c * robust_weight(options.kernel, kernel_residual(corr[i], r, increment * T, p2d_level),
                              scale);
      }
      double wsum = 0.0;
      for (double w : weights) wsum += w;
      if (!(wsum > 0.0)) break;  // keep the last increment
      if (p2d_level) {
        // Gauss-Newton on the source in its own frame (so the source covariances need no
        // rotating), warm-started from the current increment.
        const PointToDistributionResult g = estimate_point_to_distribution(
            source_points, tp, corr, *source_cov, target_cov, &weights, options.p2d, increment * T);
        T_p2d = g.T_target_source;
        increment = T_p2d * T.inverse();
        report.degenerate = g.degenerate;
      } else {
        increment = options.dof == DegreesOfFreedom::k6
                        ? estimate_rigid_transform(moved, tp, corr, &weights, &report)
                        : estimate_4dof_transform(moved, tp, corr, &weights, options.up_axis);
      }
    }
    if (!is_finite(increment)) {
      result.termination = TerminationReason::kDegenerate;
      break;
    }
    // Gauss-Newton returns the full estimate with an orthonormalised rotation: taking it as is
    // (rather than composing increment * T, whose rounding would compound) keeps T rigid.
    T = p2d_level ? T_p2d : increment * T;
    ++result.iterations;
    ++level_iterations;
    result.num_correspondences = corr.size();

    const bool settled =
        increment.translation().norm() < options.settle_translation_m &&
        Eigen::AngleAxisd(increment.linear()).angle() < options.settle_rotation_rad;
    if (settled || level_iterations >= options.max_iterations_per_level) {
      if (level + 1 == finders.size()) {
        if (settled) {
          result.termination =
              report.degenerate ? TerminationReason::kDegenerate : TerminationReason::kTransform;
          break;
        }
        // not settled at the last level: keep going until the total budget ends
      } else {
        ++level;
        level_iterations = 0;
      }
    }
    if (result.iterations >= options.max_iterations) {
      result.termination = TerminationReason::kMaxIterations;
      break;
    }
  }

  // Final diagnostics at the final estimate, with the last level's correspondences.
  const std::size_t last = level;
  result.final_max_distance_m = options.max_distance_schedule_m[last];
  finders[last].find(source_points, T, moved, corr, workspace, true);
  if (options.mutual && std::isfinite(result.final_max_distance_m)) keep_mutual(moved, tp, corr);
  if (result.overlap_ratio < 1.0) trim_correspondences(corr, result.overlap_ratio);
  result.inlier_ratio =
      static_cast<double>(corr.size()) / static_cast<double>(source_points.size());
  if (!corr.empty()) {
    const double scale =
        std::max(options.kernel_scale_m, options.kernel_scale_ratio * result.final_max_distance_m);
    weights.resize(corr.size());
    const bool p2d_final = p2d && result.final_max_distance_m <= options.p2d_max_level_distance_m;
    double wsum = 0.0, wr2 = 0.0;
    for (std::size_t i = 0; i < corr.size(); ++i) {
      const Vec3 r = moved[corr[i].source_index] - tp[corr[i].target_index];
      const double c = confidence ? (*confidence)[corr[i].target_index] : 1.0;
      // Point-to-point keeps the pair's own distance (bit-identical to before P2D existed).
      const double rn =
          p2d_final ? kernel_residual(corr[i], r, T, true) : std::sqrt(corr[i].distance_sq_m2);
      weights[i] = c * robust_weight(options.kernel, rn, scale);
      wsum += weights[i];
      wr2 += weights[i] * corr[i].distance_sq_m2;
    }
    result.inlier_rms_m = wsum > 0.0 ? std::sqrt(wr2 / wsum) : 0.0;
    if (p2d_final) {
      result.covariance = Mat6::Zero();
      if (wsum > 0.0) {
        PointToDistributionOptions eval = options.p2d;
        eval.max_iterations = 0;  // the normal equations at T only
        const PointToDistributionResult g = estimate_point_to_distribution(
            source_points, tp, corr, *source_cov, target_cov, &weights, eval, T);
        if (!g.degenerate) result.covariance = g.variance_factor * g.covariance;
      }
    } else {
      const PoseCovariance cov = point_to_point_covariance(moved, tp, corr, &weights);
      result.covariance = cov.valid ? cov.covariance : Mat6::Zero();
    }
  }
  result.converged = result.termination == TerminationReason::kTransform;
  result.T_target_source = T;
  result.final_score_m2 = fitness_score(source_points, target.tree(), T).mean_sq_m2;
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

}  // namespace lmalign
