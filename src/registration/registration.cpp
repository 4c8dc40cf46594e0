#include "lmalign/registration/registration.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/stages/data_scales.hpp"

namespace lmalign {

RegistrationOptions RegistrationOptions::paper(WeightKind weight, int k) {
  RegistrationOptions o;
  o.k = k;
  o.weight = weight;
  o.correspondence = weight == WeightKind::kUniform ? CorrespondenceKind::kNearest
                                                    : CorrespondenceKind::kWeightedKnn;
  return o;
}

bool RegistrationOptions::is_valid(std::string* why) const {
  CorrespondenceOptions c;
  c.kind = correspondence;
  c.k = k;
  c.max_distance_m = max_correspondence_distance_m;
  std::string inner;
  if (!c.is_valid(&inner)) {
    // Map the correspondence field names onto this struct's names.
    if (inner.rfind("max_distance_m", 0) == 0)
      inner = "max_correspondence_distance_m" + inner.substr(14);
    if (why != nullptr) *why = inner;
    return false;
  }
  if (!convergence.is_valid(&inner)) {
    if (why != nullptr) *why = "convergence." + inner;
    return false;
  }
  if (std::isnan(score_max_range_m) || score_max_range_m <= 0.0) {
    if (why != nullptr) *why = "score_max_range_m must be > 0 (or infinite)";
    return false;
  }
  return true;
}

std::string RegistrationResult::brief_report() const {
  char buf[256];
  std::snprintf(buf, sizeof(buf),
                "%s after %d iterations (%s); score %.6g -> %.6g m^2; %zu correspondences; "
                "%.3f ms",
                converged ? "converged" : "stopped", iterations, to_string(termination).c_str(),
                initial_score_m2, final_score_m2, num_correspondences, wall_time_s * 1e3);
  return buf;
}

namespace {
void check_coordinate_range(const char* which, const Points3& points) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double largest = points[i].cwiseAbs().maxCoeff();
    if (!(largest <= kMaxCoordinateM)) {
      char buf[160];
      std::snprintf(buf, sizeof(buf),
                    "registration: %s point %zu has a coordinate of magnitude %g m, beyond the "
                    "supported %g m",
                    which, i, largest, kMaxCoordinateM);
      throw InvalidArgument(buf);
    }
  }
}

Points3 validated_positions(const Map& map) {
  map.validate();
  return map.positions();
}
}  // namespace

PreparedTarget::PreparedTarget(const Map& target, const WeightOptions& weight_options)
    : tree_(validated_positions(target)) {
  for (WeightKind kind : {WeightKind::kUniform, WeightKind::kCovariance, WeightKind::kObservations,
                          WeightKind::kMeanDistance}) {
    weights_[kind] = compute_weights(target, kind, weight_options);
  }
  covariances_ = target.covariances_m2();
  up_axis_ = estimate_up_axis(target);
}

void PreparedTarget::set_up_axis(std::optional<Vec3> up) {
  if (up.has_value()) {
    if (!up->allFinite() || !(up->norm() > 0.0)) {
      throw InvalidArgument("set_up_axis: the up axis must be finite and non-zero");
    }
    up->normalize();
  }
  up_axis_ = up;
}

PreparedTarget::PreparedTarget(Points3 points) : tree_(std::move(points)) {
  weights_[WeightKind::kUniform] = std::vector<double>(tree_.size(), 1.0);
}

void PreparedTarget::set_weights(WeightKind kind, std::vector<double> weights) {
  if (weights.size() != tree_.size()) {
    throw InvalidArgument("set_weights: " + std::to_string(weights.size()) + " weights for " +
                          std::to_string(tree_.size()) + " target points");
  }
  for (std::size_t i = 0; i < weights.size(); ++i) {
    if (!std::isfinite(weights[i]) || weights[i] < 0.0) {
      throw InvalidArgument("set_weights: weight " + std::to_string(i) +
                            " must be finite and >= 0");
    }
  }
  weights_[kind] = std::move(weights);
}

void PreparedTarget::set_covariances(std::vector<Mat3> covariances_m2) {
  if (covariances_m2.size() != tree_.size()) {
    throw InvalidArgument("set_covariances: " + std::to_string(covariances_m2.size()) +
                          " covariances for " + std::to_string(tree_.size()) + " target points");
  }
  for (std::size_t i = 0; i < covariances_m2.size(); ++i) {
    if (!covariances_m2[i].allFinite()) {
      throw InvalidArgument("set_covariances: covariance " + std::to_string(i) + " is not finite");
    }
  }
  covariances_ = std::move(covariances_m2);
}

