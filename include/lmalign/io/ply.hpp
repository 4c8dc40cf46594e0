// Point clouds as PLY (ASCII), for viewers such as MeshLab or CloudCompare.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"

namespace lmalign {

/// Writes `points` (metres) as an ASCII PLY, atomically. `rgb`, if non-empty, holds one colour per
/// point. Throws InvalidArgument if rgb's size differs, IoError if the file cannot be written.
void write_ply(const std::string& path, const Points3& points,
               const std::vector<std::array<std::uint8_t, 3>>& rgb = {});

}  // namespace lmalign
