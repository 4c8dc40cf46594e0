// The global search of the adaptive default: an exhaustive coarse-to-fine search over every
// pair of up-axis candidates, every yaw and every translation, that refines the candidates it
// keeps with the pipeline's own refinement and ranks them by the score the result is judged by.
//
//   1. Coarse vote. For each pair of up axes (source, target) and each yaw on a grid of
//      yaw_step_deg, the sampled source landmarks, rotated about their centre, vote for the
//      3-D translations q - R p towards every sampled target landmark, in cells of cell_m.
//      Every pair votes, so the counts carry a smooth background (the overlap of the two maps'
//      extents at that translation) under the matched landmarks' spike of one or two cells; a
//      peak is ranked by its prominence, its cell's votes above the mean of the cells two away
//      (on a street the background is a ridge along the road whose crest, where the maps overlap
//      most, outvotes the truth of a short overlap on its flank). The peaks_per_yaw most
//      prominent peaks of every yaw, each at least three cells from a better one, are the
//      candidates: every yaw and every region of translations is visited; nothing is kept
//      because a neighbouring yaw did better.
//   2. Pool. The candidates are ranked twice, by prominence and by the gated score at the coarse
//      resolution on screen_samples landmarks; the pool takes them from the two rankings in
//      turn, dropping near-duplicates, up to `pool`; then the input's extra candidates (the
//      correspondence search's poses) join it: all of them when there are at most extra_keep,
//      else extra_keep of them, from their own order (by clique size) and the sharp gated score
//      on rank_samples landmarks, in turn. (Indoors, repeated structure spreads the
//      votes and the score ranks best; on a street the score at the coarse resolution is flatter
//      than the true peak is narrow, and the prominence ranks best.)
//   3. Snap. Each pooled candidate moves to the peak of a finer vote about it: yaws within one
//      coarse step at a quarter of it, translations within two cells at a third of a cell,
//      towards each moved landmark's snap_neighbours nearest target landmarks.
//   4. Rounds. The snapped candidates are ranked by the gated score at the fine resolution; the
//      best rank_keep are refined (round1_iterations on round1_samples landmarks, from the fine
//      pose uncertainty) and ranked by the sharp gated score (no pose uncertainty); the best
//      round1_keep are refined further on round2_samples; the best `modes` distinct ones (moving
//      a landmark at the source radius by more than distinct_cells cells apart) are returned,
//      best first, with their scores.
// The search's resolution is the fine one: a returned mode is a pose refined from within a third
// of a cell and a quarter yaw step of the best pose of its region of the pool.
//
// Frames: T_target_source, p_target = T_target_source * p_source. Deterministic for any thread
// count: strided samples, no random draws, one slot per candidate, stable sorts.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/stages/mahalanobis_gate.hpp"

namespace lmalign {

/// Settings of complete_search(). Plain struct; check with is_valid().
struct CompleteSearchOptions {
  double yaw_step_deg = 3.0;               ///< (0, 90]
  std::size_t vote_source_samples = 128;   ///< >= 3
  std::size_t vote_target_samples = 1024;  ///< >= 3
  std::size_t peaks_per_yaw = 4;           ///< [1, 64]
  std::size_t pool = 768;                  ///< >= 1
  std::size_t screen_samples = 128;        ///< >= 16
  std::size_t snap_samples = 256;          ///< >= 16
  std::size_t snap_neighbours = 32;        ///< [1, 256]
  std::size_t rank_samples = 256;          ///< >= 16
  std::size_t rank_keep = 96;              ///< >= 1
  int round1_iterations = 15;              ///< >= 1
  std::size_t round1_samples = 256;        ///< >= 16
  std::size_t round1_keep = 16;            ///< >= 1
  int round2_iterations = 20;              ///< >= 1
  std::size_t round2_samples = 512;        ///< >= 16
  std::size_t modes = 6;                   ///< >= 1
  double distinct_cells = 4.0;             ///< > 0
  /// Extra candidates kept (step 2), >= 1: on a street's repeated facades the largest cliques
  /// are often wrong, and the truth's clique pose ranks lower by size than by the sharp score.
  std::size_t extra_keep = 16;
  /// False: no coarse vote (steps 1 and 2); the pool is the input's extra candidates alone,
  /// snapped and refined in the rounds (the correspondence search's first pass).
  bool vote = true;
  bool is_valid(std::string* why = nullptr) const;
};

/// What the search works on: the maps (SearchMaps), and what follows.
struct CompleteSearchInput : SearchMaps {
  /// The source's centre and typical distance from it (DataScales), metres.
  Vec3 source_centre_m = Vec3::Zero();
  double source_radius_m = 1.0;
  /// The coarse vote's cell, metres (> 0).
  double cell_m = 0.0;
  MahalanobisGateOptions gate;
  /// The gated score's evidence scales (Scales::evidence(); pair_evidence); off: every gated
  /// pair counts fully.
  EvidenceScales evidence;
  /// The pose uncertainty of the coarse resolution (the gate's start from a coarse candidate);
  /// the fine one is a third of it.
  PoseSigma coarse_sigma;
  /// Poses found otherwise (the correspondence search's, correspondence_search.hpp), best first,
  /// added to the pool after the coarse vote's candidates (at most options.extra_keep of them,
  /// step 2): snapped and refined like them.
  std::vector<Isometry3> extra_candidates;
};

/// The refinement the search uses: from `start`, with the gate's pose uncertainty starting at
/// `sigma` (pivot ignored: the refinement sets it), on the source landmarks `subset`, for at
/// most `max_iterations`; returns the refined pose. Must be safe to call concurrently.
using SearchRefineFn =
    std::function<Isometry3(const Isometry3& start, const PoseSigma& sigma,
                            const std::vector<std::uint32_t>& subset, int max_iterations)>;

struct SearchMode {
  Isometry3 T_target_source = Isometry3::Identity();
  double score = 0.0;  ///< sharp gated score on round2_samples landmarks
};

struct CompleteSearchResult {
  std::vector<SearchMode> modes;  ///< distinct, best first
  std::size_t candidates = 0;     ///< from the coarse vote
  std::size_t pooled = 0;
  PoseSigma fine_sigma;  ///< the search's resolution
  double fine_cell_m = 0.0;
};

/// Runs the search (see the file comment). Throws InvalidArgument on invalid options or input
/// (no up axes, a cell, floor or sigma that is not finite and > 0, fewer than 3 landmarks on a
/// side).
CompleteSearchResult complete_search(const CompleteSearchInput& input,
                                     const CompleteSearchOptions& options,
                                     const SearchRefineFn& refine);

/// Evenly strided indices: min(n, want) of [0, n).
std::vector<std::uint32_t> strided_indices(std::size_t n, std::size_t want);

}  // namespace lmalign
