// The scale of an alignment (Sim(3), docs/scale.md): whether it is estimated (ScaleMode), and,
// when it is, where its search starts and how it goes on (ScaleSearch). The engine owns one
// ScaleSearch per free-scale run (Pipeline::run): the initial scale from the data, the rungs of
// the scale axis at which the search's hypotheses are concluded again without a new search, the
// searches again at other initial scales, and when a refinement's scale has settled. The scale
// itself is estimated by the Estimator seam in 7 DoF (seams.hpp, Pose::scale). Its settings are
// the rows `scale.*` of every pipeline (scale_search_settings()).
//
// Frames: p_target = scale * R * p_source + t; scale is target units per source unit.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/registration/settings.hpp"

namespace lmalign {

/// Whether an alignment estimates the scale. kAuto: free when either map has no metric scale
/// (its header says arbitrary or unknown), fixed otherwise.
enum class ScaleMode { kAuto, kFree, kFixed };
inline constexpr EnumName<ScaleMode> kScaleModeNames[] = {
    {ScaleMode::kAuto, "auto"}, {ScaleMode::kFree, "free"}, {ScaleMode::kFixed, "fixed"}};
/// "auto", "free", "fixed".
std::string to_string(ScaleMode mode);
/// The mode of a name above; throws InvalidArgument "unknown scale mode 'NAME' (known: auto,
/// free, fixed)".
ScaleMode parse_scale_mode(const std::string& name);
/// kFree or kFixed: auto resolved from whether each map's lengths are metres.
ScaleMode resolve_scale_mode(ScaleMode mode, bool source_metric, bool target_metric);

/// The settings of the scale search (rows scale.*; defaults here, read by the rows).
struct ScaleSearchOptions {
  /// The initial scale from the data (target / source median landmark spacing) is clamped to
  /// [initial_min, initial_max].
  double initial_min = 0.1;
  double initial_max = 10.0;
  /// The rungs of the scale axis: the first search's hypotheses are concluded again, without a
  /// new search, at rung_ratio^k times the initial scale for k = -rungs ... rungs (nearest
  /// first) while none is trusted. The search absorbs about 6% either way; 1.12 leaves no gap.
  double rung_ratio = 1.12;
  int rungs = 1;
  /// Searches again at rung_ratio^k times the initial scale, k = 1 ... researches on each side,
  /// each concluded at its own initial scale alone, while none is trusted, nearest first, the
  /// side the first result's refined scale leans to first. A measurement that was not decisive
  /// reorders the same scales (ScaleSearch::set_evidence): the one with the largest clique
  /// within half a rung of it is searched first, the others by their cliques, and among those
  /// the cliques cannot rank, the side of the largest clique first when it lies more than half
  /// a rung from the initial scale (else the lean). Where the first
  /// search has a first pass (search.first_pass) that is not trusted, the searches again are
  /// first passes too, before any complete search; none trusted: the complete search at the
  /// scale whose first pass scored highest, and its rungs (Pipeline::run).
  int researches = 2;
  /// After the first passes at the searches' scales, none trusted: one more first pass half a
  /// rung from the best-scoring one, towards its better-scoring neighbour a rung away, before
  /// the complete search. A first pass stands about 5% of scale error, and the truth may lie
  /// midway between two rungs (6% from each): a held-out desk pair, frames 0-59 and 170-229,
  /// whose first passes both missed it (docs/scale.md, step 6).
  bool half_rung = true;
  /// Before the first search, the initialiser measures the scale from the landmarks'
  /// correspondences (Initialiser::measure_scale: consistent cliques at rung_ratio^k times the
  /// initial scale, |k| <= measure_steps); a decisive measurement (measure_margin) becomes the
  /// initial scale and replaces the searches again (issue 39, item 4: the scale from
  /// scale-invariant pairs, not whole re-runs). 0: not measured, the searches again as before.
  int measure_steps = 6;
  /// A measurement counts when its largest clique has at least this many times the matches of
  /// the largest clique at a scale more than a rung away.
  double measure_margin = 2.0;
  /// A free-scale refinement goes on while its last step changed the scale by more than this
  /// (relative), within its schedule's budget.
  double settle = 1e-6;
};

/// The rows scale.* (settings.hpp) of ScaleSearchOptions.
std::vector<SettingRow> scale_search_settings();
/// The options from a pipeline's table (with the rows above).
ScaleSearchOptions scale_search_options(const Settings& settings);

/// One place on the scale axis where the engine concludes its hypotheses: the initial scale of
/// its search times `factor`; `new_search` when the initialiser proposes again at that scale
/// (otherwise the first search's hypotheses are concluded there).
struct ScaleAttempt {
  double factor = 1.0;
  bool new_search = false;
};

class ScaleSearch {
 public:
  /// `initial_scale`: the data's (initial_scale_from_spacing) or the caller's (finite, > 0).
  ScaleSearch(const ScaleSearchOptions& options, double initial_scale);

