// The merge-manifest fuzz oracle, shared by the libFuzzer target (fuzz_merge_manifest.cpp) and
// the regression test that replays fuzz/corpus/merge_manifest/ and
// fuzz/regressions/merge_manifest/ (tests/merge/test_merge_fuzz_regressions.cpp).
// docs/robustness.md describes it.
//
// Input: a manifest (YAML, docs/merge.md "Manifest"). It is read (parse_manifest) and planned as
// `lmalign merge` plans it, with the map files replaced by small synthetic maps (no file is
// read): each entry gets a fixed room of landmarks, expressed in its own frame by the inverse of
// its prior when it has one; summarise_map, plan_candidates; then the pose graph of the priors
// and one edge per candidate that has a relative prior (its initial guess, with a small
// covariance), and the merged map of component 0. Manifests of more than kFuzzMaxManifestMaps
// maps are only read.
//
// For any bytes:
//   - parse_manifest throws lmalign::Error (yaml-cpp's exceptions included, as ParseError) or
//     returns a manifest: names unique and non-empty; every prior rigid, with a symmetric
//     positive definite covariance, within the supported range;
//   - planning does not throw: each candidate names two maps (source < target), and a relative
//     prior is a finite rigid guess within the supported range with sigmas PriorSigma accepts;
//   - the pose graph does not throw, and its poses are finite rigid transforms; the merged map
//     is finite and valid.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <random>
#include <set>
#include <string>
#include <vector>


#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/symmetric_eigen.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/merge/candidates.hpp"
#include "lmalign/merge/manifest.hpp"
#include "lmalign/merge/output.hpp"
#include "lmalign/merge/pose_graph.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "map_reader_check.hpp"  // LMALIGN_FUZZ_CHECK, is_proper_rigid

namespace lmalign::fuzz {

/// Larger manifests are read and checked, not planned (time per input).
inline constexpr std::size_t kFuzzMaxManifestMaps = 12;

/// A small room of landmarks (a floor, a wall, clutter; metres), the same for every call with
/// the same seed, with isotropic 1 cm covariances and two observations by one frame.
inline Map fuzz_room_map(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Map map;
  Frame f;
  f.id = 0;
  f.p_world_camera = Vec3(2.0, 1.5, 1.2);
  map.frames.push_back(f);
  for (int i = 0; i < 40; ++i) {
    Landmark l;
    l.id = i;
    const double pick = u(rng);
    l.p_world = Vec3(4.0 * u(rng), 3.0 * u(rng), pick < 0.5 ? 0.0 : 2.5 * u(rng));
    if (pick >= 0.5 && pick < 0.7) l.p_world.y() = 0.0;
    l.cov_world_m2 = Mat3::Identity() * 1e-4;
    l.observations = {{0, 100.0, 120.0}, {0, 101.0, 121.0}};
    map.landmarks.push_back(l);
  }
  return map;
}

/// The whole oracle for one input.
inline void check_merge_manifest_bytes(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  Manifest manifest;
  try {
    manifest = parse_manifest(text, "fuzz.yaml", "/fuzz-base");
  } catch (const Error&) {
    return;  // a clear refusal; any other exception propagates (a finding)
  }
  const std::size_t n = manifest.maps.size();
  LMALIGN_FUZZ_CHECK(n > 0, "an accepted manifest lists no map");
  std::set<std::string> names;
  std::vector<std::optional<MapPrior>> priors;
  for (const ManifestEntry& e : manifest.maps) {
    LMALIGN_FUZZ_CHECK(!e.name.empty() && names.insert(e.name).second,
                       "map names are not unique and non-empty");
    priors.push_back(e.prior);
    if (!e.prior) continue;
    LMALIGN_FUZZ_CHECK(is_rigid_transform(e.prior->T_world_map), "an accepted prior is not rigid");
    const Mat6& C = e.prior->covariance;
    LMALIGN_FUZZ_CHECK(C.allFinite() && (C - C.transpose()).cwiseAbs().maxCoeff() <=
                                            1e-9 * C.cwiseAbs().maxCoeff(),
                       "an accepted prior covariance is not symmetric");
    LMALIGN_FUZZ_CHECK(symmetric_eigen(C, false).values.minCoeff() > 0.0,
                       "an accepted prior covariance is not positive definite");
    try {
      check_prior_in_supported_range(*e.prior, "prior");
    } catch (const InvalidArgument& ex) {
      std::fprintf(stderr, "%s\n", ex.what());
      LMALIGN_FUZZ_CHECK(false, "an accepted prior is beyond the supported range");
    }
  }
  if (n > kFuzzMaxManifestMaps) return;

  // The maps: each entry's room, in its own frame (its prior's inverse, when it has one).
  std::vector<Map> maps;
  std::vector<MapSummary> summaries;
  std::vector<std::string> sessions;
  for (std::size_t i = 0; i < n; ++i) {
    const Map room = fuzz_room_map(static_cast<std::uint32_t>(i % 3));
    maps.push_back(priors[i] ? transform_map(room, priors[i]->T_world_map.inverse()) : room);
    summaries.push_back(summarise_map(maps.back(), {}, i + 1));
    sessions.push_back(manifest.maps[i].session);
  }
  const std::vector<CandidatePair> candidates = plan_candidates(summaries, priors);
  std::vector<Edge> edges;
  for (const CandidatePair& c : candidates) {
    LMALIGN_FUZZ_CHECK(c.source < c.target && c.target < n, "a candidate names no valid pair");
    LMALIGN_FUZZ_CHECK(c.initial_guess.has_value() == c.prior.has_value(),
                       "a guess without sigmas or sigmas without a guess");
    if (!c.initial_guess) continue;
    LMALIGN_FUZZ_CHECK(is_proper_rigid(*c.initial_guess), "a relative prior is not rigid");
    LMALIGN_FUZZ_CHECK(within_supported_range(c.initial_guess->translation()),
                       "a relative prior is beyond the supported range");
    std::string why;
    if (!c.prior->is_valid(&why)) std::fprintf(stderr, "%s\n", why.c_str());
    LMALIGN_FUZZ_CHECK(c.prior->is_valid(), "the sigmas of a relative prior are refused");
    Edge e;
    e.source = c.source;
    e.target = c.target;
    e.T_target_source = *c.initial_guess;
    e.covariance = Mat6::Identity() * 1e-4;
    e.covariance_valid = true;
    e.trusted = true;
    e.trust_reason = "ok";
    edges.push_back(e);
  }
  const MergeResult r = solve_pose_graph(n, priors, edges);
  for (const MapPose& p : r.maps) {
    LMALIGN_FUZZ_CHECK(is_proper_rigid(p.T_world_map),
                       "a solved pose is not a finite rigid transform");
    LMALIGN_FUZZ_CHECK(!p.covariance_valid || p.covariance.allFinite(),
                       "a valid pose covariance is not finite");
  }
  LMALIGN_FUZZ_CHECK(r.num_components >= 1, "no component");
  const Map merged = merge_maps(maps, sessions, r, 0);
  for (const Landmark& l : merged.landmarks) {
    LMALIGN_FUZZ_CHECK(l.p_world.allFinite() && l.cov_world_m2.allFinite(),
                       "a merged landmark is not finite");
  }
}

}  // namespace lmalign::fuzz
