// 4x4 rigid-transform text files (ground truth, results): four rows of four numbers, row-major,
// last row 0 0 0 1. Blank lines and '#' comments are ignored.
#pragma once

#include <string>

#include "lmalign/core/similarity.hpp"
#include "lmalign/core/types.hpp"

namespace lmalign {

/// Reads a 4x4 rigid transform. Throws ParseError (file, line, what was expected) on a wrong
/// count of rows or numbers, a non-numeric or non-finite value, a last row other than 0 0 0 1, or
/// a rotation block that is not orthonormal with det +1 (tolerance 1e-6); IoError if unreadable.
Isometry3 read_transform(const std::string& path);

/// Reads a 4x4 similarity [sR t; 0 0 0 1] (a rigid transform is one with s = 1), the file
/// format as read_transform. Throws ParseError as read_transform, and naming the file when the
/// scale (cube root of the 3x3 block's determinant) is not finite and > 0 or the 3x3 block is
/// neither a rotation nor a scaled rotation (core/similarity.hpp).
Similarity3 read_similarity(const std::string& path);
/// Writes T atomically in the same format (full round-trip precision).
void write_transform(const std::string& path, const Isometry3& T);

}  // namespace lmalign
