// Edges of the merge (docs/merge.md, "Edges"): one alignment per candidate pair with
// run_strategy() and the recommended default (adaptive), kept with its trust verdict and 6x6
// covariance. align_edge() is a pure, deterministic function of its inputs (any thread count:
// the adaptive pipeline is), so that pairs can run anywhere (OpenMP here; a Dask worker later)
// and their results be cached by edge_key().
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/merge/candidates.hpp"
#include "lmalign/registration/adaptive.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/strategy.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

/// One aligned pair.
struct Edge {
  std::size_t source = 0;  ///< map index
  std::size_t target = 0;  ///< map index
  /// p_target = T_target_source * p_source (metres).
  Isometry3 T_target_source = Isometry3::Identity();
  /// uncertainty.hpp's convention (left perturbation in the target frame, (rho m, phi rad)).
  Mat6 covariance = Mat6::Zero();
  bool covariance_valid = false;
  /// The adaptive verdict.
  bool trusted = false;
  std::string trust_reason;
  std::size_t num_inliers = 0;
  double inlier_ratio = 0.0;
  std::string initialisation;  ///< "global", "prior", "given"
  /// edge_key() of its inputs (for the resume cache).
  std::string key;
};

struct EdgeOptions {
  /// The strategy run by run_strategy() (strategy.hpp): the recommended default, adaptive. A
  /// pair's prior is passed only to adaptive (the others refuse one; they get the guess).
  PaperStrategy strategy = kRecommendedStrategy;
  /// StrategyRequest::max_iterations (empty: the strategy's default).
  std::optional<int> max_iterations;
  bool is_valid(std::string* why = nullptr) const;
};

/// Aligns source onto target for `pair` with run_strategy() (its relative prior, if any, bounds
/// the adaptive search around its initial guess). `source` and `target` are the maps of
/// pair.source and pair.target. Throws what run_strategy() throws (InvalidArgument).
Edge align_edge(const StrategySource& source, const PreparedTarget& target,
                const CandidatePair& pair, const EdgeOptions& options = {});

/// The source of a map as align_edge() takes it (positions, covariances, up axis).
StrategySource edge_source(const Map& map);

/// Same, from the two maps (builds the PreparedTarget; the overload above lets a caller prepare
/// each target once).
Edge align_edge(const Map& source, const Map& target, const CandidatePair& pair,
                const EdgeOptions& options = {});

/// A 64-bit FNV-1a hash of a map's landmark positions and covariances (bit patterns), as 16 hex
/// digits.
std::string map_fingerprint(const Map& map);

/// The cache key of an edge: hex hash of both maps' fingerprints, the pair (indices, guess,
/// prior) and the options' fields that change the result, plus a format version.
std::string edge_key(const std::string& source_fingerprint, const std::string& target_fingerprint,
                     const CandidatePair& pair, const EdgeOptions& options);

}  // namespace lmalign
