// Bare point clouds as XYZ text, one point per line (CloudCompare, PDAL, MeshLab and many
// scanners' ".xyz" / ".txt" exports). docs/map-format.md, "XYZ text".
#pragma once

#include <istream>
#include <string>

#include "lmalign/map/map.hpp"

namespace lmalign {

/// Reads an XYZ text point cloud as landmarks: every line that is not blank and does not start
/// with '#' (after blanks) holds `x y z` (metres, or the cloud's own unit) and optionally more
/// numbers (colour, normal, intensity, ...), which are skipped; fields are separated by blanks,
/// tabs or a comma. Every line must have as many fields as the first. Landmark ids are the
/// 0-based point indices; there are no frames, no observations and no covariances
/// (covariance_unknown on every landmark; read_any_map() assumes them from the spacing). The
/// header's scale is unknown. Lines end in LF or CRLF.
/// Throws ParseError(file, line, what was expected) for a line with fewer than 3 fields, a field
/// count that differs from the first line's, a field that is not a finite number; IoError if
/// unreadable.
Map read_xyz_map(const std::string& path);
/// Same, from a stream; `name` is used in error messages.
Map read_xyz_map(std::istream& in, const std::string& name);

/// True if `line` (one record of a text file) reads as an XYZ point: 3 or more fields, all
/// finite numbers, separated as above. detect_map_format() uses it on the first record.
bool is_xyz_record(const std::string& line);

}  // namespace lmalign
