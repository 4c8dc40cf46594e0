// The one C++ function behind lmalign.align() (docs/python.md): what `lmalign align --strategy
// NAME` does for one strategy (apps/lmalign/cmd_align.cpp): align(preset, ...)
// (registration/presets.hpp), so that Python's result equals the CLI's bit for bit.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/registration.hpp"

namespace lmalign::python {

/// The options of one alignment, as `lmalign align` takes them. An unset optional is an option
/// not given on the command line (then each preset keeps its own). The library's request
/// (registration/presets.hpp: the guess, the prior, k, the limits, settings= as the CLI's --set,
/// the scale mode), and what Python's align() adds to it.
struct AlignRequest : lmalign::AlignRequest {
  std::string strategy;  ///< a preset name or a preset file; empty: the recommended one
  /// The source's up axis (source frame), from a Map's frames.
  std::optional<Vec3> source_up;
  /// What each Map's header says (scale, assumed covariances), for AlignRequest::describe_maps;
  /// an array keeps the default header (metric, covariances measured).
  MapHeader source_header;
  MapHeader target_header;
  /// OpenMP threads for this call (0: OpenMP's default). Results do not depend on it.
  int threads = 0;
};

/// The result, as align() gives it (as the CLI).
struct AlignOutcome {
  std::string strategy;
  Summary summary;
  /// When run_alignment() began and ended (alignment and trust verdict), seconds of
  /// std::chrono::steady_clock: CLOCK_MONOTONIC on Linux, the clock of Python's
  /// time.monotonic(). Lets callers see what ran at the same time.
  double started_s = 0.0;
  double finished_s = 0.0;
};

/// Runs the preset through align() with the limits and settings as the CLI passes them.
/// `source_covariances_m2` and `source_view_directions` (unit, source frame, zero where unknown:
/// Map::view_directions()) may be empty. Throws InvalidArgument (bad strategy name, setting or
/// option; a prior for a preset whose initialiser uses none) and what align() throws.
/// Does not touch Python: the caller releases the GIL around it.
AlignOutcome run_alignment(const Points3& source_points,
                           const std::vector<Mat3>& source_covariances_m2,
                           const std::vector<Vec3>& source_view_directions,
                           const PreparedTarget& target, const AlignRequest& request);

}  // namespace lmalign::python
