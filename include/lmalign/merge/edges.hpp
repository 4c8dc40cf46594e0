// Edges of the merge (docs/merge.md, "Edges"): one alignment per candidate pair with align()
// (registration/presets.hpp) and the recommended default, kept with its trust verdict and 6x6
// covariance. align_edge() is a pure, deterministic function of its inputs (any thread count:
// the engine is), so that pairs can run anywhere (OpenMP here; a Dask worker) and their results
// be cached by edge_key(), which hashes every setting of the pipeline that ran.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/merge/candidates.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/scale_search.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

/// One aligned pair.
struct Edge {
  std::size_t source = 0;  ///< map index
  std::size_t target = 0;  ///< map index
  /// p_target = scale * R * p_source + t with (R, t) = T_target_source (target units: metres
  /// for a map with metric scale).
  Isometry3 T_target_source = Isometry3::Identity();
  /// uncertainty.hpp's convention (left perturbation in the target frame, (rho m, phi rad)).
  Mat6 covariance = Mat6::Zero();
  bool covariance_valid = false;
  /// Whether the alignment estimated the scale (Sim(3); AlignRequest::scale resolved for the
  /// two maps). False: a rigid edge, scale exactly 1.
  bool scale_free = false;
  /// Target units per source unit (1 for a rigid edge).
  double scale = 1.0;
  /// Its standard deviation (same units); NaN when fixed or not determined.
  double scale_sd = std::numeric_limits<double>::quiet_NaN();
  /// The 7x7 covariance of (rho [target units], phi [rad], log scale) at the target origin
  /// (ScaleEstimate::covariance_7x7); nullopt for a rigid edge or when the alignment had none.
  std::optional<Mat7> covariance_7x7;
  /// The preset's verdict.
  bool trusted = false;
  std::string trust_reason;
  std::size_t num_inliers = 0;
  double inlier_ratio = 0.0;
  std::string initialisation;  ///< the initialiser's ("global", "prior", "given", ...)
  /// The alignment's Summary as JSON (to_json, pipeline.hpp): what the edge file keeps of it.
  std::string summary_json;
  /// edge_key() of its inputs (for the resume cache).
  std::string key;
};

struct EdgeOptions {
  /// The preset (a name, or a preset file); empty: the recommended default. A pair's prior is
  /// passed only to presets whose initialiser uses one (the others get the guess alone).
  std::string strategy;
  /// AlignRequest::max_iterations (empty: the preset's own).
  std::optional<int> max_iterations;
  /// Settings by key (AlignRequest::settings).
  std::vector<std::pair<std::string, SettingValue>> settings;
  /// AlignRequest::scale for every pair: kAuto estimates the scale of a pair where either map
  /// has no metric scale (CandidatePair::source_metric / target_metric), kFree always, kFixed
  /// never (rigid edges).
  ScaleMode scale = ScaleMode::kAuto;
  bool is_valid(std::string* why = nullptr) const;
};

/// Aligns source onto target for `pair` with align() (its relative prior, if any, bounds the
/// search around its initial guess). `source` and `target` are the maps of pair.source and
/// pair.target. Throws what align() throws (InvalidArgument).
Edge align_edge(const SourceLandmarks& source, const PreparedTarget& target,
                const CandidatePair& pair, const EdgeOptions& options = {});

/// The source of a map as align_edge() takes it (positions, covariances, up axis).
SourceLandmarks edge_source(const Map& map);

/// Same, from the two maps (builds the PreparedTarget; the overload above lets a caller prepare
/// each target once).
Edge align_edge(const Map& source, const Map& target, const CandidatePair& pair,
                const EdgeOptions& options = {});

/// A 64-bit FNV-1a hash of a map's landmark positions and covariances (bit patterns), as 16 hex
/// digits.
std::string map_fingerprint(const Map& map);

/// The cache key of an edge: hex hash of both maps' fingerprints, the pair (indices, guess,
/// prior, the maps' metric and assumed-covariance flags), the scale mode, the preset and every
/// setting of the pipeline that runs (Settings::canonical_text), plus a format version. Throws
/// InvalidArgument for an unknown preset or setting.
std::string edge_key(const std::string& source_fingerprint, const std::string& target_fingerprint,
                     const CandidatePair& pair, const EdgeOptions& options);

}  // namespace lmalign
