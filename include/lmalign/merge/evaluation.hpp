// Ground-truth evaluation of a merge (docs/merge.md, "Ground truth").
//
// A component held by priors is aligned to the truth frame by the rigid transform G that best
// fits all its maps (chordal rotation mean of R_true R_est^T, then mean translation). Any other
// component's frame is arbitrary: it is aligned by a G fitted to the maps that agree with the
// truth. Of the fit to all its maps and each map's own G_k = T_true_k T_est_k^-1, the one that
// puts the most maps within the thresholds wins, refitted to those maps when that keeps as many;
// so one misplaced map does not move the others' errors. Per map, the error of
// G * T_world_map_est against T_world_map_true (transform_error, core/geometry.hpp). An edge is
// true when its T_target_source agrees with T_world_target_true^-1 * T_world_source_true within
// the thresholds.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/merge/edges.hpp"
#include "lmalign/merge/pose_graph.hpp"

namespace lmalign {

struct GroundTruthThresholds {
  double rotation_deg = 5.0;  ///< indoors 5 deg / 10 cm, outdoors 5 deg / 1 m
  double translation_m = 0.10;
};

struct MapError {
  double rotation_deg = 0.0;
  double translation_m = 0.0;
  bool within = false;
};

struct MergeEvaluation {
  std::vector<MapError> maps;
  double fraction_within = 0.0;
  double max_rotation_deg = 0.0;
  double max_translation_m = 0.0;
  /// Edges kept by the graph (used, not rejected) that are true / all kept; 1 when none kept.
  double edge_precision = 1.0;
  /// Kept true edges / candidate edges whose alignment is true (trusted or not; an untrusted
  /// edge that was right counts as missed).
  double edge_recall = 1.0;
  std::size_t kept_edges = 0;
  std::size_t false_kept_edges = 0;
  std::vector<bool> edge_true;  ///< per edge
};

/// Reads a ground-truth file: YAML `maps: {name: [[4x4 rows]], ...}` (T_world_map, metres),
/// one entry per name in `names`. Throws ParseError naming the file, line and map.
std::vector<Isometry3> read_ground_truth(const std::string& path,
                                         const std::vector<std::string>& names);

/// Evaluates `result` against `truth` (T_world_map_true per map). Throws InvalidArgument if sizes
/// do not match.
MergeEvaluation evaluate_merge(const MergeResult& result, const std::vector<Edge>& edges,
                               const std::vector<Isometry3>& truth,
                               const GroundTruthThresholds& thresholds = {});

}  // namespace lmalign
