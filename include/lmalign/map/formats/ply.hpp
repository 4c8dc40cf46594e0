// Landmark maps as PLY point clouds (Open3D, MeshLab, CloudCompare): vertices with optional
// per-vertex covariance properties. docs/map-format.md, "PLY".
#pragma once

#include <istream>
#include <string>

#include "lmalign/map/map.hpp"

namespace lmalign {

/// Reads the `vertex` element of a PLY file (format ascii 1.0 or binary_little_endian 1.0) as
/// landmarks: id = vertex index, position from the x, y, z properties (metres), covariance from
/// the six properties cov_xx cov_xy cov_xz cov_yy cov_yz cov_zz (m^2) when all six are present
/// (then it must be finite, symmetric by construction, and positive semi-definite within
/// 1e-9 of its largest eigenvalue), else covariance_unknown. A uchar/int property
/// covariance_known equal to 0 also flags the vertex (as write_ply_map writes it). PLY holds no
/// frames and no observations. Other properties and elements are skipped (list properties
/// included); elements after `vertex` are not read.
/// Throws ParseError naming the file and the line (header, ASCII body) or "byte N" (binary body)
/// and what was expected: not a PLY, an unsupported format (big-endian) or type, a missing x/y/z,
/// a partial covariance, a vertex count that the rest of the file cannot hold (refused before
/// allocating), truncation, a non-finite value, a list property in `vertex`; IoError if
/// unreadable.
Map read_ply_map(const std::string& path);
/// Same, from a stream; `name` is used in error messages.
Map read_ply_map(std::istream& in, const std::string& name);

/// Writes the landmarks of `map` as an ASCII PLY, atomically: per vertex x y z (double, metres),
/// num_observations (int), cov_xx cov_xy cov_xz cov_yy cov_yz cov_zz (double, m^2) and
/// covariance_known (uchar, 0 for covariance_unknown landmarks, whose covariance is written as 0).
/// Values in shortest round-trip form, so read_ply_map gives back positions and covariances
/// bit-exactly. Frames and observations are not written. Throws IoError on write failure.
void write_ply_map(const std::string& path, const Map& map);

}  // namespace lmalign