const std::vector<Mat3>& PreparedTarget::covariances_m2() const {
  if (!has_covariances()) {
    throw InvalidArgument(
        "target has no landmark covariances (built from bare points; use a Map or "
        "set_covariances()), which the point-to-distribution cost needs");
  }
  return covariances_;
}

const std::vector<double>& PreparedTarget::weights(WeightKind kind) const {
  auto it = weights_.find(kind);
  if (it == weights_.end()) {
    throw InvalidArgument("target has no '" + to_string(kind) +
                          "' weights (built from bare points)");
  }
  return it->second;
}

RegistrationResult align(const Points3& source_points, const PreparedTarget& target,
                         const RegistrationOptions& options,
                         const Isometry3& T_target_source_init) {
  const auto t_start = std::chrono::steady_clock::now();
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("registration options: " + why);
  if (!is_finite(T_target_source_init)) {
    throw InvalidArgument("registration: the initial guess T_target_source_init is not finite");
  }
  for (std::size_t i = 0; i < source_points.size(); ++i) {
    if (!source_points[i].allFinite()) {
      throw InvalidArgument("registration: source point " + std::to_string(i) + " is not finite");
    }
  }
  // Degenerate inputs (docs/robustness.md): empty sets are refused; coordinates so large that
  // a double cannot resolve 0.1 m are refused before anything can overflow.
  if (source_points.empty()) throw InvalidArgument("registration: the source has no points");
  if (target.size() == 0) throw InvalidArgument("registration: the target has no points");
  check_coordinate_range("source", source_points);
  check_coordinate_range("target", target.points());
  if (!(T_target_source_init.translation().cwiseAbs().maxCoeff() <= kMaxCoordinateM)) {
    throw InvalidArgument("registration: the initial guess translation exceeds " +
                          std::to_string(kMaxCoordinateM) + " m");
  }

  // The paper's ICP is a preset of the engine (pipeline.hpp): the initial guess, the nearest or
  // the weighted-kNN matcher, no kernel, Umeyama, PCL's convergence criteria.
  const Pipeline pipeline(paper_pipeline_spec(options));
  SourceView view;
  view.positions = &source_points;
  PipelineRequest request;
  request.initial_guess = T_target_source_init;
  request.record_history = options.record_history;
  request.history_scores = options.history_scores;
  RegistrationResult result = pipeline.run(view, target, request).registration;
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

PipelineSpec paper_pipeline_spec(const RegistrationOptions& options) {
  PipelineSpec spec;
  spec.name = "paper";
  spec.matcher =
      options.correspondence == CorrespondenceKind::kWeightedKnn ? "weighted_knn" : "nearest";
  if (options.correspondence == CorrespondenceKind::kWeightedKnn) {
    spec.settings.emplace_back("match.k", static_cast<long long>(options.k));
    spec.settings.emplace_back("match.confidence", to_string(options.weight));
  }
  spec.settings.emplace_back("match.reuse_neighbours", options.reuse_neighbours);
  const ConvergenceOptions& c = options.convergence;
  spec.settings.emplace_back("schedule.max_distance_m", options.max_correspondence_distance_m);
  spec.settings.emplace_back("schedule.max_iterations", static_cast<long long>(c.max_iterations));
  spec.settings.emplace_back("schedule.transformation_epsilon_m2", c.transformation_epsilon_m2);
  spec.settings.emplace_back("schedule.transformation_rotation_epsilon_cos",
                             c.transformation_rotation_epsilon_cos);
  spec.settings.emplace_back("schedule.euclidean_fitness_epsilon", c.euclidean_fitness_epsilon);
  spec.settings.emplace_back("schedule.absolute_mse_epsilon_m2", c.absolute_mse_epsilon_m2);
  spec.settings.emplace_back("schedule.max_iterations_similar_transforms",
                             static_cast<long long>(c.max_iterations_similar_transforms));
  spec.settings.emplace_back("schedule.min_correspondences",
                             static_cast<long long>(c.min_correspondences));
  spec.settings.emplace_back("fitness.max_range_m", options.score_max_range_m);
  return spec;
}

RegistrationResult align_maps(const Map& source, const Map& target,
                              const RegistrationOptions& options,
                              const Isometry3& T_target_source_init) {
  source.validate();
  const PreparedTarget prepared(target);
  return align(source.positions(), prepared, options, T_target_source_init);
}

}  // namespace lmalign
