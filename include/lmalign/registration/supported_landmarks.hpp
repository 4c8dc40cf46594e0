// The landmarks of an alignment within the supported range (core/supported_range.hpp): what
// align() (presets.hpp) aligns when a map holds landmarks beyond it.
#pragma once

#include <cstddef>
#include <optional>

#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/seams.hpp"

namespace lmalign {

/// Both sides of an alignment without their landmarks beyond the supported range.
struct SupportedLandmarks {
  /// A copy of the source without them (positions and covariances); only when some were left out.
  std::optional<SourceLandmarks> source;
  /// A copy of the target without them (points, every kind of weight it has, covariances and
  /// the up axis); only when some were left out.
  std::optional<PreparedTarget> target;
  std::size_t source_left_out = 0;
  std::size_t target_left_out = 0;
};

/// Leaves out the landmarks of `source` and `target` that are finite but beyond the supported
/// range. Covariances of the source are kept in step when there is one per position. The rest is
/// unchanged (the weights are per landmark). Throws InvalidArgument, naming the side and the
/// landmark, for a non-finite landmark (corrupt input, not a far landmark), and when every
/// landmark of a side is beyond the range (there is then nothing left to align).
SupportedLandmarks keep_supported_landmarks(const SourceView& source, const PreparedTarget& target);

}  // namespace lmalign
