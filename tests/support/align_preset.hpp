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

/// What one alignment asks beyond the preset, as a test writes it.
struct Ask {
  std::vector<std::string> settings;  ///< "KEY=VALUE"
  std::optional<Isometry3> guess;
  std::optional<PriorSigma> prior;
  std::optional<int> k;
  std::optional<int> max_iterations;
  std::optional<double> max_distance_m;
  bool history = false;
};

inline AlignRequest request_of(const Ask& ask) {
  AlignRequest r;
  for (const std::string& s : ask.settings) r.add_assignment(s);
  r.initial_guess = ask.guess;
  r.prior = ask.prior;
  r.k = ask.k;
  r.max_iterations = ask.max_iterations;
  r.max_distance_m = ask.max_distance_m;
  r.record_history = ask.history;
  return r;
}

inline Summary align_with(const std::string& preset, const SourceView& source,
                          const PreparedTarget& target, const Ask& ask = {}) {
  return align(find_preset(preset), source, target, request_of(ask));
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
