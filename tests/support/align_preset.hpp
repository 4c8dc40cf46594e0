// Tests align the way every front end does: align(preset, source, target, AlignRequest) with the
// preset's settings given as "KEY=VALUE" text (registration/presets.hpp).
#pragma once

#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/presets.hpp"

namespace lmalign::test {

/// What one alignment asks beyond the preset: the front ends' AlignRequest, with its settings
/// written as a test writes them, "KEY=VALUE" (AlignRequest::add_assignment).
struct Ask : AlignRequest {
  Ask() = default;
  /// Settings ("KEY=VALUE"), and optionally the initial guess and its prior.
  Ask(const std::vector<std::string>& settings, std::optional<Isometry3> guess = std::nullopt,
      std::optional<PriorSigma> prior_sigma = std::nullopt) {
    for (const std::string& s : settings) add_assignment(s);
    initial_guess = guess;
    prior = prior_sigma;
  }
};

inline Summary align_with(const std::string& preset, const SourceView& source,
                          const PreparedTarget& target, const Ask& ask = {}) {
  return align(find_preset(preset), source, target, ask);
}

inline Summary align_with(const std::string& preset, const SourceLandmarks& source,
                          const PreparedTarget& target, const Ask& ask = {}) {
  return align_with(preset, source.view(), target, ask);
}

/// Bare points (no covariances, no up axis) as a source.
inline Summary align_with(const std::string& preset, const Points3& source,
                          const PreparedTarget& target, const Ask& ask = {}) {
  SourceView view;
  view.positions = &source;
  return align_with(preset, view, target, ask);
}

/// The default of a preset's setting (its table's row), as a number.
inline double preset_setting(const std::string& preset, const std::string& key) {
  const Pipeline p(find_preset(preset).spec);
  const SettingValue& v = p.settings().value(key);
  if (const double* d = std::get_if<double>(&v)) return *d;
  if (const long long* i = std::get_if<long long>(&v)) return static_cast<double>(*i);
  if (const bool* b = std::get_if<bool>(&v)) return *b ? 1.0 : 0.0;
  return 0.0;
}

/// The paper's preset of a landmark confidence (method.md §3): base for kUniform, else the
/// weighted kNN of that confidence.
inline std::string paper_preset(WeightKind weight) {
  switch (weight) {
    case WeightKind::kCovariance:
      return "covariance";
    case WeightKind::kObservations:
      return "observations";
    case WeightKind::kMeanDistance:
      return "distance";
    default:
      return "base";
  }
}

}  // namespace lmalign::test
