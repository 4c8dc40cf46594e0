// What every registration shares: the target as every preset reads it (PreparedTarget: its
// kd-tree, its confidence weights, its covariances, its up axis) and the result of a refinement
// (RegistrationResult). The paper's ICP (method.md §3, mirroring PCL's
// IterativeClosestPoint::computeTransformation) is a preset of the engine (pipeline.hpp;
// configs/presets/base.yaml and the other three), run by align() of presets.hpp.
//
// Frames: the result is T_target_source, p_target = T_target_source * p_source.
#pragma once

#include <cstddef>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/supported_range.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/registration/convergence.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/search/kdtree.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign {

/// What a registration returns (after small_gicp's RegistrationResult and Ceres' Summary).
struct RegistrationResult {
  /// The estimate, p_target = T_target_source * p_source. Always finite.
  Isometry3 T_target_source = Isometry3::Identity();
  /// True when a convergence criterion (transform, absolute or relative MSE) stopped the run.
  /// Unlike PCL's hasConverged(), reaching max_iterations is reported as not converged.
  bool converged = false;
  TerminationReason termination = TerminationReason::kNotTerminated;
  int iterations = 0;
  /// Correspondences used in the last iteration.
  std::size_t num_correspondences = 0;
  /// Fitness score (method.md §4) of the initial guess and of the final estimate, m^2.
  double initial_score_m2 = std::numeric_limits<double>::infinity();
  double final_score_m2 = std::numeric_limits<double>::infinity();
  std::vector<IterationRecord> history;
  /// Wall time of the alignment (not of target preparation), seconds.
  double wall_time_s = 0.0;

  /// One line: termination, iterations, scores, time.
  std::string brief_report() const;
};

/// A target prepared once for many alignments: the kd-tree and each kind of confidence weight.
class PreparedTarget {
 public:
  /// From a map: builds the kd-tree over the landmark positions, computes all four weights and
  /// keeps the landmark covariances (for the point-to-distribution cost) and viewing directions.
  /// Throws InvalidArgument if the map is invalid (see Map::validate()).
  explicit PreparedTarget(const Map& target, const WeightOptions& weight_options = {});
  /// From bare points: only uniform weights until set_weights() provides others, and no
  /// covariances until set_covariances() provides them.
  explicit PreparedTarget(Points3 points);

  /// Sets the weights used for `kind` (one per point, finite, >= 0). Throws InvalidArgument.
  void set_weights(WeightKind kind, std::vector<double> weights);
  /// Throws InvalidArgument if no weights of that kind are available.
  const std::vector<double>& weights(WeightKind kind) const;

  /// Sets the landmark position covariances (one 3x3 per point, m^2, target frame, finite).
  /// Throws InvalidArgument.
  void set_covariances(std::vector<Mat3> covariances_m2);
  bool has_covariances() const { return !covariances_.empty() || tree_.size() == 0; }
  /// One 3x3 position covariance per point (m^2, target frame). Throws InvalidArgument if the
  /// target has none (built from bare points without set_covariances()).
  const std::vector<Mat3>& covariances_m2() const;

  /// The target's up axis (unit, target frame): from the map's frames (estimate_up_axis(),
  /// registration/stages/data_scales.hpp) when built from a Map, else none until set_up_axis().
  const std::optional<Vec3>& up_axis() const { return up_axis_; }
  /// Sets it (normalised); nullopt clears it. Throws InvalidArgument for a zero or non-finite axis.
  void set_up_axis(std::optional<Vec3> up);

  /// Each landmark's unit mean viewing direction (target frame, zero where unknown;
  /// Map::view_directions()), or empty: none (built from bare points). Read by the Mahalanobis
  /// gate's viewing-direction test.
  const std::vector<Vec3>& view_directions() const { return view_directions_; }
  /// Sets them: one per point, each unit or zero, or empty for none. Throws InvalidArgument.
  void set_view_directions(std::vector<Vec3> directions);

  const KdTree& tree() const { return tree_; }
  const Points3& points() const { return tree_.points(); }
  std::size_t size() const { return tree_.size(); }

 private:
  KdTree tree_;
  std::map<WeightKind, std::vector<double>> weights_;
  std::vector<Mat3> covariances_;
  std::optional<Vec3> up_axis_;
  std::vector<Vec3> view_directions_;
};

}  // namespace lmalign
