// Candidate pairs of a merge (docs/merge.md, "Candidates"): which mini-maps to try to align.
//   - Both maps with a prior: the pair is a candidate when the maps' bounding spheres, placed by
//     their priors, overlap within 3 sigma of the relative prior's translation (plus the
//     rotation sigma times the radius).
//   - Otherwise, N <= all_pairs_max_maps: every pair.
//   - Otherwise map retrieval ranks the pairs (issue 37): a bag of words over the landmarks'
//     yaw-invariant neighbourhood descriptors (landmark_descriptors.hpp, at each map's own
//     descriptor radius), with a vocabulary learned by k-means from the maps at hand, tf-idf
//     weights and cosine similarity; each map is also split in two halves along its main
//     horizontal axis, and a pair's similarity is the best over {whole, halves} x {whole,
//     halves} (two maps often share only a corner). Geometric verification (verify_per_map > 0):
//     each map's verify_per_map most similar maps are checked by the correspondence search
//     (registration/stages/correspondence_search.hpp) on the two maps' sketches (their
//     retrieval_landmarks strided landmarks with covariances and viewing directions): the
//     largest clique of pairwise-consistent descriptor matches. Every sketch is described
//     once (describe_search_landmarks), at one radius for all: the median over the maps of
//     each sketch's search_descriptor_radius (a search describes both maps at the target's
//     radius; the median stands in for it). Each map then keeps the
//     keep_per_map partners with the largest cliques (ties: the more similar first); the union
//     of those is the candidate set. A map with too few descriptors
//     falls back to the earlier histograms (its landmarks' heights along its up axis relative to
//     its median camera height, and distances between seeded random landmark pairs; L1
//     distance), ranked after every retrieved pair.
//   - At most max_pairs pairs (the best ranked first).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/merge/manifest.hpp"
#include "lmalign/registration/pipeline.hpp"