  double initial_scale() const { return initial_scale_; }
  /// The factor the correspondences measured (finite, > 0): the initial scale is multiplied by
  /// it and researches() is then empty. Throws InvalidArgument otherwise.
  void set_measured(double factor);
  /// The measured factor; NaN when none.
  double measured_factor() const { return measured_factor_; }
  /// A measurement that was not decisive: each clique's (factor relative to the initial scale,
  /// matches). Of the scales rung_ratio^k, |k| <= researches, the one with the most matches
  /// within half a rung (the initial scale on a tie) becomes the initial scale, and researches()
  /// covers the others, by their matches. Factors that are not finite and > 0 are ignored.
  /// Returns whether the initial scale moved. Call before the first search, at most once.
  bool set_evidence(std::vector<std::pair<double, std::size_t>> cliques);
  /// The factor set_evidence() moved the initial scale by; NaN when it did not.
  double lead_factor() const {
    return lead_k_ == 0 ? std::numeric_limits<double>::quiet_NaN()
                        : std::pow(o_.rung_ratio, lead_k_);
  }
  int measure_steps() const { return o_.measure_steps; }
  double measure_margin() const { return o_.measure_margin; }
  double rung_ratio() const { return o_.rung_ratio; }
  /// The rungs of the first search, in order: factor 1 first, then the rungs nearest first.
  std::vector<ScaleAttempt> rungs() const;
  /// The searches again, in order, after the first search's result refined to `refined_scale`:
  /// by the evidence of set_evidence() (the most matches within half a rung first), then
  /// nearest first, the largest clique's side first when it lies more than half a rung from the
  /// initial scale, else the refined scale's; none once a scale was measured.
  std::vector<ScaleAttempt> researches(double refined_scale) const;
  /// The factor of the first pass half a rung away (ScaleSearchOptions::half_rung), given the
  /// (factor, score) of each first pass so far: sqrt(best x neighbour), the neighbour being the
  /// best-scoring factor a rung from the best one (the first of the best on ties). None when
  /// half_rung is off, or no first pass lies a rung from the best.
  std::optional<double> half_rung(const std::vector<std::pair<double, double>>& scored) const;

 private:
  ScaleSearchOptions o_;
  double initial_scale_;
  double measured_factor_ = std::numeric_limits<double>::quiet_NaN();
  // The matches within half a rung of rung_ratio^k (relative to the scale before the lead),
  // for k = -researches ... researches (index k + researches); empty without evidence.
  std::vector<std::size_t> matches_;
  int lead_k_ = 0;
  // log of the largest clique's factor (relative to the scale before the lead); 0 without one.
  double largest_log_factor_ = 0.0;
};

/// The scale that brings the source's typical landmark spacing (median nearest-neighbour
/// distance) to the target's: target_spacing / source_spacing, clamped to [min_scale,
/// max_scale]. Both spacings > 0; throws InvalidArgument otherwise.
double initial_scale_from_spacing(double source_spacing, double target_spacing,
                                  double min_scale = 0.1, double max_scale = 10.0);

}  // namespace lmalign
