// stella_vslam / OpenVSLAM map databases (`.msg`): the MessagePack file written by
// stella_vslam's map_database_io_msgpack (its map as JSON, encoded with
// nlohmann::json::to_msgpack). docs/map-format.md, "stella_vslam / OpenVSLAM".
#pragma once

#include <string>
#include <string_view>

#include "lmalign/map/map.hpp"

namespace lmalign {

/// Reads a stella_vslam / OpenVSLAM map database. Uses:
///   cameras.<name>: model_type "perspective", cols, rows, fx, fy, cx, cy, k1, k2, p1, p2, k3
///     -> PINHOLE (no distortion) or OPENCV (k3 must be 0: our OPENCV model has none);
///   keyframes.<id>: cam (a camera name), rot_cw (quaternion x y z w, world-to-camera), trans_cw
///     (world-to-camera), keypts (raw keypoints, {pt: [x, y]}) and lm_ids (one landmark id per
///     keypoint, -1 for none) -> a Frame (id = <id>) whose pose is the inverse of (rot_cw,
///     trans_cw), and one observation per keypoint with a landmark, at its raw pixel;
///   landmarks.<id>: pos_w -> a Landmark (id = <id>), observations from the keyframes' lm_ids.
/// Frames and landmarks are in increasing id order; a landmark's observations in keyframe order.
/// Other fields are ignored. Landmarks have covariance_unknown set (read_any_map derives them).
/// Throws ParseError: "<file>: byte N: ..." for bytes that are not one complete MessagePack
/// value (truncation included: nlohmann's decoder, which reads as it goes and so allocates no
/// more than the input holds), and "<file>: <record>: ..." naming the keyframe, landmark or
/// camera and the field, and what was expected, for a missing field, a wrong type or count
/// (keypts vs lm_ids), a non-finite number, an unknown camera model, a quaternion far from unit
/// norm (1e-3), or a dangling camera or landmark id. IoError if the file cannot be read.
Map read_stella_vslam(const std::string& path);
/// Same, from the file's bytes; `name` is used in error messages.
Map read_stella_vslam_bytes(std::string_view bytes, const std::string& name);

}  // namespace lmalign
