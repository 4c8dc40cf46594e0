// Yaw-invariant neighbourhood descriptors of landmarks (issue 39, item 1; reused by the merge's
// map retrieval, issue 37). A landmark's descriptor is a histogram of its neighbours within a
// radius: 4 bins of horizontal distance x 5 bins of height along the map's up axis, filled by
// soft (bilinear) assignment between bin centres, normalised and square-rooted (the Hellinger
// embedding, so that Euclidean distance compares them). It does not change under a rotation
// about the up axis or any translation; with the radius measured on each map's own spacing
// (descriptor_radius), it does not change with the map's scale either.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/search/kdtree.hpp"

namespace lmalign {

/// Floats per descriptor (without the optional viewing elevation).
constexpr int kLandmarkDescriptorDims = 20;

/// Floats per oriented descriptor (describe_landmark_oriented): 3 radial x 4 height x 8 azimuth
/// bins.
constexpr int kOrientedDescriptorDims = 96;

/// The median, over the landmarks `sample` (indices into `points`), of the distance to the
/// `neighbours`-th nearest other landmark (metres; 0 without samples or for fewer than 2
/// landmarks). `tree` is built over exactly `points`. Deterministic.
double descriptor_radius(const Points3& points, const KdTree& tree, std::size_t neighbours,
                         const std::vector<std::uint32_t>& sample);

/// Writes landmark i's descriptor into out[0, kLandmarkDescriptorDims), plus, when
/// `view_direction` is given (unit, or zero where unknown), elevation_weight times its
/// component along `up` into out[kLandmarkDescriptorDims]. Counts the landmarks within
/// `radius_m` among its `max_neighbours` nearest (`tree` over exactly `points`); returns false
/// (out zeroed) when fewer than 4 lie within it. `up`: unit, the map's frame.
bool describe_landmark(const Points3& points, const KdTree& tree, std::size_t i, const Vec3& up,
                       double radius_m, std::size_t max_neighbours, float* out,
                       const Vec3* view_direction = nullptr, float elevation_weight = 0.5f);

/// The oriented descriptor of landmark i (issue 39): its neighbourhood in a frame of its own,
/// the map's up axis and the horizontal part of the landmark's mean viewing direction, which is
/// what a SLAM map knows beyond the points. A histogram of the neighbours within `radius_m`:
/// 3 bins of horizontal distance x 4 of height x 8 of azimuth from that direction, each soft
/// (bilinear; azimuth circular), the counts normalised and square-rooted (Hellinger), into
/// out[0, kOrientedDescriptorDims). It does not change under a rotation about the up axis or
/// any translation (the viewing direction turns with the map); it does change when the two maps
/// saw the landmark from other sides: forward-looking cameras on a road agree within a median
/// 5-7 deg, a camera orbiting a desk within 16-80 deg (measured at the true correspondences,
/// docs/accuracy.md). Returns false (out zeroed) when the viewing direction is unknown or within
/// 12 deg of the up axis (its horizontal part under 0.2), or when fewer than 4 other landmarks
/// lie within `radius_m`. `tree` is built over exactly `points`; `up` and `view_direction` unit,
/// the map's frame; `scratch` any vector (reused between calls).
bool describe_landmark_oriented(const Points3& points, const KdTree& tree, std::size_t i,
                                const Vec3& up, const Vec3& view_direction, double radius_m,
                                float* out, std::vector<PointIndex>* scratch);

}  // namespace lmalign
