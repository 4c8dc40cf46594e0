// The merge manifest (docs/merge.md, "Manifest"): the mini-maps to merge, each with an optional
// prior pose T_world_map and its uncertainty.
//
//   maps:
//     - name: robot1_a            # unique
//       path: maps/r1_a.txt       # relative to the manifest's folder (or absolute)
//       format: auto              # optional: auto, lmalign, colmap-text, ... (formats.hpp)
//       session: robot1           # optional: landmarks with the same id in one session are
//                                 # the same landmark (fused on output, docs/merge.md)
//       T_world_map: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]   # optional prior, 4x4 rows
//                                 # (a similarity [sR t; 0 1] gives the scale of a map
//                                 # without metric scale: world units per map unit)
//       prior_sigma: [2.0, 0.5]   # rotation deg, translation m (or `prior_covariance`, 6x6)
//
// Prior covariance convention (registration/uncertainty.hpp): left perturbation in the world
// frame, T_world_map = Exp(xi) * T_prior, xi = (rho m, phi rad); rows 0-2 translation (m^2),
// 3-5 rotation (rad^2). `prior_sigma: [r, t]` means diag(t^2, t^2, t^2, r^2, r^2, r^2) with r in
// radians.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/map.hpp"

namespace lmalign {

/// A prior pose of a map in the common world frame.
struct MapPrior {
  Isometry3 T_world_map = Isometry3::Identity();
  /// 6x6, symmetric positive definite (see the file comment).
  Mat6 covariance = Mat6::Identity();
  /// World units per map unit (a similarity T_world_map [sR t; 0 1] in the manifest): holds the
  /// scale of a map without metric scale (pose_graph.hpp); finite and > 0. A map with metric
  /// scale keeps scale 1 whatever its prior says.
  double scale = 1.0;
};

/// One mini-map of the manifest.
struct ManifestEntry {
  std::string name;
  /// Resolved path (relative paths are joined to the manifest's folder).
  std::string path;
  MapFormat format = MapFormat::kAuto;
  /// Empty: none (landmark ids are then never fused with another map's).
  std::string session;
  std::optional<MapPrior> prior;
};

struct Manifest {
  std::string file;  ///< where it was read from (for messages)
  std::vector<ManifestEntry> maps;
};

/// Throws InvalidArgument("<what>.T_world_map: translation ... beyond the supported range", or
/// "<what>.covariance[i][i]: standard deviation ... beyond the supported range") unless the
/// prior's translation and standard deviations are within the supported range
/// (core/supported_range.hpp: 1e15 m; rotation 1e15 degrees) and finite, and its scale is
/// finite and > 0 ("<what>.scale: ..."). parse_manifest() checks
/// each field so (naming its line); plan_candidates() and solve_pose_graph() check every prior
/// they are given.
void check_prior_in_supported_range(const MapPrior& prior, const std::string& what);

/// Parses manifest text. `name` is used in messages; relative map paths are joined to
/// `base_dir`. Throws ParseError("<name>:<line>: <field>: <what was expected>") for a YAML
/// syntax error, a missing or mistyped field, an unknown key, a duplicate map name, a prior
/// that is neither a rigid transform (rotation orthonormal to 1e-6, det +1, last row 0 0 0 1)
/// nor a similarity [sR t; 0 0 0 1] with a scale s finite and > 0, a
/// covariance that is not symmetric (to 1e-9 relative) positive definite, prior_sigma values
/// that are not finite and > 0, both prior_sigma and prior_covariance, a sigma without a
/// T_world_map, or an empty `maps` list.
Manifest parse_manifest(const std::string& yaml_text, const std::string& name,
                        const std::string& base_dir);

/// Reads and parses a manifest file. Throws IoError if it cannot be read, else as above.
Manifest read_manifest(const std::string& path);

/// Reads every map of the manifest (read_any_map with its format and default options). Throws
/// IoError / ParseError naming the map's file ("map 'robot1_a': <reader's message>").
std::vector<Map> load_manifest_maps(const Manifest& manifest);

}  // namespace lmalign
