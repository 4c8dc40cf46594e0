// Folds a merge could not rule out (docs/merge.md, "Folds the merge reports"): trusted edges that
// the graph rejected, several of which ask for one and the same motion of part of the world.
//
// A look-alike place (the fleet simulator's twins: a turned copy of another place) gives many
// trusted edges between the two places' maps, all agreeing with each other. When they outweigh
// the true edges that tie one place to its surroundings, the graph keeps them and places that
// place's maps onto the other: a fold. The true edges at the fold's border are then rejected,
// and each asks for the same motion W of the world: the fold undone. One rejected edge is an
// outlier; two or more that agree on one motion are a second placement of part of the merge,
// supported by trusted edges. The merge cannot tell which placement is right (both are
// consistent with their own edges; docs/merge.md, "Why the look-alikes win on the fleet"), so
// it reports the fold and changes nothing.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lmalign/core/similarity.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/merge/edges.hpp"
#include "lmalign/merge/pose_graph.hpp"

namespace lmalign {

struct FoldOptions {
  /// Rejected edges that agree on one motion, at least this many (>= 2).
  std::size_t min_edges = 2;
  /// Two motions agree when they differ by less than this fraction of the moved map's extent
  /// (the median distance of its landmarks from their centroid), in (0, 1]: the difference's
  /// displacement of the map's centre plus its angle (rad) times the extent, plus |log scale|
  /// times the extent.
  double tolerance = 0.1;
  bool is_valid(std::string* why = nullptr) const;
};

struct SuspectedFold {
  /// The rejected edges that agree (indices into the edges), by decreasing inliers (ties: edge
  /// order). Each was trusted, entered the graph, and was rejected by it (the cycle check, the
  /// chi^2 after optimisation or the overlap repair), with both maps in one part.
  std::vector<std::size_t> edges;
  /// Their maps, ascending.
  std::vector<std::size_t> maps;
  /// The motion the first edge asks for, world frame (world units): the first edge's source
  /// placed where that edge puts it is S_world_moved times where the graph put it.
  Similarity3 S_world_moved;
  /// How far that motion moves the first edge's source map's centre (world units), and its
  /// rotation angle (deg).
  double motion_m = 0.0;
  double motion_deg = 0.0;
};

/// The folds of `result` (solve_pose_graph's, after any overlap repair) for `maps` and `edges`
/// (the merge's): clusters of rejected trusted edges by the world motion each asks for, greedily
/// by decreasing inliers, a motion W and its inverse counting as one (which end moves depends on
/// the edge's direction). Clusters of at least options.min_edges, by decreasing edge count (ties:
/// the first edge's order). A map without landmarks has extent 0: only its centre's displacement
/// counts. Deterministic; reports only. Throws InvalidArgument on invalid options or sizes that
/// do not match.
std::vector<SuspectedFold> suspected_folds(const std::vector<Map>& maps,
                                           const std::vector<Edge>& edges,
                                           const MergeResult& result,
                                           const FoldOptions& options = {});

}  // namespace lmalign
