// Bundler v0.3 `.out` files (Snavely's Bundler; the format of its bundle.out and of GTSAM's
// examples/Data/*.out). docs/map-format.md, "Bundler".
#pragma once

#include <istream>
#include <string>

#include "lmalign/map/map.hpp"

namespace lmalign {

struct BundlerReadOptions {
  /// Image size in pixels, the same for every camera (Bundler stores none; its pixels are
  /// relative to the image centre). Both > 0: pixels from the top-left corner; both 0 (the
  /// default): unknown, the pixels stay centred (CameraIntrinsics::centred_pixels), which
  /// triangulation does not mind (it needs only the focal length) but outputs that store
  /// top-left pixels (our map text format, COLMAP) refuse.
  long long width_px = 0;
  long long height_px = 0;
  /// Largest accepted deviation of R^T R from the identity (max abs entry).
  double rotation_tolerance = 1e-3;
};

/// Reads a Bundler v0.3 file: `# Bundle file v0.3`, `num_cameras num_points`, per camera
/// `f k1 k2`, R (3 rows), t, per point its position, colour and view list
/// `n  camera key x y ...`. Bundler's camera satisfies X_camera = R X_world + t, looks down its
/// -z axis with y up, and its pixels are centred with y up. They are converted to ours:
///   R_camera_world = D R, t = D t with D = diag(1, -1, -1) (z forward, y down), the frame pose
///   T_world_camera its inverse; pixel (x, y) -> (x + w/2, h/2 - y); intrinsics RADIAL
///   (f, w/2, h/2, k1, k2), which with these conventions is Bundler's projection exactly.
///   Without an image size, w = h = 0: pixels (x, -y), RADIAL (f, 0, 0, k1, k2), centred_pixels.
/// The map's scale is arbitrary (MapHeader::scale).
/// Frame ids are the camera indices, landmark ids the point indices. Cameras with f = 0 (not
/// reconstructed by Bundler) are not frames; a view of one is an error. Landmarks have no
/// covariance in the file: covariance_unknown is set on all (read_any_map() derives them).
/// Throws ParseError(file, line, what was expected) on a bad header, a count that the file size
/// cannot hold (refused before allocating), a missing or non-numeric or non-finite value, a
/// rotation that is not orthonormal with det +1, a view of an unknown or unreconstructed camera,
/// or trailing content; InvalidArgument if the image size is negative or only one side is 0;
/// IoError if unreadable.
Map read_bundler(const std::string& path, const BundlerReadOptions& options);
/// Same, from a stream; `name` is used in error messages.
Map read_bundler(std::istream& in, const std::string& name, const BundlerReadOptions& options);

}  // namespace lmalign
