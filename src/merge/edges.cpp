// Edges of a merge (include/lmalign/merge/edges.hpp).
#include "lmalign/merge/edges.hpp"

#include <algorithm>
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

SourceLandmarks edge_source(const Map& map) { return SourceLandmarks::from_map(map); }

namespace {

const Preset& edge_preset(const EdgeOptions& options, Preset* storage) {
  if (options.strategy.empty()) return recommended_preset();
  *storage = find_preset(options.strategy);
  return *storage;
}

AlignRequest edge_request(const Preset& preset, const CandidatePair& pair,
                          const EdgeOptions& options) {
  AlignRequest request;
  request.max_iterations = options.max_iterations;
  const Pipeline pipeline(preset.spec);
  // A merge's prior edge is checked by the global search like a single alignment
  // (init.prior_check=rivals): a wrong prior gives no trusted edge. How far an untrusted one is
  // rescued is the pair's (CandidatePair::prior_complete_search): on a fleet, whose candidate
  // pairs mostly do not overlap, by the maps' first pass alone ("check"); on a small merge by
  // their complete search too ("rescue"; docs/merge.md, "Edges with priors"). The caller's own
  // setting (EdgeOptions::settings: lmalign merge --set) wins.
  // The pair's own value of `key`, unless the caller sets it or the preset has no such setting.
  auto pair_setting = [&](const std::string& key, const std::string& value) {
    const bool set_by_caller = std::any_of(options.settings.begin(), options.settings.end(),
                                           [&](const auto& kv) { return kv.first == key; });
    if (!set_by_caller && pipeline.settings().has(key)) {
      request.settings.emplace_back(key, SettingValue(value));
    }
  };
  if (pair.prior) pair_setting("init.prior_complete_search", pair.prior_complete_search);
  // Without a prior, likewise: a fleet's pair is searched completely only to check a trusted
  // first-pass answer (CandidatePair::complete_search, "check").
  if (!pair.prior) pair_setting("search.complete_search", pair.complete_search);
  request.settings.insert(request.settings.end(), options.settings.begin(), options.settings.end());
  request.initial_guess = pair.initial_guess;
  request.scale = options.scale;
  request.source_metric = pair.source_metric;
  request.target_metric = pair.target_metric;
  request.covariances_assumed = pair.covariances_assumed;
  if (pair.prior && pipeline.initialiser().uses_prior()) request.prior = pair.prior;
  return request;
}

}  // namespace

Edge align_edge(const SourceLandmarks& source, const PreparedTarget& target,
                const CandidatePair& pair, const EdgeOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("edge options: " + why);
  Preset storage;
  const Preset& preset = edge_preset(options, &storage);
  const Summary r = align(preset, source.view(), target, edge_request(preset, pair, options));
  Edge e;
  e.source = pair.source;
  e.target = pair.target;
  e.T_target_source = r.registration.T_target_source;
  e.covariance = r.covariance.covariance;
  e.covariance_valid = r.covariance.valid;
  e.scale_free = r.scale.free;
  e.scale = r.scale.scale;
  e.scale_sd = r.scale.scale_sd;
  e.covariance_7x7 = r.scale.covariance_7x7;
  e.trusted = r.verdict.trustworthy;
  e.trust_reason = r.verdict.reason;
  e.num_inliers = r.verdict.num_inliers;
  e.inlier_ratio = r.verdict.inlier_ratio;
  e.initialisation = r.initialisation.initialisation;
  e.summary_json = to_json(r);
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
  // v4: the scale mode (resolved for the pair) and the maps' flags
  f.text("lmalign-merge-edge-v4");
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
  f.text(to_string(resolve_scale_mode(options.scale, pair.source_metric, pair.target_metric)));
  f.integer(pair.source_metric ? 1 : 0);
  f.integer(pair.target_metric ? 1 : 0);
  f.integer(pair.covariances_assumed ? 1 : 0);
  Preset storage;
  const Preset& preset = edge_preset(options, &storage);
  const PipelineSpec spec = resolve_spec(preset, edge_request(preset, pair, options));
  f.text(preset.name);
  f.text(spec.initialiser + "|" + spec.matcher + "|" + spec.kernel + "|" + spec.estimator + "|" +
         spec.schedule + "|" + spec.scorer + "|" + spec.trust);
  for (const std::string& r : spec.rejectors) f.text(r);
  f.text(Pipeline(spec).settings().canonical_text());
  return f.hex();
}

}  // namespace lmalign
