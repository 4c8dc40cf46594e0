// Selection and gating with the landmark covariances of both maps (the individual compatibility
// test of SLAM data association): a source landmark is paired with the one of its k Euclidean
// nearest target landmarks, seen from a compatible direction, whose Mahalanobis distance
//   d^2 = r^T S^-1 r,  r = q_t - T p_s,
//   S = C_t + R C_s R^T + (floor^2 + sigma_t^2 + sigma_r^2 |T p_s - pivot|^2) I
// is smallest, and the pair is kept when d^2 < chi2_threshold (a chi-square test with 3 degrees of
// freedom). C_t and C_s are the landmarks' covariances, `floor` the data's covariance floor
// (DataScales), and sigma_t, sigma_r an isotropic stand-in for the uncertainty of the current
// pose estimate (translation, metres; rotation about `pivot`, radians): while the pose is only
// roughly known the gate is wider, and it narrows to the landmarks' own covariances as the
// estimate settles. "Seen from a compatible direction": the angle between the landmarks' mean
// viewing directions (Map::view_directions(); the source's rotated by T) is at most
// max_view_angle_deg. A feature-based SLAM map holds a landmark only where its cameras saw it;
// two maps that observed one place saw it from roughly one side (on the real desk windows a
// median 28-36 deg apart, at most 4% beyond 90 deg), while a pose turned to the wrong side
// pairs landmarks seen from opposite sides (22-55% beyond 90 deg at the desk's 137-171 deg
// rivals: issue 39). Euclidean gates (a maximum correspondence distance in metres) are what the
// paper and lmalign's earlier strategies use; a fixed one is desk-sized or road-sized, this one
// follows the data.
//
// Frames: source points and covariances in the source frame, T = T_target_source, everything
// else in the target frame. Deterministic for any thread count (one slot per source landmark).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/registration.hpp"