namespace lmalign {

/// A pair to align: `source` and `target` are map indices (source < target); the edge
/// estimates T_target_source.
struct CandidatePair {
  std::size_t source = 0;
  std::size_t target = 0;
  /// Rank key, smaller = more promising (the descriptor distance, divided by 1 + the verified
  /// clique's matches when verified; or the prior centre distance over the spheres' reach); 0
  /// for "every pair".
  double rank = 0.0;
  /// With priors on both maps: the relative prior T_target_source = T_world_target^-1 *
  /// T_world_source and its sigmas (the two priors' covariances, assumed independent, moved
  /// into the target frame by the adjoint; worst axes).
  std::optional<Isometry3> initial_guess;
  std::optional<PriorSigma> prior;
  /// Whether each map's lengths are metres (MapHeader::scale == MapScale::kMetric), and whether
  /// either map's covariances are assumed (MapHeader::covariance_assumed): passed to align()
  /// (AlignRequest::source_metric, target_metric, covariances_assumed).
  bool source_metric = true;
  bool target_metric = true;
  bool covariances_assumed = false;
  /// With a prior: the edge's init.prior_complete_search (registration/stages/
  /// init_complete_search.cpp) unless the caller sets it. plan_candidates says "rescue" (an
  /// untrusted prior-bounded alignment also gets the maps' complete search) for merges of at
  /// most CandidateOptions::all_pairs_max_maps maps, where a merge without priors would align
  /// every pair with the full default anyway: a merge with priors is never worse than the same
  /// merge without them (issue 37, item 4). Beyond, "check" (the maps' first pass checks a
  /// trusted answer and rescues an untrusted one; their complete search only checks): most
  /// candidate pairs of a fleet do not overlap, and the complete search on each would cost
  /// several times the merge (docs/merge.md, "Edges with priors").
  std::string prior_complete_search = "check";
  /// Without a prior: the edge's search.complete_search (registration/stages/
  /// init_complete_search.cpp) unless the caller sets it. plan_candidates says "rescue" (the
  /// default's complete search whenever its first pass does not settle the pair) for merges of
  /// at most CandidateOptions::all_pairs_max_maps maps, as a single alignment; beyond, "check":
  /// the complete search only checks a trusted first-pass answer, and a pair whose first pass
  /// finds no correspondence pose gets no answer (not trusted). On four simulated fleets of
  /// 50-200 maps the complete search took 77-93% of the edges' time and made 0-3 of the 32-654
  /// pairs it ran on trusted and right, up to 5 trusted and wrong (docs/merge.md, "Pairs without
  /// priors").
  std::string complete_search = "rescue";
  /// Retrieved pairs with geometric verification (CandidateOptions::verify_per_map): the
  /// matches in the correspondence search's largest clique between the maps' sketches (0: none
  /// found, or not verified).
  std::size_t verified_matches = 0;
};

struct CandidateOptions {
  /// Every pair is a candidate up to this many maps without priors, >= 2.
  std::size_t all_pairs_max_maps = 12;
  /// The pre-filter keeps this many most similar maps per map, >= 1.
  std::size_t keep_per_map = 4;
  /// At most this many pairs in all (0 = no limit).
  std::size_t max_pairs = 0;
  /// Spheres overlap test: this many sigmas of the relative prior, > 0.
  double prior_sigmas = 3.0;
  /// Bounding radius: this quantile of the landmarks' distances from their centroid, (0, 1].
  double radius_quantile = 0.95;
  /// Histogram bins, and the largest height / distance binned (as multiples of the median
  /// landmark distance from the centroid).
  std::size_t bins = 16;
  /// Random landmark pairs per map for the distance histogram (seeded by the map index).
  std::size_t distance_samples = 4000;
  /// Retrieval: landmarks described per map (evenly strided), >= 8; the descriptor radius is
  /// the map's median distance to its descriptor_neighbours-th nearest landmark, [4, 256].
  std::size_t retrieval_landmarks = 512;
  std::size_t descriptor_neighbours = 24;
  /// Words of the vocabulary learned from the maps (k-means), [2, 4096].
  std::size_t vocabulary_words = 1024;
  /// Geometric verification of the retrieval: each map's this many most similar maps are
  /// verified by the correspondence search before keep_per_map are kept; 0 = none (the words
  /// alone rank). The default verifies every pair of up to 201 maps and grows linearly beyond.
  /// Measured on the synthetic fleet (docs/merge.md, "Candidates"): overlapping maps share
  /// cliques of 9-110 matches, 28 of 30 unrelated pairs none; 200 maps verify every pair in
  /// 42 s on 2 cores.
  std::size_t verify_per_map = 200;
  bool is_valid(std::string* why = nullptr) const;
};

/// What the planner needs to know of a map (cheap to keep for thousands of maps).
struct MapSummary {
  Vec3 centroid = Vec3::Zero();  ///< map frame, metres
  double radius_m = 0.0;
  std::vector<double> descriptor;  ///< normalised histograms (see the file comment)
  /// Retrieval: the described landmarks' descriptors, kLandmarkDescriptorDims floats each, and
  /// each one's half of the map (0 or 1, along its main horizontal axis).
  std::vector<float> local_descriptors;
  std::vector<std::uint8_t> local_regions;
  /// The geometric verification's sketch: the described landmarks (up to retrieval_landmarks,
  /// evenly strided; map frame, metres), their covariances (m^2; zero where unknown: the floor
  /// applies) and unit mean viewing directions (zero where unknown), the map's up axis (unit)
  /// and its covariance floor (metres, DataScales::floor_m of the sketch).
  Points3 sketch_points;
  std::vector<Mat3> sketch_covariances_m2;
  std::vector<Vec3> sketch_view_directions;
  Vec3 up = Vec3::UnitZ();
  double floor_m = 0.0;
  /// The sketch's descriptor radius as the target of a correspondence search (metres;
  /// search_descriptor_radius; 0: none). plan_candidates describes every sketch once, at the
  /// median of these over the maps, for the verification of every pair it is in.
  double sketch_radius_m = 0.0;
  std::size_t num_landmarks = 0;
  bool metric = true;               ///< MapHeader::scale == MapScale::kMetric
  bool covariance_assumed = false;  ///< MapHeader::covariance_assumed
};

/// The summary of one map (deterministic; `seed` seeds the distance sampling).
MapSummary summarise_map(const Map& map, const CandidateOptions& options, std::uint64_t seed);

/// Relative prior of two maps' priors (see CandidatePair::prior): T_target_source and its 6x6
/// covariance in the target frame (uncertainty.hpp's convention). Its rotation is a rotation to
/// round-off even when the priors' are orthonormal only to 1e-6 (the nearest rotation then).
Isometry3 relative_prior(const MapPrior& source, const MapPrior& target, Mat6* covariance);

/// Plans the candidate pairs of `summaries` (one per map, in manifest order) with their priors
/// (`priors[i]` empty when map i has none). Deterministic. Throws InvalidArgument on invalid
/// options or sizes that do not match.
std::vector<CandidatePair> plan_candidates(const std::vector<MapSummary>& summaries,
                                           const std::vector<std::optional<MapPrior>>& priors,
                                           const CandidateOptions& options = {});

}  // namespace lmalign
