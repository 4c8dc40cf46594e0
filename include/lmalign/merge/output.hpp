// Outputs of a merge (docs/merge.md, "Outputs"), every file written atomically
// (io/output_file.hpp):
//   poses.yaml, poses.json   per map: name, component, gauge flag, T_world_map (4x4 rows),
//                            6x6 covariance (uncertainty.hpp's convention, world frame);
//                            poses.json also the map's landmark centre in the world frame
//                            (coordinate-wise median, m; null without landmarks) and the range
//                            [begin, end) of the landmark ids its component's merged map gives
//                            the landmarks it added (for the plots, scripts/plot_merge.py)
//   edges.csv                one row per candidate edge
//   summary.json             counts, final chi^2, the edge covariance scale, rejected edges,
//                            the maps alone in their part and why, maps of the same landmarks
//                            (map_notes), the folds the merge could not rule out
//                            (suspected_folds, folds.hpp), the overlap check's counts
//                            (overlap_check.hpp)
//   overlap_check.csv        with the check: one row per judged pair of maps
//   merged_map.txt           (one component) or merged_map_component<k>.txt (one per
//                            component, each in its own frame): every map's frames and
//                            landmarks moved into the world frame (covariances rotated), frames
//                            and landmarks renumbered in map order; with fusion, landmarks of
//                            maps of the same session sharing an id are one landmark
//                            (information-weighted mean, summed information; observations
//                            concatenated)
//   edges/<source>__<target>.json   one per aligned edge (the resume cache), written as each
//                            edge finishes (write_edge_file)
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/map/map.hpp"
#include "lmalign/merge/edges.hpp"
#include "lmalign/merge/overlap_check.hpp"
#include "lmalign/merge/pose_graph.hpp"

namespace lmalign {

struct MergeOutputOptions {
  /// Fuse landmarks of one session with the same id (maps without a session never fuse).
  bool fuse_landmarks = true;
};

/// The merged map of component `component`: maps of that component moved by their T_world_map
/// (transform_map), renumbered (frame ids 0.., landmark ids 0.. in map order; fused landmarks
/// keep the first occurrence's place). `sessions[i]` is map i's session ("" = none). If
/// `landmark_ranges` is given, it is resized to maps.size() and (*landmark_ranges)[i] is the range
/// [begin, end) of the merged landmark ids that map i added ({0, 0} for a map of another
/// component; a fused landmark belongs to the map that added it first). Landmarks beyond the
/// supported range (core/supported_range.hpp), which no edge aligned, are left out; `left_out`,
/// if given, receives their number. Maps without metric scale are moved by their similarity
/// (MapPose::similarity(), covariances times s^2). The header: metric when a map of the
/// component is metric or priors hold the component, else arbitrary (the gauge map's units);
/// covariances assumed when any map's are.
/// Throws InvalidArgument if sizes do not match.
Map merge_maps(const std::vector<Map>& maps, const std::vector<std::string>& sessions,
               const MergeResult& result, std::size_t component,
               const MergeOutputOptions& options = {},
               std::vector<std::pair<std::size_t, std::size_t>>* landmark_ranges = nullptr,
               std::size_t* left_out = nullptr);

/// What the report says of one map beside its pose (docs/merge.md, "Why a map stands alone").
struct MapNote {
  /// Why the map is alone in its part; empty when its part holds other maps. One of: "no
  /// candidate pair" (neither retrieval nor the priors paired it); "none of its N pairs was
  /// trusted (K: REASON; ...)", the edges' trust reasons by how often they occur; "its trusted
  /// pairs did not enter the graph or were rejected by it (REASON)".
  std::string alone;
  /// An earlier map (index) with exactly the same landmarks (map_fingerprint: positions and
  /// covariances, bit for bit): a map listed twice, or one map in two files. Reported only;
  /// their edge is aligned like any other.
  std::optional<std::size_t> same_landmarks_as;
};

/// One note per map, from the maps, the candidate edges and their fate in the graph (sizes as
/// write_merge_outputs). Throws InvalidArgument if sizes do not match.
std::vector<MapNote> map_notes(const std::vector<Map>& maps, const std::vector<Edge>& edges,
                               const MergeResult& result);

/// Writes poses.yaml, poses.json, edges.csv, summary.json and the merged map(s) into `out_dir`
/// (created if missing). `names[i]` names map i. With `overlaps` (the check ran): also
/// overlap_check.csv, summary.json's "overlap_check" and each map's "contradicted_pairs" in
/// poses.json (else null). Throws IoError / InvalidArgument.
void write_merge_outputs(const std::string& out_dir, const std::vector<std::string>& names,
                         const std::vector<std::string>& sessions, const std::vector<Map>& maps,
                         const std::vector<Edge>& edges, const MergeResult& result,
                         const MergeOutputOptions& options = {},
                         const OverlapCheck* overlaps = nullptr);

/// The cache file of an edge: <dir>/<name_source>__<name_target>.json.
std::string edge_file_path(const std::string& dir, const std::string& source_name,
                           const std::string& target_name);
/// Writes one edge atomically (JSON; doubles round-trip exactly).
void write_edge_file(const std::string& path, const Edge& edge);
/// Reads an edge file. Returns nullopt if it does not exist; throws ParseError naming the file
/// if it is malformed.
std::optional<Edge> read_edge_file(const std::string& path);

}  // namespace lmalign