namespace lmalign {

/// chi-square quantile of 3 degrees of freedom at probability 0.99.
inline constexpr double kChi2Dof3P99 = 11.344866730144373;

/// Settings of the gate. Plain struct; check with is_valid().
struct MahalanobisGateOptions {
  /// Euclidean nearest target landmarks examined per source landmark, [1, 64].
  int k = 5;
  /// Gate on d^2 (dimensionless), > 0. Default: chi-square, 3 dof, 0.99.
  double chi2_threshold = kChi2Dof3P99;
  /// Largest angle between the two landmarks' mean viewing directions (the source's rotated
  /// into the target frame) for them to be paired, degrees, in (0, 180]; 180 turns the test
  /// off. A landmark whose direction is unknown (zero, or no directions at all) passes.
  double max_view_angle_deg = 90.0;
  bool is_valid(std::string* why = nullptr) const;
};

/// The isotropic pose-uncertainty term of the gate (see the file comment).
struct PoseSigma {
  double translation_m = 0.0;   ///< >= 0
  double rotation_rad = 0.0;    ///< >= 0
  Vec3 pivot_m = Vec3::Zero();  ///< target frame
};

/// A kept pair.
struct GatedPair {
  std::uint32_t source_index = 0;
  std::uint32_t target_index = 0;
  double d2 = 0.0;                     ///< Mahalanobis distance squared at the current estimate
  Vec3 moved_source_m = Vec3::Zero();  ///< T p_s, target frame
  Mat3 information = Mat3::Zero();     ///< S^-1, 1/m^2
  /// det(C_t / e_t^2 + R C_s R^T / e_s^2 + (f_t^2 / e_t^2 + f_s^2 / e_s^2) I), dimensionless:
  /// the pair's own combined covariance (without the pose-uncertainty term), each map's part
  /// in units of that map's evidence scale e (EvidenceScales; f its floor). Its sixth root is
  /// the pair's vagueness (pair_evidence). 0: not recorded (no EvidenceScales), counts fully.
  double evidence_det = 0.0;
};

/// Each map's evidence scale, in its own units (Scales::evidence()): the standard deviation up
/// to which a pair's landmarks count fully in the gated score (pair_evidence), and each map's
/// covariance floor. Because each map's covariances are measured against its own scale, a
/// pair's weight does not change when either map is rescaled (a free scale). All > 0 to weigh;
/// else (the default) no pair's evidence is recorded and every pair counts fully.
struct EvidenceScales {
  double source_m = 0.0;
  double target_m = 0.0;
  double floor_source_m = 0.0;
  double floor_target_m = 0.0;
  bool on() const { return source_m > 0.0 && target_m > 0.0; }
};

/// The landmarks of one side as the gate needs them. `covariances_m2` may be empty (no
/// covariances: only the floor and the pose term remain).
struct GateSide {
  const Points3* points = nullptr;
  const std::vector<Mat3>* covariances_m2 = nullptr;
  /// Unit mean viewing directions (source frame), zero where unknown; null or empty = none.
  const std::vector<Vec3>* view_directions = nullptr;
};

/// The two maps a global search works on (the complete search's and the correspondence
/// search's input): the source landmarks (source frame; covariances and viewing directions may
/// be null or empty), the prepared target (its covariances and viewing directions are used if
/// set), each map's up-axis candidates (unit, each in its own frame, best first; every pair is
/// searched), and the covariance floor, metres (> 0): the smallest position standard deviation
/// assumed.
struct SearchMaps {
  GateSide source;
  const PreparedTarget* target = nullptr;
  std::vector<Vec3> ups_source;
  std::vector<Vec3> ups_target;
  double floor_m = 0.0;
};

/// Each source landmark's nearest target landmarks where it was last searched: the next call
/// takes its k nearest from them without a search when the landmark moved too little for any
/// other target landmark to come nearer (the moved distance against the gap to the nearest one
/// left out), else searches seeded with them (KdTree::knn_seeded). Either way the neighbours are
/// exactly a fresh search's, found faster when the pose moved little, as between two iterations
/// of a refinement. One per refinement; not shared between threads that gate concurrently.
/// Empty = nothing cached yet.
struct GateNeighbourCache {
  /// Source landmark i's cached neighbours at [i width, i width + counts[i]), in the search's
  /// total order at `at_m[i]` (its position in the target frame then, metres); reach_m2[i]: the
  /// squared distance from there of the nearest target landmark not cached (m^2; infinity when
  /// every target landmark is cached).
  std::vector<PointIndex> indices;
  std::vector<std::uint8_t> counts;
  std::vector<double> reach_m2;
  Points3 at_m;
  int k = 0;
  int width = 0;  ///< 2 k, at least 8
};

/// Pairs and gates the source landmarks `subset` (indices into source.points; nullptr = all)
/// against `target` at T_target_source. Writes the kept pairs, in increasing source index, to
/// *pairs. `cache`, optional: seeds the searches with the previous call's neighbours (the result
/// is identical with or without it; GateNeighbourCache). `evidence`, optional: each kept pair's
/// GatedPair::evidence_det is recorded against these scales (null or off: 0, every pair counts
/// fully). Throws InvalidArgument on invalid options, a negative or non-finite floor or sigma, or
/// covariance counts that do not match the points.
void gate_correspondences(const GateSide& source, const PreparedTarget& target,
                          const Isometry3& T_target_source, double floor_m,
                          const PoseSigma& pose_sigma, const MahalanobisGateOptions& options,
                          const std::vector<std::uint32_t>* subset, std::vector<GatedPair>* pairs,
                          GateNeighbourCache* cache = nullptr,
                          const EvidenceScales* evidence = nullptr);

/// One gated pair's evidence, its term of the gated score (dimensionless, in [0, 1]):
/// 1 - d^2 / chi2_threshold times evidence_weight(pair). Issue 39: on simulated streets of
/// 15,000 and 60,000 landmarks (median landmark standard deviation 3-5 m) a pose 40-190 m from
/// the truth outscored it by 5-40% on vague landmarks alone; weighted, the truth scores 1.5-2.4
/// times as much (docs/accuracy.md, "A pair counts what it can tell").
double pair_evidence(const GatedPair& pair, double chi2_threshold);

/// pair_evidence's weight alone, in (0, 1]: min(1, rho^-3), rho = pair.evidence_det^(1/6) the
/// geometric mean of the standard deviations of the pair's own combined covariance, each map's
/// part in units of its evidence scale (EvidenceScales). A gate of standard deviation sigma holds
/// about (sigma / spacing)^3 landmarks of a map by chance, so a pair vaguer than its scale tells
/// that much less. 1 when the determinant was not recorded (0) or is not finite.
double evidence_weight(const GatedPair& pair);

/// The covariance-aware inlier score of an estimate: sum over the gated pairs (zero pose
/// sigma) of their evidence (pair_evidence). Each source landmark adds at most 1, more the
/// better its best target landmark agrees with it under both covariances, and less the vaguer
/// the two are (when the gate recorded their evidence). The overload of maps (below) gates them
/// first without evidence scales (every pair counts fully); it also returns the number of gated
/// pairs in *num_inliers if not null. Same arguments and errors as gate_correspondences.
/// The score of pairs already gated at the estimate (zero pose sigma).
double gated_inlier_score(const std::vector<GatedPair>& pairs,
                          const MahalanobisGateOptions& options);

/// E[d^2 | d^2 < chi2_threshold] for d^2 ~ chi-square with 3 dof: the mean NIS of a gate's
/// inliers when the covariances hold (2.894 at kChi2Dof3P99). Uses
/// P(chi2_5 <= c) = P(chi2_3 <= c) - (c/2)^(3/2) e^(-c/2) / Gamma(5/2), so
/// E = 3 P(chi2_5 <= c) / P(chi2_3 <= c). Throws InvalidArgument unless chi2_threshold > 0 and
/// finite.
double expected_gated_d2(double chi2_threshold);

double gated_inlier_score(const GateSide& source, const PreparedTarget& target,
                          const Isometry3& T_target_source, double floor_m,
                          const MahalanobisGateOptions& options,
                          const std::vector<std::uint32_t>* subset,
                          std::size_t* num_inliers = nullptr);

}  // namespace lmalign
