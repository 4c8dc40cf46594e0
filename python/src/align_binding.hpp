// The one C++ function behind lmalign.align() (docs/python.md): what `lmalign align --strategy
// NAME` does for one strategy (apps/lmalign/cmd_align.cpp), so that Python's result equals the
// CLI's bit for bit. Kept alone so that it can be re-pointed at a new registration API in one
// place.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/strategy.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign::python {

/// The options of one alignment, as `lmalign align` takes them. An unset optional is an option
/// not given on the command line (then the paper's strategies use 150 iterations and an
/// unlimited distance, lmalign's own their preset schedule and budget).
struct AlignRequest {
  std::string strategy = to_string(kRecommendedStrategy);
  int k = 5;
  std::optional<int> max_iterations;
  std::optional<double> max_distance_m;
  /// The CLI's --initial-guess: p_target = T * p_source (none: the identity, or for
  /// 'adaptive' no guess at all).
  std::optional<Isometry3> initial_guess;
  /// The CLI's --prior-sigma (degrees, metres); 'adaptive' only.
  std::optional<PriorSigma> prior;
  /// The source's up axis (source frame), for 'adaptive'; from a Map's frames.
  std::optional<Vec3> source_up;
  /// OpenMP threads for this call (0: OpenMP's default). Results do not depend on it.
  int threads = 0;
};

/// The result and its trust verdict, as run_strategy() gives them (as the CLI).
struct AlignOutcome {
  std::string strategy;
  StrategyOutcome outcome;
  /// When run_alignment() began and ended (alignment and trust verdict), seconds of
  /// std::chrono::steady_clock: CLOCK_MONOTONIC on Linux, the clock of Python's
  /// time.monotonic(). Lets callers see what ran at the same time.
  double started_s = 0.0;
  double finished_s = 0.0;
};

/// Runs the strategy through run_strategy() (registration/strategy.hpp), with the limits as the
/// CLI passes them. `source_covariances_m2` may be empty (needed only by p2d / robust_p2d; used
/// by adaptive when present). Throws InvalidArgument (bad strategy name or option) and what
/// run_strategy() throws.
/// Does not touch Python: the caller releases the GIL around it.
AlignOutcome run_alignment(const Points3& source_points,
                           const std::vector<Mat3>& source_covariances_m2,
                           const PreparedTarget& target, const AlignRequest& request);

}  // namespace lmalign::python
