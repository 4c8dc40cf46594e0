// The correspondence search (issue 39, item 1): global hypotheses from matched landmarks rather
// than from a vote over every pose. For each pair of up-axis candidates (source, target):
//
//   1. Descriptors, of two kinds. The yaw-invariant one: each described landmark gets a
//      histogram of its neighbours within a radius (the target's median distance to its
//      `neighbours`-th nearest landmark): horizontal distance x height above or below it, both
//      along the map's up axis, so that it does not change under a yaw about that axis or any
//      translation. The oriented one, where both maps know their landmarks' viewing directions
//      (`oriented`): the neighbourhood within 1.5 times that radius in the landmark's own frame,
//      the up axis and the horizontal part of its mean viewing direction, with 8 bins of
//      azimuth (describe_landmark_oriented): what a SLAM map knows beyond the points tells a
//      facade's front from its side. Both append the viewing direction's elevation where both
//      maps know it. Square roots of the normalised counts (the Hellinger embedding), compared
//      by Euclidean distance. Each kind is matched, graphed and cut into cliques on its own.
//   2. Matches. Every source keypoint (evenly strided) takes its `matches_per_keypoint` nearest
//      target descriptors.
//   3. A consistency graph. Two matches (i, j) and (i', j') agree when the source pair and the
//      target pair have the same horizontal distance and the same height difference, each within
//      `consistency_sigmas` standard deviations of the four landmarks' positions (from their
//      covariances, at least the covariance floor; G3Reg's covariance-aware test, in 4 DoF).
//      Landmarks vaguer than a quarter of the descriptor radius match nothing: a landmark that
//      gates in anywhere tells nothing about where the maps meet.
//   4. Cliques. The graph's k-core numbers order the matches; from each of the best-ordered
//      `seeds`, a clique grows greedily (the candidate with the most neighbours among the
//      remaining candidates first). Each clique of at least `min_inliers` matches gives a 4-DoF
//      pose (estimate_4dof_transform after turning the source's up onto the target's), then,
//      when rigid, the pose again from every match that pose carries within
//      `consistency_sigmas` standard deviations (the two landmarks' together; the nearest one
//      per source keypoint), until those matches repeat, at most `refits` times: LO-RANSAC's
//      local optimisation (Chum, Matas and Kittler 2003). A greedy clique is a few of the true
//      matches; the refit takes in the others. Each
//      descriptor kind and pair of up axes ranks its distinct poses by decreasing clique size;
//      the hypotheses are those lists taken in turn, `hypotheses` in all.
//   5. Scale (free-scale runs only). The pairwise test compares the target's distances with the
//      source's times a factor, at each rung of a ladder of factors, with half a rung's
//      tolerance; a clique's distances then fix its scale (TEASER++ measures scale from
//      scale-invariant pairs the same way, by their distances' ratios).
//
// The pipeline then refines and scores them with everything else (best-first verification is the
// pipeline's ranking by the score the verdict uses). Frames: T_target_source, p_target =
// T_target_source * p_source. Deterministic: strided keypoints, no random draws, stable orders.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/stages/mahalanobis_gate.hpp"

