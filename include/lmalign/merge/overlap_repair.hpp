// The merge repaired by its own overlap check (docs/merge.md, "Maps the graph puts on top of each
// other"): when check_overlaps (overlap_check.hpp) finds a part that contradicts itself, the edges
// that fold it are found and dropped.
//
// A fold is a group of edges that agree with each other and with their short cycles, but lay one
// place on another (the fleet simulator's twins: a turned copy of a place). The cycle check keeps
// such a group when its edges have the most inliers, and rejects the true edges that disagree
// with it; the overlap check then sees the folded places disagree.
//
// Each round:
//   1. a spanning tree of the kept edges, by decreasing inliers (ties: edge order);
//   2. each tree edge counts the contradicted pairs whose tree path crosses it;
//   3. for the trials_per_round tree edges crossed most (ties: edge order), the cut of the tree
//      at that edge: the kept edges from one side to the other (the tree edge's group, the edges
//      that agree with where it puts the other side). The graph is solved again without the group,
//      which lets the cycle check take back the edges the group had outvoted, and checked again;
//   4. the trial with the fewest contradicted pairs is kept when it has fewer than before, as
//      many parts or fewer, and a largest part at least as large (dropping a group may not
//      resolve a contradiction by cutting the maps apart).
// It stops when nothing is contradicted, no trial helps, or after max_rounds. A group may hold
// edges that agree with the repaired part as well (a true edge between two maps of the folded
// side): last, each dropped edge is tried again, in the order dropped, and taken back when the
// graph keeps it and it adds no contradicted pair, no part, and leaves the largest part as large.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/map/map.hpp"
#include "lmalign/merge/edges.hpp"
#include "lmalign/merge/overlap_check.hpp"
#include "lmalign/merge/pose_graph.hpp"

namespace lmalign {

struct OverlapRepairOptions {
  bool enabled = true;
  int max_rounds = 16;       ///< >= 1
  int trials_per_round = 8;  ///< tree edges tried per round, >= 1
  bool is_valid(std::string* why = nullptr) const;
};

struct OverlapRepair {
  std::size_t contradicted_before = 0;
  int rounds = 0;
  int trials = 0;
  /// Edges dropped (indices into the edges), in the order dropped.
  std::vector<std::size_t> dropped;
};

/// Repairs `result` and `check` in place (see the file comment) for the merge of `maps` with
/// `priors`, `edges`, `graph` and `scale_free` as given to solve_pose_graph, and `overlaps` as
/// given to check_overlaps. A dropped edge is reported used and rejected, with the reason in
/// EdgeReport::reject_reason. Deterministic for any thread count. Throws InvalidArgument on
/// invalid options or sizes (as solve_pose_graph and check_overlaps).
OverlapRepair repair_overlaps(const std::vector<Map>& maps,
                              const std::vector<std::optional<MapPrior>>& priors,
                              const std::vector<Edge>& edges, const PoseGraphOptions& graph,
                              const std::vector<bool>& scale_free,
                              const OverlapCheckOptions& overlaps,
                              const OverlapRepairOptions& options, MergeResult* result,
                              OverlapCheck* check);

}  // namespace lmalign
