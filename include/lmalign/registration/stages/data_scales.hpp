// Scales read off the data, so that no registration constant is tuned to one scene
// (docs/accuracy.md, "The adaptive default"). A desk map has landmarks millimetres apart and
// covariances of millimetres; an outdoor stereo map has landmarks decimetres apart and
// covariances of metres along the viewing rays. Every metric setting of the adaptive pipeline is
// a multiple of one of these.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

/// What the adaptive pipeline needs to know of a landmark map's size and noise.
struct DataScales {
  /// Median distance from a landmark to its nearest other landmark, metres (> 0).
  double spacing_m = 0.0;
  /// Covariance floor, metres: the median over landmarks of the smallest-axis standard deviation
  /// sqrt(lambda_min(C)) when the map carries covariances, else half the spacing. Added as
  /// floor^2 I to every pair's combined covariance (unmodelled noise, and maps without
  /// covariances). > 0.
  double floor_m = 0.0;
  /// Median distance of the landmarks from `centre_m`, metres (the map's size; > 0).
  double radius_m = 0.0;
  /// The median of the landmark positions along their principal axes (the scatter's
  /// eigenvectors about the mean; for an even count the mean of the two middle values), metres,
  /// in the map's frame: it turns and moves with the map, as the coordinate-wise median did not.
  Vec3 centre_m = Vec3::Zero();
  /// The map's typical landmark standard deviation, metres: the median over landmarks of the
  /// geometric mean of their covariance's axes, det(C)^(1/6) (an isotropic C = s^2 I gives s).
  /// 0 when the map carries no covariances (has_covariances false). Scales::evidence uses it.
  double sigma_m = 0.0;
  /// True when at least half of the landmarks have a non-zero covariance.
  bool has_covariances = false;
};

/// Measures the scales of a landmark set: `points` (N x 3, metres) and, optionally, one 3x3
/// covariance per point (m^2, same frame; nullptr or empty = none). At most `max_samples`
/// landmarks (evenly strided) enter the spacing and floor medians. `tree`, optional: a kd-tree
/// already built over exactly `points` (e.g. PreparedTarget::tree()), used instead of building
/// one; the result is the same. Deterministic.
/// Throws InvalidArgument for fewer than 2 points, a non-finite point, or covariances whose
/// count differs from the points'. Coincident landmarks (zero spacing) give the smallest
/// positive spacing among the samples, or 1e-6 m if all coincide.
DataScales estimate_data_scales(const Points3& points, const std::vector<Mat3>* covariances_m2,
                                std::size_t max_samples = 4096, const KdTree* tree = nullptr);

/// The up (anti-gravity) direction of a SLAM or SfM map in its own frame, from its frames
/// (keyframe poses T_world_camera; cameras with x right, y down, z forward, as in the map file):
/// people and vehicles rarely roll a camera, so its x axis is nearly horizontal. The up axis is
/// taken in the span of the directions that every frame's x axis is nearly orthogonal to
/// (eigenvalues of the mean x x^T below 0.05, i.e. about 13 degrees), as the direction there
/// nearest the mean of the frames' -y axes (which fixes the sign, and the direction when the
/// camera only moved straight ahead). Returns nullopt for fewer than 2 frames, or when no
/// direction is orthogonal to the x axes (a camera rolled through all angles).
/// Its accuracy on a hand-held and a car-mounted camera: docs/accuracy.md.
std::optional<Vec3> estimate_up_axis(const Map& map);

/// A second opinion on the up axis, from the landmarks themselves: the normal of their
/// best-fitting plane (the eigenvector of the smallest eigenvalue of their scatter), when they are
/// planar enough (smallest eigenvalue at most `max_flatness` times the middle one), oriented to
/// make an acute angle with `up_hint`. Most maps are dominated by a horizontal surface (a floor,
/// a desk, a road), and this cue needs no camera assumption: a hand-held camera rolls, which
/// makes estimate_up_axis() unreliable on a short window (both compared: docs/accuracy.md).
/// `points`: N x 3, metres. At most `max_samples` (evenly strided) enter. Returns nullopt for
/// fewer than 3 points, non-finite points, or a scatter that is not planar enough.
std::optional<Vec3> landmark_plane_normal(const Points3& points, const Vec3& up_hint,
                                          double max_flatness = 0.25,
                                          std::size_t max_samples = 4096);

/// A third cue to the up axis: the normal of the map's dominant plane within max_angle_deg of
/// `up_hint` (a floor, a desk, a road; walls are farther from the hint), found by RANSAC over
/// point triplets (256 seeded draws; landmarks within `threshold_m` of the plane are its
/// inliers) and refitted to its inliers, oriented like the hint. The best-fitting plane of all
/// landmarks (landmark_plane_normal) leans with the clutter on a desk; the dominant plane does
/// not. `points`: N x 3, metres; at most `max_samples` (evenly strided) enter. Returns nullopt
/// when fewer than a tenth of them lie on one plane, or for invalid input. Deterministic.
std::optional<Vec3> dominant_plane_normal(const Points3& points, const Vec3& up_hint,
                                          double threshold_m, double max_angle_deg = 60.0,
                                          std::size_t max_samples = 2000);

}  // namespace lmalign