namespace lmalign {

/// Settings of correspondence_search(). Plain struct; check with is_valid().
struct CorrespondenceSearchOptions {
  std::size_t keypoints = 512;           ///< source landmarks described and matched, >= 3
  std::size_t target_keypoints = 4096;   ///< target landmarks described, >= 3
  std::size_t neighbours = 24;           ///< sets the descriptor radius, [4, 256]
  std::size_t matches_per_keypoint = 3;  ///< [1, 16]
  double consistency_sigmas = 3.0;       ///< > 0
  /// When both maps know their landmarks' viewing directions, the oriented descriptors
  /// (describe_landmark_oriented: the neighbourhood about the up axis and the horizontal viewing
  /// direction, at the radius and twice it); otherwise, or when false, the yaw-invariant ones.
  bool oriented = true;
  std::size_t seeds = 128;      ///< cliques grown, >= 1
  std::size_t min_inliers = 5;  ///< >= 3
  std::size_t hypotheses = 64;  ///< poses at most, over every pair of up axes, >= 1
  /// Refits of each clique's pose from the matches it carries (step 4) at most, [0, 16]; fewer
  /// when those matches repeat. Rigid runs only (scale_steps 0). 0: the clique's own pose.
  int refits = 2;
  /// Free scale (issue 39, item 4): the graph is also built at scale factors
  /// scale_ratio^k, |k| <= scale_steps (target units per source unit, relative to the source
  /// as given), each with a tolerance of half a step on every distance; each clique then
  /// measures its own scale. 0: rigid, the factor 1 alone.
  int scale_steps = 0;        ///< [0, 64]
  double scale_ratio = 1.12;  ///< > 1
  bool is_valid(std::string* why = nullptr) const;
};

/// What the search works on: the maps alone.
struct CorrespondenceSearchInput : SearchMaps {};

struct CorrespondenceHypothesis {
  /// p_target = T_target_source * (scale * p_source).
  Isometry3 T_target_source = Isometry3::Identity();
  std::size_t inliers = 0;  ///< matches in its clique
  /// The clique's scale, target units per source unit (1 unless options.scale_steps > 0):
  /// Umeyama's, sum (t - t_mean).R(s - s_mean) / sum |s - s_mean|^2 over its matches.
  double scale = 1.0;
  /// Whether its clique's matches come from the oriented descriptors (else the yaw-invariant).
  bool oriented = false;
};

struct CorrespondenceSearchResult {
  /// Distinct within each descriptor kind and pair of up axes, each such list by decreasing
  /// clique size; the lists' best first, in turn (the yaw-invariant kind's pairs, then the
  /// oriented kind's).
  std::vector<CorrespondenceHypothesis> hypotheses;
  std::size_t matches = 0;  ///< graph nodes, over the up-axis pairs
  double radius_m = 0.0;    ///< descriptor radius
};

/// Runs the search (see the file comment). Throws InvalidArgument on invalid options or input
/// (no target, no up axes, a floor that is not finite and > 0). Maps with fewer than 3
/// landmarks, or too sparse for a descriptor, give no hypotheses.
CorrespondenceSearchResult correspondence_search(const CorrespondenceSearchInput& input,
                                                 const CorrespondenceSearchOptions& options);

/// One map's landmarks described once for many searches: the merge's geometric verification
/// matches each map against dozens of others (merge/candidates.hpp). The yaw-invariant
/// descriptors (step 1) of the evenly strided `keypoints` landmarks about one up axis, at one
/// radius, each with its viewing elevation where the map knows its viewing directions.
struct DescribedLandmarks {
  std::vector<std::uint32_t> keys;  ///< landmark indices, increasing
  /// keys.size() x (kLandmarkDescriptorDims + 1): the descriptor, then the viewing elevation
  /// term (0 where unknown or when has_views is false).
  std::vector<float> descriptors;
  std::vector<char> described;  ///< per key: enough neighbours within the radius
  bool has_views = false;       ///< the map's viewing directions were given
  double radius_m = 0.0;        ///< metres
  Vec3 up = Vec3::UnitZ();      ///< unit, the map's frame
};

/// The descriptor radius correspondence_search() uses when `points` is the target: the median
/// distance of (at most 512 of) the `target_keypoints` strided landmarks to their
/// `neighbours`-th nearest landmark, metres; 0 for fewer than 3 landmarks.
double search_descriptor_radius(const Points3& points, const CorrespondenceSearchOptions& options);

/// Describes `points` (map frame; view_directions: unit or zero, null or empty = none) for
/// correspondence_search_described(): options.keypoints strided landmarks when `as_source`,
/// options.target_keypoints otherwise, about `up` (normalised here) at `radius_m` (> 0 and
/// finite; search_descriptor_radius() of the map that will be the target reproduces
/// correspondence_search() exactly). Throws InvalidArgument on invalid options, a radius or up
/// that is not finite, or view directions whose count differs from the points'.
DescribedLandmarks describe_search_landmarks(const Points3& points,
                                             const std::vector<Vec3>* view_directions,
                                             const Vec3& up, double radius_m, bool as_source,
                                             const CorrespondenceSearchOptions& options);

/// correspondence_search() (yaw-invariant descriptors only, one pair of up axes: the described
/// ones') on landmarks described beforehand: steps 2-4 alone. `input` supplies the points,
/// covariances and the floor (its ups are ignored); `source` and `target` describe
/// input.source.points and input.target's points. Landmarks vaguer than a quarter of the
/// target's radius match nothing, and the viewing elevation counts when both sides have views,
/// as in correspondence_search(). With both described at the target's search_descriptor_radius()
/// (and options.oriented false) the hypotheses are correspondence_search()'s. Throws
/// InvalidArgument as correspondence_search(), and when a described key is out of range or a
/// described up axis is not unit.
CorrespondenceSearchResult correspondence_search_described(
    const CorrespondenceSearchInput& input, const DescribedLandmarks& source,
    const DescribedLandmarks& target, const CorrespondenceSearchOptions& options);

/// Step 2 alone: each valid source descriptor's `m` nearest valid target descriptors
/// (Euclidean over `dims` floats; ties by the earlier target), source by source, nearest first,
/// as (source key, target key). `source` and `target` hold source_keys.size() x dims and
/// target_keys.size() x dims floats; `source_ok` and `target_ok` one flag per key (0: invalid,
/// matched with nothing). The components are summed in decreasing order of their variance over
/// the valid targets, and a sum stops once it exceeds the m-th best so far. `lanes` targets are
/// summed at once, one per lane, with the same single-precision operations in the same order,
/// so the result is the same for every width: 0 (the default) the widest this CPU runs (8 with
/// AVX, chosen at run time; else 4 with SSE2, x86-64's baseline; else 1), or 1, 4 or 8 to ask
/// for one (tests compare them). Throws InvalidArgument if a size disagrees, dims < 1, m < 1,
/// or `lanes` is a width this build or CPU lacks.
std::vector<std::pair<std::uint32_t, std::uint32_t>> match_descriptors(
    const std::vector<std::uint32_t>& source_keys, const std::vector<float>& source,
    const std::vector<char>& source_ok, const std::vector<std::uint32_t>& target_keys,
    const std::vector<float>& target, const std::vector<char>& target_ok, int dims, std::size_t m,
    std::size_t lanes = 0);

}  // namespace lmalign
