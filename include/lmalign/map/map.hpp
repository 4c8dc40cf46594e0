// The landmark map model of a feature-based visual SLAM session (method.md §1).
//
// A Map holds frames (keyframe poses) and landmarks (3-D points with a position covariance and
// the pixel observations that made them). Everything is expressed in one world frame, the
// map's own; positions in metres (or in the map's own unit when its header says its scale is
// arbitrary), covariances in m^2, pixels in raw (undistorted-free) pixels.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/map/camera_model.hpp"

namespace lmalign {

/// A keyframe. Its pose is camera-to-world: p_world = T_world_camera() * p_camera.
struct Frame {
  Id id = 0;
  /// Rotation camera-to-world, as read from the file (w x y z). Not re-normalised on load so that
  /// a read/write round trip is exact; use T_world_camera() for a proper rotation.
  Quat q_world_camera = Quat::Identity();
  /// Camera centre in the world frame, metres.
  Vec3 p_world_camera = Vec3::Zero();
  /// Intrinsics of this image, when the file stores them (COLMAP, Bundler); our own text format
  /// does not (nullopt). Observations of this frame are raw pixels of this camera.
  std::optional<CameraIntrinsics> camera;

  /// The rigid pose camera-to-world, with the quaternion normalised.
  Isometry3 T_world_camera() const;
};

/// One pixel measurement of a landmark in a frame.
struct Observation {
  Id frame_id = 0;
  double u_px = 0.0;  ///< column, pixels, raw (no undistortion), origin at the image's top-left
  double v_px = 0.0;  ///< row, pixels
};

/// A 3-D landmark.
struct Landmark {
  Id id = 0;
  /// Position in the world frame, metres.
  Vec3 p_world = Vec3::Zero();
  /// 3x3 position covariance in the world frame, m^2; symmetric positive semi-definite.
  Mat3 cov_world_m2 = Mat3::Zero();
  /// True when no covariance could be estimated (one view, too little parallax, failed
  /// triangulation: docs/map-format.md). cov_world_m2 is then zero and means nothing; it is never
  /// a made-up number. Always false for maps read from our own text format.
  bool covariance_unknown = false;
  /// Observations, in file order.
  std::vector<Observation> observations;

  std::size_t num_observations() const { return observations.size(); }
};

/// Whether a map's lengths are metres.
enum class MapScale {
  /// Metres: RGB-D and stereo SLAM (stella_vslam's Stereo and RGBD setups, our VO builder), and
  /// our own map text format unless its header says otherwise.
  kMetric,
  /// One unknown scale of its own: monocular SLAM (stella_vslam's Monocular setup) and structure
  /// from motion (COLMAP, Bundler). Two such maps of one place differ by a similarity.
  kArbitrary,
  /// The file does not say (a point cloud from another tool).
  kUnknown,
};
inline constexpr EnumName<MapScale> kMapScaleNames[] = {{MapScale::kMetric, "metric"},
                                                        {MapScale::kArbitrary, "arbitrary"},
                                                        {MapScale::kUnknown, "unknown"}};

/// "metric", "arbitrary", "unknown".
std::string map_scale_name(MapScale scale);
/// The scale of a name above, or nullopt.
std::optional<MapScale> map_scale_from_name(const std::string& name);

/// What a map says about itself (docs/map-format.md, "The MAP record").
struct MapHeader {
  /// Whether its lengths are metres: our text format's `MAP scale ...` (metric without one),
  /// arbitrary for COLMAP and Bundler, stella_vslam's setup_type, PLY's `obj_info lmalign_scale`
  /// (unknown without one).
  MapScale scale = MapScale::kMetric;
  /// True when the landmark covariances are not measurements but assumed: isotropic, from the
  /// landmarks' local spacing (assume_covariances_from_spacing(); point clouds without
  /// covariances). Aligners that weigh by covariance say so in their result.
  bool covariance_assumed = false;

  bool operator==(const MapHeader& other) const {
    return scale == other.scale && covariance_assumed == other.covariance_assumed;
  }
  bool operator!=(const MapHeader& other) const { return !(*this == other); }
};

/// A landmark map: frames and landmarks in one world frame.
///
/// Invariants kept by the reader (and checked by validate()): ids are unique within frames and
/// within landmarks, and every observation refers to a frame of the map.
class Map {
 public:
  MapHeader header;
  std::vector<Frame> frames;
  std::vector<Landmark> landmarks;

  /// Index of the frame with this id, or nullopt. O(1) after the first call (lazy index).
  /// The index is rebuilt if `frames` changed size; call invalidate_index() after other edits.
  std::optional<std::size_t> frame_index(Id id) const;
  const Frame* find_frame(Id id) const;
  void invalidate_index() const { frame_index_.clear(); }

  /// Landmark positions in the world frame (N x 3 as a vector of Vec3, metres), in landmark order.
  Points3 positions() const;
  /// Landmark position covariances in the world frame (m^2), in landmark order.
  std::vector<Mat3> covariances_m2() const;
  /// Each landmark's mean viewing direction in the world frame, in landmark order: the mean of
  /// the unit vectors from the centres of the frames that observed it to the landmark, normalised
  /// (unit, dimensionless). The zero vector where it says nothing: no observation of a known
  /// frame, a landmark at a camera centre, or rays so spread that their mean is shorter than
  /// kMinViewConcentration (seen from all around). What a SLAM map knows beyond a point cloud:
  /// the Mahalanobis gate pairs two landmarks only when they were seen from compatible
  /// directions (stages/mahalanobis_gate.hpp, match.max_view_angle_deg).
  std::vector<Vec3> view_directions() const;
  /// Below this length of the mean unit ray, a landmark's viewing direction is zero (unknown).
  static constexpr double kMinViewConcentration = 0.5;

  /// Throws InvalidArgument if an id is negative or duplicated, an observation names an unknown
  /// frame, a value is not finite, or a frame quaternion is zero. The message names the id.
  void validate() const;

 private:
  mutable std::unordered_map<Id, std::size_t> frame_index_;
};

/// Applies T_new_old to every landmark (position and covariance) and every frame pose of `map`,
/// giving the map expressed in frame `new`. Observations and the header are unchanged
/// (observations are camera-relative).
Map transform_map(const Map& map, const Isometry3& T_new_old);

/// Gives every landmark of `map` an assumed isotropic covariance from its local spacing, for
/// point clouds that store none: sigma_i = d_i / 2, with d_i the median distance from landmark i
/// to its `k` nearest other landmarks (the half-spacing floor of the adaptive default's
/// DataScales, per landmark). A d_i of 0 (duplicates) takes the median of the positive d_i.
/// Sets covariance_unknown = false on every landmark and header.covariance_assumed = true.
/// Throws InvalidArgument if the map has fewer than 2 landmarks, a non-finite position, or all
/// its landmarks at one point (no spacing), or if k is 0.
void assume_covariances_from_spacing(Map& map, std::size_t k = 6);

}  // namespace lmalign
