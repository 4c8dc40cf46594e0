// The merged map checked against itself (docs/merge.md, "Maps the graph puts on top of each
// other"): after solve_pose_graph, every pair of maps of one part whose poses make them overlap is
// compared landmark by landmark at the relative pose the graph implies, edge or no edge. This is
// the negative evidence a cycle check cannot see: a group of false edges that agree with each
// other (a look-alike place, the fleet simulator's twins) closes only consistent short cycles, yet
// it lays two different places on top of each other, and there the maps' landmarks disagree.
//
// For maps a and b of one part, with S_world_a and S_world_b from MapPose::similarity() and
// p_b = S_world_b^-1 S_world_a p_a:
//   - a landmark of a lies in b's footprint when b has a landmark within the footprint radius
//     (footprint_spacings times b's median nearest-neighbour spacing, and at least 3 gates);
//   - it agrees when its nearest landmark of b lies within the gate: d^2 <= chi2_3(0.99)
//     (sigma_a^2 + sigma_b^2), each sigma^2 a third of the landmark covariance's trace (a map's
//     median where the covariance is unknown, in world units);
//   - agreement(a, b) = agreeing / in the footprint; the pair's agreement is the lower of both
//     directions, counted when each direction has at least min_landmarks in the footprint.
// The reference is the median agreement of the pairs that a kept edge joins (what right overlaps
// look like in these maps); a pair is contradicted when its agreement is below
// contradiction_ratio times the reference. A part with a contradicted pair holds an edge that
// puts a map in the wrong place.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lmalign/map/map.hpp"
#include "lmalign/merge/edges.hpp"
#include "lmalign/merge/pose_graph.hpp"

namespace lmalign {

struct OverlapCheckOptions {
  /// Run the check (run_merge). Off: OverlapCheck stays empty.
  bool enabled = true;
  /// Footprint radius in target landmark spacings (median nearest-neighbour distance), > 0.
  double footprint_spacings = 3.0;
  /// Landmarks in the footprint, each direction, for a pair to be judged, >= 1.
  std::size_t min_landmarks = 30;
  /// A pair below this fraction of the reference agreement is contradicted, in (0, 1).
  double contradiction_ratio = 0.25;
  /// OpenMP threads over the pairs (0 = OpenMP's default). The result does not depend on it.
  int threads = 0;
  bool is_valid(std::string* why = nullptr) const;
};

/// One judged pair of maps (a < b, indices into the maps), both in `component`.
struct OverlapPair {
  std::size_t a = 0;
  std::size_t b = 0;
  std::size_t component = 0;
  std::size_t in_footprint = 0;  ///< landmarks in the footprint, the smaller direction
  double agreement = 0.0;        ///< in [0, 1], the lower direction
  bool joined_by_edge = false;   ///< a kept edge joins a and b
  bool contradicted = false;
};

struct OverlapCheck {
  bool ran = false;
  /// Median agreement of the edge-joined pairs; 0 when there is none (then nothing is
  /// contradicted).
  double reference_agreement = 0.0;
  std::vector<OverlapPair> pairs;  ///< judged pairs, ordered by (a, b)
  /// Per map: the contradicted pairs it belongs to.
  std::vector<std::size_t> contradicted_per_map;
  /// Per component: its contradicted pairs (0: the part agrees with itself).
  std::vector<std::size_t> contradicted_per_component;
  std::size_t num_contradicted() const;
};

/// Checks the merge `result` of `maps` (their order) against the maps themselves; `edges` and
/// result.edges say which pairs a kept edge joins. Maps are in their own frames and units
/// (MapPose::similarity() takes them to the world). Deterministic for any thread count.
/// Throws InvalidArgument on invalid options or when the sizes differ.
OverlapCheck check_overlaps(const std::vector<Map>& maps, const MergeResult& result,
                            const std::vector<Edge>& edges,
                            const OverlapCheckOptions& options = {});

}  // namespace lmalign
