#include "lmalign/registration/convergence.hpp"

#include <cmath>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/error.hpp"

namespace lmalign {

std::string to_string(TerminationReason reason) {
  static constexpr EnumName<TerminationReason> kNames[] = {
      {TerminationReason::kNotTerminated, "not_terminated"},
      {TerminationReason::kMaxIterations, "max_iterations"},
      {TerminationReason::kTransform, "transform"},
      {TerminationReason::kAbsoluteMse, "absolute_mse"},
      {TerminationReason::kRelativeMse, "relative_mse"},
      {TerminationReason::kNoCorrespondences, "no_correspondences"},
      {TerminationReason::kDegenerate, "degenerate"}};
  return name_of(kNames, reason);
}

bool ConvergenceOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& msg) {
    if (why != nullptr) *why = msg;
    return false;
  };
  if (max_iterations < 1) {
    return fail("max_iterations must be >= 1, got " + std::to_string(max_iterations));
  }
  if (std::isnan(transformation_epsilon_m2) || transformation_epsilon_m2 < 0.0) {
    return fail("transformation_epsilon_m2 must be >= 0, got " +
                std::to_string(transformation_epsilon_m2));
  }
  if (std::isnan(transformation_rotation_epsilon_cos) ||
      transformation_rotation_epsilon_cos > 1.0) {
    return fail("transformation_rotation_epsilon_cos must be <= 1, got " +
                std::to_string(transformation_rotation_epsilon_cos));
  }
  if (std::isnan(euclidean_fitness_epsilon)) return fail("euclidean_fitness_epsilon is NaN");
  if (std::isnan(absolute_mse_epsilon_m2)) return fail("absolute_mse_epsilon_m2 is NaN");
  if (max_iterations_similar_transforms < 0) {
    return fail("max_iterations_similar_transforms must be >= 0, got " +
                std::to_string(max_iterations_similar_transforms));
  }
  if (min_correspondences < 3) {
    return fail("min_correspondences must be >= 3, got " + std::to_string(min_correspondences));
  }
  return true;
}

ConvergenceCriteria::ConvergenceCriteria(const ConvergenceOptions& options) : options_(options) {
  std::string why;
  if (!options_.is_valid(&why)) throw InvalidArgument("convergence options: " + why);
  // IterativeClosestPoint::computeTransformation: a positive rotation epsilon is used as is,
  // otherwise 1 - transformation_epsilon.
  rotation_threshold_cos_ = options_.transformation_rotation_epsilon_cos > 0.0
                                ? options_.transformation_rotation_epsilon_cos
                                : 1.0 - options_.transformation_epsilon_m2;
}

double correspondence_mse_m2(const Correspondences& correspondences) {
  if (correspondences.empty()) return 0.0;
  double sum = 0.0;
  for (const Correspondence& c : correspondences) sum += c.distance_sq_m2;
  return sum / static_cast<double>(correspondences.size());
}

TerminationReason ConvergenceCriteria::check(int iterations, const Isometry3& increment,
                                             const Correspondences& correspondences) {
  bool is_similar = false;
  const int similar_needed = options_.max_iterations_similar_transforms;

  // 1. Iteration budget (PCL: failure_after_max_iter_ false -> ITERATIONS).
  if (iterations >= options_.max_iterations) return TerminationReason::kMaxIterations;

  // 2. Transformation increment.
  const Mat3& R = increment.linear();
  const double cos_angle = 0.5 * (R(0, 0) + R(1, 1) + R(2, 2) - 1.0);
  const double translation_sq = increment.translation().squaredNorm();
  if (cos_angle >= rotation_threshold_cos_ &&
      translation_sq <= options_.transformation_epsilon_m2) {
    if (similar_iterations_ >= similar_needed) return TerminationReason::kTransform;
    is_similar = true;
  }

  current_mse_ = correspondence_mse_m2(correspondences);

  // 3. Absolute MSE change.
  const double delta = std::abs(current_mse_ - previous_mse_);
  if (delta < options_.absolute_mse_epsilon_m2) {
    if (similar_iterations_ >= similar_needed) return TerminationReason::kAbsoluteMse;
    is_similar = true;
  }

  // 4. Relative MSE change.
  if (delta / previous_mse_ < options_.euclidean_fitness_epsilon) {
    if (similar_iterations_ >= similar_needed) return TerminationReason::kRelativeMse;
    is_similar = true;
  }

  similar_iterations_ = is_similar ? similar_iterations_ + 1 : 0;
  previous_mse_ = current_mse_;
  return TerminationReason::kNotTerminated;
}

}  // namespace lmalign
