// Initialisation without a good initial guess: pose hypotheses from a yaw search and a
// translation vote (a Hough transform over translations).
//
// SLAM and SfM maps are nearly gravity-aligned in their own frames, so the unknown rotation
// between two of them is a rotation taking the source's up axis onto the target's, then a yaw
// about the target's up axis. For every yaw on a grid the sampled source landmarks, rotated about
// their centre (the coordinate-wise median of the samples, which a few far landmarks cannot
// move), vote for the translations q - R p towards every sampled target landmark (taken relative
// to the target samples' median, so that the votes span the maps' sizes, not their coordinates)
// in a grid of `cell_m` cells, clamped to 2^20 cells from the centre per axis; landmarks present in
// both maps vote for the same cell, the rest spread out, so partial overlap lowers the peak but
// does not move it. The peak (3x3x3 cells) gives each yaw a translation and a vote count; the yaws
// whose counts are local maxima over yaw, best first, are the hypotheses. With a prior (an initial
// guess and its sigmas) the yaws stay within 3 sigma of the guess's rotation, and the votes within
// 3 sigma of where the guess puts the source centre. The sigmas are of the left perturbation about
// the target origin (uncertainty.hpp): each yaw's window is centred where that yaw about the up
// axis through the origin takes the guess's image of that centre, with radius 3 (sd_t + sd_r h) + 2
// cells across the up axis and 3 (sd_t + sd_r d) + 2 cells along it (h, d: the image's height and
// horizontal distance from the origin, the lever arms of a tilt).
//
// Frames: T_target_source, p_target = T_target_source * p_source. Deterministic: strided
// samples, no random draws, one slot per yaw.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lmalign/core/geometry.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

/// Settings of the yaw-vote search. Plain struct; check with is_valid().
struct YawVoteOptions {
  /// Spacing of the yaw grid, degrees, (0, 90]. A hypothesis is then at most half a step off in
  /// yaw; the refinement's basin must cover that (the basins: docs/accuracy.md).
  double yaw_step_deg = 3.0;
  /// Landmarks that vote: evenly strided samples of each map, >= 3 each.
  std::size_t source_samples = 128;
  std::size_t target_samples = 1024;
  /// How many hypotheses are returned at most, >= 1.
  std::size_t hypotheses = 6;
  /// Translation peaks kept per yaw (each at least 3 cells from a better one), >= 1. With 1,
  /// a yaw's peak is a hypothesis when it is a local maximum over yaw; with more, every peak of
  /// every yaw is, best first.
  std::size_t peaks_per_yaw = 1;
  /// Vote in 3-D cells instead of horizontal cells with the height from the peak's votes; peaks
  /// are ranked by prominence (their cell's votes above the mean of the cells two away, which
  /// removes the smooth background of every-pair votes), their translation is the mean of their
  /// 3x3x3 block's votes.
  bool vote_3d = false;
  bool is_valid(std::string* why = nullptr) const;
};

/// A prior on T_target_source: the guess and its standard deviations (of the left perturbation
/// T = Exp(xi) T_guess about the target origin, uncertainty.hpp; worst axes).
struct PoseWindow {
  Isometry3 T_target_source_guess = Isometry3::Identity();
  double rotation_sd_rad = 0.0;   ///< > 0
  double translation_sd_m = 0.0;  ///< > 0

  /// The window of a prior given as InitialiserContext and PriorSigma give it: the guess, the
  /// rotation's standard deviation in degrees and the translation's in metres.
  static PoseWindow of_prior(const Isometry3& guess, double rotation_sd_deg,
                             double translation_sd_m) {
    PoseWindow w;
    w.T_target_source_guess = guess;
    w.rotation_sd_rad = rotation_sd_deg * kPi / 180.0;
    w.translation_sd_m = translation_sd_m;
    return w;
  }

