// The named strategies: presets of the registration engine (pipeline.hpp) read from files,
// configs/presets/NAME.yaml (built into the library), one per preset, the only place a preset's
// name is written. The one entry point every front end calls (the CLI's align, the experiment
// runner, Python, the merge): align(preset, source, target, request) -> Summary.
//
// A preset file (docs/architecture.md, "Presets"):
//   doc: one line                  what it does
//   group: paper | lmalign         the paper's four, or lmalign's own
//   order: N                       where it is listed
//   header, aliases, recommended   optional: a table header, other names, the default
//   initialiser, matcher, rejectors (a list), kernel, estimator, schedule, scorer, trust: stages
//   settings: {key: value}         the settings that differ from the stages' defaults
//
// Frames: T_target_source, p_target = T_target_source * p_source.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"
#include "lmalign/registration/pipeline.hpp"

namespace lmalign {

struct Preset {
  std::string name;  ///< the file's stem
  std::string doc;
  std::string group;  ///< "paper" or "lmalign"
  int order = 0;
  std::string header;  ///< a short table header (the name if the file gives none)
  std::vector<std::string> aliases;
  bool recommended = false;
  PipelineSpec spec;  ///< spec.name = name; spec.settings = the file's settings
  std::string file;   ///< the file it was read from ("configs/presets/NAME.yaml" when built in)

  /// True when its matcher has a neighbourhood size (the paper's weighted kNN): the CLI's --k,
  /// an experiment's k.
  bool uses_k() const;
};

/// The built-in presets, by `order`.
const std::vector<Preset>& presets();
/// The names of the built-in presets of `group` ("" = all), by order.
std::vector<std::string> preset_names(const std::string& group = "");
/// The recommended default.
const Preset& recommended_preset();
/// A built-in preset by name or alias; else, when `name` ends in .yaml or .yml, that file
/// (read_preset_file). Throws InvalidArgument "unknown strategy 'NAME' (nearest: 'OTHER'; known:
/// ...)" for an unknown name, ParseError for a bad file, IoError for an unreadable one.
Preset find_preset(const std::string& name);
/// True when `name` names a built-in preset (or one of its aliases).
bool is_preset_name(const std::string& name);

/// Reads a preset file (the name is the file's stem). Throws ParseError "FILE:LINE: ..." for
/// unknown keys, an unknown stage (naming the stage and the known ones), an unknown setting
/// (naming the nearest known key) or a value outside its bound; IoError if unreadable.
Preset read_preset_file(const std::string& path);
/// The same from YAML text; `file` stands for the file in messages.
Preset parse_preset(const std::string& yaml_text, const std::string& name, const std::string& file);

/// What one alignment asks beyond the preset.
struct AlignRequest {
  /// The start, and a prior around it (an initialiser that searches bounds its search by it).
  std::optional<Isometry3> initial_guess;
  std::optional<PriorSigma> prior;
  /// The weighted kNN's neighbourhood size (match.k) where the preset has one; ignored otherwise.
  std::optional<int> k;
  /// A user's limits (`lmalign align --max-iterations / --max-distance`), applied by the
  /// preset's schedule (Schedule::limits): the iteration budget, and a cap on the correspondence
  /// distance where the schedule has one.
  std::optional<int> max_iterations;
  std::optional<double> max_distance_m;
  /// Settings by key (--set KEY=VALUE, an experiment's `settings:`, Python's settings=); they
  /// win over k and the limits. A value may be given as text (std::string), which resolve()
  /// reads by the setting's own row (SettingRow::parse: numbers, lists, inf, true/false, names).
  std::vector<std::pair<std::string, SettingValue>> settings;
  /// Per-iteration history of the final refinement (and the fitness score at each).
  bool record_history = false;
  /// Whether the scale is estimated too (Sim(3), PipelineRequest::free_scale). kAuto: free when
  /// either map has no metric scale (source_metric, target_metric: what the maps' headers say,
  /// set by describe_maps(); true when the front end does not know, as for bare arrays), fixed
  /// otherwise.
  ScaleMode scale = ScaleMode::kAuto;
  bool source_metric = true;
  bool target_metric = true;
  /// Either map's covariances are assumed, not measured (MapHeader::covariance_assumed: a point
  /// cloud without any, given an isotropic covariance from its local spacing). A pipeline that
  /// uses covariances says so in Summary::covariances_assumed and at the end of its verdict's
  /// reason.
  bool covariances_assumed = false;

  /// Fills what the maps say about themselves: source_metric / target_metric (true only for
  /// MapScale::kMetric: an arbitrary or unknown scale lets kAuto estimate it) and
  /// covariances_assumed (either header's covariance_assumed). Every front end calls it with
  /// the two maps it read, so `auto` means the same in the CLI, Python, the experiment runner
  /// and the merge.
  void describe_maps(const MapHeader& source, const MapHeader& target);

  /// Makes the request the preset's, checked before any work: every setting given as text read
  /// by its row in the preset's table, then the whole table (k, the limits, the settings) within
  /// its bounds; a prior that is valid and that the preset's initialiser uses; a guess that is a
  /// rigid transform within the supported range. Throws InvalidArgument naming what is wrong and
  /// the strategy: "settings: unknown setting 'schedule.max_iteration' (nearest:
  /// 'schedule.max_iterations') (strategy 'adaptive')", "prior sigma: the strategy 'base' uses
  /// no prior (its initialiser 'guess' does not search)". The one place a front end's request is
  /// made (the CLI, Python, the experiment runner, the merge); align() calls it too.
  void resolve(const Preset& preset);
  /// Adds a setting given as "KEY=VALUE" text (the first '=' splits; the value is read by
  /// resolve()). Throws InvalidArgument "'TEXT': expected KEY=VALUE".
  void add_assignment(const std::string& key_value);
};

/// The preset's pipeline spec with the request's k, limits and settings applied. Throws
/// InvalidArgument naming the preset for an unknown setting (and the nearest known key) or a
/// value outside its bound (key, value, bound).
PipelineSpec resolve_spec(const Preset& preset, const AlignRequest& request);

/// Aligns the source onto the target with the preset. A pipeline whose stages read a target
/// confidence that is 0 for every target landmark (observations or mean distance on a point
/// cloud without observations: Eqs. 2-3) aligns nothing; its verdict is then untrusted and says
/// so. Throws InvalidArgument on bad settings
/// (resolve_spec), a non-rigid initial guess, a prior for a preset whose initialiser uses none,
/// and what Pipeline::run throws.
Summary align(const Preset& preset, const SourceView& source, const PreparedTarget& target,
              const AlignRequest& request = {});

}  // namespace lmalign
