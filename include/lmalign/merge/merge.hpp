// A whole merge in one call (docs/merge.md): the CLI's `lmalign merge` runs it. It is the
// composition of the pure steps, each usable alone (e.g. to run the edges elsewhere):
//   summarise_map + plan_candidates (candidates.hpp) -> align_edge per pair (edges.hpp, in
//   parallel with OpenMP, one slot per pair: the same result for any thread count) ->
//   solve_pose_graph (pose_graph.hpp) -> write_merge_outputs (output.hpp).
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
#include "lmalign/merge/pose_graph.hpp"

namespace lmalign {

struct MergeOptions {
  CandidateOptions candidates;
  EdgeOptions edges;
  PoseGraphOptions graph;
  /// OpenMP threads over the pairs (0 = OpenMP's default). The result does not depend on it.
  int threads = 0;
  /// When not empty: each finished edge is written there (write_edge_file) as it finishes, and
  /// an edge whose file holds the same edge_key() is read instead of aligned (resume).
  std::string edge_cache_dir;
  bool is_valid(std::string* why = nullptr) const;
};

/// Which maps get a scale of their own in the pose graph (solve_pose_graph's scale_free): those
/// without metric scale (MapHeader::scale not kMetric), none when `mode` is kFixed.
std::vector<bool> scale_free_maps(const std::vector<Map>& maps, ScaleMode mode);

/// Progress: (stage "edges" / "graph", done, total). Called from one thread at a time.
using MergeProgress =
    std::function<void(const std::string& stage, std::size_t done, std::size_t total)>;

struct MergeRun {
  std::vector<CandidatePair> candidates;
  std::vector<Edge> edges;  ///< one per candidate, same order (only the finished if cancelled)
  MergeResult result;       ///< empty if cancelled
  std::size_t edges_reused = 0;
  bool cancelled = false;
  double seconds_edges = 0.0;
  double seconds_graph = 0.0;
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