  /// The standard deviation (metres) of where `point_m` (source frame) lands under the prior:
  /// the translation sigma is about the target origin (uncertainty.hpp), so it grows by the
  /// rotation's sigma times the distance of the point's image from there. The search's window
  /// and the verdict's check of it (Pipeline::run) are 3 of these.
  double point_sd_m(const Vec3& point_m) const {
    return translation_sd_m + rotation_sd_rad * (T_target_source_guess * point_m).norm();
  }
  /// How far `T` (T_target_source) is from the guess, and the window's bounds there: its rotation
  /// (radians) against 3 rotation sigmas, and the move of `centre_m` (source frame) against
  /// 3 point_sd_m(centre_m), each widened by a search's resolution (metres, radians).
  struct Check {
    double rotation_rad = 0.0, max_rotation_rad = 0.0;
    double moved_m = 0.0, max_moved_m = 0.0;
    bool inside() const { return rotation_rad <= max_rotation_rad && moved_m <= max_moved_m; }
  };
  Check check(const Isometry3& T, const Vec3& centre_m, double resolution_m,
              double resolution_rad) const {
    Check c;
    c.rotation_rad =
        Eigen::AngleAxisd(T.linear() * T_target_source_guess.linear().transpose()).angle();
    c.moved_m = (T * centre_m - T_target_source_guess * centre_m).norm();
    c.max_rotation_rad = 3.0 * rotation_sd_rad + resolution_rad;
    c.max_moved_m = 3.0 * point_sd_m(centre_m) + resolution_m;
    return c;
  }
};

struct YawHypothesis {
  Isometry3 T_target_source = Isometry3::Identity();
  double yaw_rad = 0.0;   ///< about the target's up axis, relative to the base rotation
  std::size_t votes = 0;  ///< peak votes (3x3x3 cells); with vote_3d its prominence
};

/// The hypotheses for aligning `source_points` to `target_points` (metres; see the file
/// comment). `up_source`, `up_target`: unit up axes of the two maps in their own frames
/// (estimate_up_axis()). `cell_m` (> 0): the vote cell. `window`: a prior, or nullptr (any yaw
/// and translation). The returned list is sorted by decreasing votes (ties: lower yaw index).
/// Throws InvalidArgument on invalid options, fewer than 3 points on a side, a non-finite point,
/// a zero up axis, a non-positive cell, or an invalid window.
std::vector<YawHypothesis> yaw_vote_hypotheses(const Points3& source_points,
                                               const Points3& target_points, const Vec3& up_source,
                                               const Vec3& up_target, double cell_m,
                                               const YawVoteOptions& options,
                                               const PoseWindow* window = nullptr);

/// Settings of local_vote(): a window about a candidate pose, and its resolution.
struct LocalVoteOptions {
  double yaw_half_width_rad = 0.0;  ///< >= 0
  double yaw_step_rad = 0.0;        ///< > 0
  double half_width_m = 0.0;        ///< > 0: translations within this of the candidate's
  double cell_m = 0.0;              ///< > 0
  std::size_t neighbours = 48;      ///< target landmarks examined per source landmark, >= 1
};

/// A finer vote about a candidate pose T0: for each yaw in the window (about the up axis through
/// T0 * source_centre), the source landmarks `points` moved by T0 and that yaw vote for the
/// translations towards their nearest target landmarks (within the window) in cells of cell_m
/// (3x3x3 peaks). Returns the window's best pose and its votes (0 and T0 when nothing voted).
/// `target_tree`: the target landmarks. Deterministic.
YawHypothesis local_vote(const Points3& points, const KdTree& target_tree, const Vec3& up,
                         const Vec3& source_centre, const Isometry3& T0,
                         const LocalVoteOptions& options);

/// The rotation taking unit vector `from` onto unit vector `to` by the smallest angle (about
/// from x to; a half turn about any perpendicular axis when they are opposite).
Mat3 rotation_between(const Vec3& from, const Vec3& to);

}  // namespace lmalign
