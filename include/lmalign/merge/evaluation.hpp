// Ground-truth evaluation of a merge (docs/merge.md, "Ground truth").
//
// The merge's parts are the pose graph's connected components. The maps held by priors (every
// part without a gauge map) share the priors' frame; any other part has a frame of its own. Each
// such frame is aligned to the truth by a rigid transform G fitted to its maps that agree with
// the truth: of the fit to all its maps (chordal rotation mean of R_true R_est^T, then mean
// translation) and each map's own G_k = T_true_k T_est_k^-1, the one that puts the most maps
// within the thresholds wins, refitted to those maps when that keeps as many; so one misplaced
// map (or one wrong prior) does not move the others' errors. A map alone in a part without
// priors has no error to measure (NaN). Per map, the error of G * T_world_map_est against
// T_world_map_true (transform_error, core/geometry.hpp).
// A map is placed when the merge puts it in the frame of the others: in a part held by priors,
// or, without priors, in the largest part (the first of equal ones) when that part joins at
// least two maps. A map alone in its part, or in a smaller part, is not placed, whatever its
// error within that part. An edge is true when its similarity agrees with
// S_world_target_true^-1 * S_world_source_true within the thresholds.
// With maps without metric scale (Sim(3) merges) the truths are similarities, G is one too,
// and the scale errors are reported beside the rotation and translation errors.
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
  /// Relative scale error |s_est / s_true - 1| (maps without metric scale; 0 for rigid ones).
  double scale = 0.01;
};

struct MapError {
  /// Error of the map's pose, its part aligned to the truth (NaN: alone in a part without
  /// priors, so nothing to measure).
  double rotation_deg = 0.0;
  double translation_m = 0.0;
  /// |g s_est / s_true - 1| with g the part's own scale fitted to the truth (0 for maps with
  /// metric scale in a rigid merge; NaN as above).
  double scale_error = 0.0;
  bool connected = false;  ///< a kept edge joins it to at least one other map
  bool placed = false;     ///< in the frame of the others (see the file comment)
  bool within = false;     ///< placed and its error within the thresholds
};

struct MergeEvaluation {
  std::vector<MapError> maps;
  /// The pose graph's components (maps in one frame; priors join every map that has one).
  std::size_t num_parts = 0;
  /// Connected components of the kept edges alone (what the alignments joined).
  std::size_t num_edge_parts = 0;
  std::size_t largest_part = 0;  ///< maps in the largest part
  std::size_t placed = 0;        ///< maps placed
  /// Maps placed and within the thresholds / all maps.
  double fraction_within = 0.0;
  /// Of all pairs of maps, those whose estimated relative pose T_world_i^-1 T_world_j agrees
  /// with the truth's within the thresholds; a pair in two parts without a common frame (not
  /// both held by priors) does not. NaN above 2,000 maps (not computed: 2 million pairs).
  double pair_fraction_within = 0.0;
  std::size_t pairs_within = 0;
  /// Largest errors over the maps with an error (NaN ones left out).
  double max_rotation_deg = 0.0;
  double max_translation_m = 0.0;
  double max_scale_error = 0.0;
  /// Largest relative scale error of the pairs compared (s_i^-1 s_j against the truth's).
  double max_pair_scale_error = 0.0;
  /// Edges kept by the graph (used, not rejected) that are true / all kept; 1 when none kept.
  double edge_precision = 1.0;
  /// Kept true edges / candidate edges whose alignment is true (trusted or not; an untrusted
  /// edge that was right counts as missed).
  double edge_recall = 1.0;
  std::size_t kept_edges = 0;
  std::size_t false_kept_edges = 0;
  std::vector<bool> edge_true;  ///< per edge
};

/// Reads a ground-truth file: YAML `maps: {name: [[4x4 rows]], ...}` (S_world_map, world units:
/// a rigid transform, or a similarity [sR t; 0 0 0 1] for a map without metric scale, s = world
/// units per map unit), one entry per name in `names`. Throws ParseError naming the file, line
/// and map ("maps.<name>: scale ... expected finite and > 0" for a 3x3 block of non-positive
/// or non-finite determinant; "not a rigid transform nor a similarity").
std::vector<Similarity3> read_ground_truth_similarities(const std::string& path,
                                                        const std::vector<std::string>& names);
/// The same, rigid transforms only (T_world_map, metres): a similarity is refused as above.
std::vector<Isometry3> read_ground_truth(const std::string& path,
                                         const std::vector<std::string>& names);

/// Evaluates `result` against `truth` (S_world_map_true per map). Each part is aligned to the
/// truth by a similarity G (its scale g = the geometric mean of s_true / s_est over the fitted
/// maps; 1 in a rigid merge); scale errors are |g s_est / s_true - 1| per map and
/// |s_rel_est / s_rel_true - 1| per pair and edge. Throws InvalidArgument if sizes do not match.
MergeEvaluation evaluate_merge(const MergeResult& result, const std::vector<Edge>& edges,
                               const std::vector<Similarity3>& truth,
                               const GroundTruthThresholds& thresholds = {});
/// The same with rigid truths (scale 1).
MergeEvaluation evaluate_merge(const MergeResult& result, const std::vector<Edge>& edges,
                               const std::vector<Isometry3>& truth,
                               const GroundTruthThresholds& thresholds = {});

}  // namespace lmalign
