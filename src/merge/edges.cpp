// Edges of a merge (include/lmalign/merge/edges.hpp).
#include "lmalign/merge/edges.hpp"

#include <cstdio>
#include <cstring>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {

// FNV-1a, 64 bits, over raw bytes.
struct Fnv1a {
  std::uint64_t h = 1469598103934665603ull;
  void bytes(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t k = 0; k < n; ++k) {
      h ^= p[k];
      h *= 1099511628211ull;
    }
  }
  void number(double v) { bytes(&v, sizeof v); }
  void integer(std::uint64_t v) { bytes(&v, sizeof v); }
  void text(const std::string& s) {
    integer(s.size());
    bytes(s.data(), s.size());
  }
  std::string hex() const {
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
  }
};

}  // namespace

bool EdgeOptions::is_valid(std::string* why) const {
  if (max_iterations && *max_iterations < 1) {
    if (why) *why = "max_iterations must be >= 1 (got " + std::to_string(*max_iterations) + ")";
    return false;
  }
  return true;
}

StrategySource edge_source(const Map& map) {
  const SourceLandmarks s = SourceLandmarks::from_map(map);
  StrategySource out;
  out.positions = s.positions;
  out.covariances_m2 = s.covariances_m2;
  out.up = s.up;
  return out;
}

Edge align_edge(const StrategySource& source, const PreparedTarget& target,
                const CandidatePair& pair, const EdgeOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("edge options: " + why);
  StrategyRequest request;
  request.strategy = options.strategy;
  request.max_iterations = options.max_iterations;
  request.initial_guess = pair.initial_guess;
  if (options.strategy == PaperStrategy::kAdaptive) request.prior = pair.prior;
  const StrategyOutcome r = run_strategy(source, target, request);
  Edge e;
  e.source = pair.source;
  e.target = pair.target;
  e.T_target_source = r.result.T_target_source;
  e.covariance = r.covariance.covariance;
  e.covariance_valid = r.covariance.valid;
  e.trusted = r.trustworthy;
  e.trust_reason = r.trust_reason;
  if (r.adaptive) {
    e.num_inliers = r.adaptive->num_inliers;
    e.inlier_ratio = r.adaptive->inlier_ratio;
    e.initialisation = r.adaptive->initialisation;
  } else {
    e.num_inliers = r.covariance.num_correspondences;
    e.initialisation = pair.initial_guess ? "given" : "identity";
  }
  return e;
}

Edge align_edge(const Map& source, const Map& target, const CandidatePair& pair,
                const EdgeOptions& options) {
  const PreparedTarget prepared(target);
  return align_edge(edge_source(source), prepared, pair, options);
}

std::string map_fingerprint(const Map& map) {
  Fnv1a f;
  f.integer(map.landmarks.size());
  for (const Landmark& l : map.landmarks) {
    f.bytes(l.p_world.data(), 3 * sizeof(double));
    f.bytes(l.cov_world_m2.data(), 9 * sizeof(double));
  }
  f.integer(map.frames.size());
  for (const Frame& fr : map.frames) {
    f.bytes(fr.p_world_camera.data(), 3 * sizeof(double));
    f.bytes(fr.q_world_camera.coeffs().data(), 4 * sizeof(double));
  }
  return f.hex();
}

std::string edge_key(const std::string& source_fingerprint, const std::string& target_fingerprint,
                     const CandidatePair& pair, const EdgeOptions& options) {
  Fnv1a f;
  f.text("lmalign-merge-edge-v2");  // v2: the half-sample covariance, the prior window
  f.text(source_fingerprint);
  f.text(target_fingerprint);
  f.integer(pair.source);
  f.integer(pair.target);
  f.integer(pair.initial_guess ? 1 : 0);
  if (pair.initial_guess) f.bytes(pair.initial_guess->matrix().data(), 16 * sizeof(double));
  f.integer(pair.prior ? 1 : 0);
  if (pair.prior) {
    f.number(pair.prior->rotation_deg);
    f.number(pair.prior->translation_m);
  }
  f.text(to_string(options.strategy));
  f.integer(options.max_iterations ? static_cast<std::uint64_t>(*options.max_iterations) : 0);
  return f.hex();
}

}  // namespace lmalign
