// COLMAP sparse models (cameras, images, points3D; text or binary), as written by COLMAP's
// model_converter / Reconstruction::WriteText / WriteBinary (colmap/src/colmap/scene/
// reconstruction_io.cc), and hloc / GLOMAP which write the same files. docs/map-format.md.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "lmalign/map/map.hpp"

namespace lmalign {

struct ColmapReadOptions {
  /// Largest accepted | |q| - 1 | of an image quaternion.
  double quaternion_norm_tolerance = 1e-3;
  /// Largest accepted image width or height, pixels (absurd sizes are refused).
  long long max_image_size_px = 1000000;
};

/// Reads the COLMAP model in folder `dir` (binary: cameras.bin, images.bin, points3D.bin; text:
/// the same names with .txt). Each registered image becomes a Frame (id = IMAGE_ID) whose pose
/// is the inverse of COLMAP's world-to-camera (QW QX QY QZ, TX TY TZ): q_world_camera is the
/// conjugate of the normalised quaternion and p_world_camera = -R^T t; its camera (one of
/// SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV) is kept in Frame::camera. Each 3D
/// point becomes a Landmark (id = POINT3D_ID) with one observation per track element, the pixel
/// of that image's POINT2D_IDX (COLMAP pixels: origin at the top-left corner of the image).
/// Landmarks have covariance_unknown set; `mean_reprojection_error_px`, if given, receives each
/// point's stored ERROR (pixels), in landmark order.
/// Throws ParseError naming the file and line (text) or byte offset (binary, written as the
/// "line" 0 with "byte N" in the detail) and what was expected: truncation, a wrong number of
/// fields or parameters, a non-finite value, an unknown camera model, a quaternion far from
/// unit norm, an image of an unknown camera, a track element of an unknown image or a
/// POINT2D_IDX out of range, a 2-D point naming an unknown 3-D point, a duplicate id, or a count
/// the file size cannot hold (refused before allocating). IoError if a file cannot be read.
Map read_colmap(const std::string& dir, bool binary, const ColmapReadOptions& options = {},
                std::vector<double>* mean_reprojection_error_px = nullptr);

/// The three files of a model in memory: contents and the names used in error messages, in the
/// order cameras, images, points3D.
struct ColmapFiles {
  std::array<std::string, 3> contents;
  std::array<std::string, 3> names = {"cameras", "images", "points3D"};
};
/// Same as read_colmap(dir, ...), from the files' contents (no file system access).
Map read_colmap(const ColmapFiles& files, bool binary, const ColmapReadOptions& options = {},
                std::vector<double>* mean_reprojection_error_px = nullptr);

/// Writes `map` as a COLMAP text model (cameras.txt, images.txt, points3D.txt) into folder
/// `dir` (created if missing), each file atomically. One camera per frame (CAMERA_ID = frame
/// id): the frame's own intrinsics, or `fallback` as PINHOLE with the image size
/// (2 cx, 2 cy) rounded up. POINT2D entries are the landmarks' observations; ERROR is written
/// as 0 (unknown) and the colour as 128 128 128. Throws InvalidArgument if map.validate() fails
/// or a frame's intrinsics are invalid, IoError on write failure.
void write_colmap_text(const std::string& dir, const Map& map,
                       const PinholeIntrinsics& fallback = PinholeIntrinsics::tum_fr1());

}  // namespace lmalign
