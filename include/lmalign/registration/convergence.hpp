// Convergence test with the semantics of PCL's pcl::registration::DefaultConvergenceCriteria as
// IterativeClosestPoint configures it (method.md §3).
#pragma once

#include <cstddef>
#include <limits>
#include <string>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"

namespace lmalign {

/// Why a registration stopped.
enum class TerminationReason {
  kNotTerminated,      ///< still running (never in a returned result)
  kMaxIterations,      ///< PCL CONVERGENCE_CRITERIA_ITERATIONS
  kTransform,          ///< PCL CONVERGENCE_CRITERIA_TRANSFORM: the increment was "small enough"
  kAbsoluteMse,        ///< PCL CONVERGENCE_CRITERIA_ABS_MSE
  kRelativeMse,        ///< PCL CONVERGENCE_CRITERIA_REL_MSE
  kNoCorrespondences,  ///< PCL CONVERGENCE_CRITERIA_NO_CORRESPONDENCES (fewer than the minimum)
  /// Not in PCL: the last iteration's correspondences did not determine the rotation (all points
  /// identical or collinear on the source or target side; see EstimationReport). The estimate
  /// is finite and one of the minimisers, but not unique. Reported instead of the criterion that
  /// stopped the run (docs/robustness.md).
  kDegenerate,
};

/// "max_iterations", "transform", "absolute_mse", "relative_mse", "no_correspondences",
/// "degenerate".
std::string to_string(TerminationReason reason);

/// One ICP iteration, recorded when the run asks for its history (PipelineRequest).
struct IterationRecord {
  int iteration = 0;  ///< 1-based
  std::size_t num_correspondences = 0;
  double mse_m2 = 0.0;  ///< mean squared correspondence distance (PCL's MSE), m^2
  /// Fitness score after this iteration's update (m^2); NaN unless history_scores was set.
  double score_m2 = std::numeric_limits<double>::quiet_NaN();
};

/// PCL's epsilons, with ICP's defaults (the paper's settings).
struct ConvergenceOptions {
  /// PCL setMaximumIterations. >= 1.
  int max_iterations = 150;
  /// PCL setTransformationEpsilon: the increment counts as small when its squared translation is
  /// <= this (m^2) and its rotation passes the rotation test. ICP default 0: only an exact
  /// identity increment fires this criterion.
  double transformation_epsilon_m2 = 0.0;
  /// PCL setTransformationRotationEpsilon, a threshold on cos(angle) of the increment. If <= 0,
  /// PCL uses 1 - transformation_epsilon_m2 (ICP default: 0, so the cosine must be >= 1).
  double transformation_rotation_epsilon_cos = 0.0;
  /// PCL setEuclideanFitnessEpsilon, the relative-MSE criterion. ICP default -DBL_MAX: disabled.
  double euclidean_fitness_epsilon = -std::numeric_limits<double>::max();
  /// DefaultConvergenceCriteria's absolute-MSE threshold (m^2), |mse - previous mse| < this.
  double absolute_mse_epsilon_m2 = 1e-12;
  /// DefaultConvergenceCriteria::setMaximumIterationsSimilarTransforms. PCL default 0.
  int max_iterations_similar_transforms = 0;
  /// Registration's min_number_correspondences_: fewer stops with kNoCorrespondences. >= 3.
  int min_correspondences = 3;

  bool is_valid(std::string* why = nullptr) const;
};

/// The stateful test, called once per iteration after the increment was applied. Mirrors
/// DefaultConvergenceCriteria::hasConverged (PCL 1.12), including the order of the tests:
/// 1. iterations >= max_iterations                       -> kMaxIterations
/// 2. increment cos(angle) >= rotation threshold and
///    |t|^2 <= transformation_epsilon_m2                  -> kTransform
/// 3. |mse - previous mse| < absolute_mse_epsilon_m2     -> kAbsoluteMse
/// 4. |mse - previous mse| / previous mse < relative eps -> kRelativeMse
/// where mse is the mean of the correspondences' squared distances and the previous mse starts at
/// DBL_MAX. Tests 2-4 fire only after max_iterations_similar_transforms similar iterations.
class ConvergenceCriteria {
 public:
  explicit ConvergenceCriteria(const ConvergenceOptions& options);

  /// `iterations`: iterations done so far (>= 1); `increment`: this iteration's transform;
  /// `correspondences`: this iteration's pairs. Returns kNotTerminated to continue.
  TerminationReason check(int iterations, const Isometry3& increment,
                          const Correspondences& correspondences);

  /// Mean squared correspondence distance of the last check (m^2).
  double last_mse_m2() const { return current_mse_; }

 private:
  ConvergenceOptions options_;
  double rotation_threshold_cos_;
  double previous_mse_ = std::numeric_limits<double>::max();
  double current_mse_ = 0.0;
  int similar_iterations_ = 0;
};

/// PCL's calculateMSE: mean of the correspondences' squared distances (m^2). Returns 0 for an
/// empty set (where PCL would divide by zero; the driver stops before that can happen).
double correspondence_mse_m2(const Correspondences& correspondences);

}  // namespace lmalign
