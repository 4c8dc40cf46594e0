// The range of numbers lmalign supports (docs/robustness.md, "Supported range"), and the one
// check of it that every alignment goes through: align() of presets.hpp (the CLI's `align`, the
// Python package, the merge's edges and the experiment runner's own strategies), the merge
// manifest, and the options of the CLI and of Python.
//
// One bound for every magnitude: 1e15, in metres for landmark coordinates, translations (initial
// guesses, prior poses, displacements) and translation standard deviations, in degrees for
// displacement angles and rotation standard deviations. A double still resolves 0.125 m at 1e15 m,
// and every intermediate of the pipelines (squared distances, vote cells, Mahalanobis gates,
// products of a sigma and a lever arm) stays many orders of magnitude below overflow. Standard
// deviations are also at least 1e-9 (m, degrees): the square of a smaller one, its variance,
// leaves the doubles' normal range and its inverse, the information, nears overflow.
//
// What happens beyond it:
//   - a finite landmark (a stereo landmark triangulated at near-zero disparity lands at fx b / d,
//     easily 1e9 m or more, in an otherwise good map) is left out of the alignment: align() of
//     presets.hpp counts the landmarks left out on each side (Summary::source_left_out,
//     target_left_out) and appends left_out_message() to the trust reason. The rest of the map
//     is aligned as usual. Landmarks that are far but within the range are kept: they simply find
//     no partner. A non-finite one (NaN, inf) is corrupt input: refused like any bad input (the
//     map readers refuse them; align() of presets.hpp names the side and the landmark).
//   - an option, an initial guess, a prior or a displacement is refused: InvalidArgument naming
//     it and its value, one line (check_supported_translation(), check_supported_magnitude()).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"

namespace lmalign {

/// Largest |coordinate| of a landmark and of a translation, and largest translation standard
/// deviation, metres.
inline constexpr double kMaxCoordinateM = 1e15;
/// Largest |angle| of a displacement and largest rotation standard deviation, degrees.
inline constexpr double kMaxAngleDeg = 1e15;
/// Smallest standard deviation of a prior: metres for a translation, degrees for a rotation.
inline constexpr double kMinSigma = 1e-9;

/// True when every coordinate of `p` is finite and at most kMaxCoordinateM in magnitude.
bool within_supported_range(const Vec3& p);

/// Indices (ascending) of the points that are not within_supported_range().
std::vector<std::size_t> beyond_supported_range(const Points3& points);

/// Throws InvalidArgument("<what>: translation (x, y, z) m is beyond the supported range
/// (|coordinate| <= 1e+15 m)") unless every coordinate of `t_m` is within it (finite included).
void check_supported_translation(const std::string& what, const Vec3& t_m);

/// Throws InvalidArgument("<what>: <value> <unit> is beyond the supported range (|value| <=
/// <bound> <unit>)") unless `value` is finite and |value| <= `bound`.
void check_supported_magnitude(const std::string& what, double value, double bound,
                               const std::string& unit);

/// Throws InvalidArgument("<what>: <value> <unit> is outside the supported range of a standard
/// deviation ([1e-09, 1e+15] <unit>)") unless kMinSigma <= value <= `max` (kMaxCoordinateM for
/// metres, kMaxAngleDeg for degrees, or those in other units).
void check_supported_sigma(const std::string& what, double value, double min, double max,
                           const std::string& unit);

/// The note for landmarks left out of an alignment, e.g. "1 source landmark beyond the
/// supported range (|coordinate| > 1e+15 m) left out"; empty when both counts are 0.
std::string left_out_message(std::size_t source_left_out, std::size_t target_left_out);

}  // namespace lmalign
