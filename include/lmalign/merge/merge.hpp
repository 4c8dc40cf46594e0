// A whole merge in one call (docs/merge.md): the CLI's `lmalign merge` runs it. It is the
// composition of the pure steps, each usable alone (e.g. to run the edges elsewhere):
//   summarise_map + plan_candidates (candidates.hpp) -> align_edge per pair (edges.hpp, in
//   parallel with OpenMP, one slot per pair: the same result for any thread count) ->
//   solve_pose_graph (pose_graph.hpp) -> check_overlaps (overlap_check.hpp) -> when it
//   contradicts a part, repair_overlaps (overlap_repair.hpp) -> write_merge_outputs (output.hpp).
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "lmalign/map/map.hpp"
#include "lmalign/merge/candidates.hpp"
#include "lmalign/merge/edges.hpp"
#include "lmalign/merge/manifest.hpp"
#include "lmalign/merge/overlap_check.hpp"
#include "lmalign/merge/overlap_repair.hpp"
#include "lmalign/merge/pose_graph.hpp"

namespace lmalign {

struct MergeOptions {
  CandidateOptions candidates;
  EdgeOptions edges;
  PoseGraphOptions graph;
  /// The merged map checked against itself after the graph (overlap_check.hpp).
  OverlapCheckOptions overlaps;
  /// A part the check contradicts is repaired by dropping the edges that fold it
  /// (overlap_repair.hpp); only when the check runs.
  OverlapRepairOptions repair;
  /// OpenMP threads over the pairs (0 = OpenMP's default). The result does not depend on it.
  int threads = 0;
  /// When not empty: each finished edge is written there (write_edge_file) as it finishes, and
  /// an edge whose file holds the same edge_key() is read instead of aligned (resume).
  std::string edge_cache_dir;
  bool is_valid(std::string* why = nullptr) const;
};

/// Sets options->overlaps.enabled and options->repair.enabled from the name of an overlap-check
/// mode, as `lmalign merge --overlap-check` and Python's merge(overlap_check=) take it:
/// "repair" (the check, and the repair of a part it contradicts), "check" (the check alone) or
/// "off" (neither). Throws InvalidArgument "overlap_check: expected 'repair', 'check' or 'off',
/// got 'NAME'".
void set_overlap_check_mode(const std::string& mode, MergeOptions* options);

/// Which maps get a scale of their own in the pose graph (solve_pose_graph's scale_free): those
/// without metric scale (MapHeader::scale not kMetric), none when `mode` is kFixed.
std::vector<bool> scale_free_maps(const std::vector<Map>& maps, ScaleMode mode);

/// The graph step of run_merge, once the edges are aligned: solve_pose_graph (maps without
/// metric scale as scale_free_maps says), then, with options.overlaps enabled, check_overlaps,
/// and repair_overlaps when the check contradicts a part (options.repair). The Dask backend calls
/// it too, so both give the same poses. Throws InvalidArgument (options, sizes).
struct MergeGraph {
  MergeResult result;
  OverlapCheck overlaps;
  OverlapRepair repair;
  double seconds_check = 0.0;  ///< the check and the repair
};
MergeGraph solve_and_check(const std::vector<Map>& maps,
                           const std::vector<std::optional<MapPrior>>& priors,
                           const std::vector<Edge>& edges, const MergeOptions& options);

/// Progress: (stage "edges" / "graph", done, total). Called from one thread at a time.
using MergeProgress =
    std::function<void(const std::string& stage, std::size_t done, std::size_t total)>;

struct MergeRun {
  std::vector<CandidatePair> candidates;
  std::vector<Edge> edges;  ///< one per candidate, same order (only the finished if cancelled)
  MergeResult result;       ///< empty if cancelled
  /// The merged map checked against itself (overlap_check.hpp); not ran if cancelled or
  /// MergeOptions::overlaps is disabled.
  OverlapCheck overlaps;
  /// What the repair dropped (overlap_repair.hpp); the check above is after it.
  OverlapRepair repair;
  std::size_t edges_reused = 0;
  bool cancelled = false;
  double seconds_edges = 0.0;
  double seconds_graph = 0.0;
  double seconds_check = 0.0;
};

/// Runs the merge of `maps` (priors from `priors`, one per map). A map without metric scale
/// (MapHeader::scale not kMetric) gets a scale of its own in the pose graph (Sim(3)) unless
/// options.edges.scale is kFixed; its pairs are aligned with the scale free (kAuto). With `cancel`
/// set (e.g. by a SIGINT handler), no new edge is started; finished edges are in the cache; returns
/// cancelled. Throws InvalidArgument on invalid options or sizes, IoError on the cache. An
/// exception thrown while the edges are aligned in parallel (by an edge or by `progress`) stops the
/// remaining edges and reaches the caller: std::bad_alloc as itself, other std::exceptions as
/// InvalidArgument("merge: an edge failed: <what>"), any other type as itself.
MergeRun run_merge(const std::vector<Map>& maps, const std::vector<std::string>& names,
                   const std::vector<std::optional<MapPrior>>& priors, const MergeOptions& options,
                   const MergeProgress& progress = {}, const std::atomic<bool>* cancel = nullptr);

}  // namespace lmalign
