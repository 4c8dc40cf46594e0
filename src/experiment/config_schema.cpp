// The experiment config's schema as one table (config_schema.hpp).
#include "config_schema.hpp"

#include <type_traits>

#include "lmalign/core/error.hpp"
#include "text_format.hpp"

namespace lmalign {
namespace detail {

namespace {

template <class S>
constexpr Owner owner_of() {
  if constexpr (std::is_same_v<S, ExperimentConfig>) return Owner::kConfig;
  if constexpr (std::is_same_v<S, MapSpec>) return Owner::kMap;
  if constexpr (std::is_same_v<S, SuccessCriteria>) return Owner::kSuccess;
  if constexpr (std::is_same_v<S, ExperimentSpec>) return Owner::kExperiment;
  if constexpr (std::is_same_v<S, EscalationSpec>) return Owner::kEscalation;
  if constexpr (std::is_same_v<S, BasinSpec>) return Owner::kBasin;
  if constexpr (std::is_same_v<S, RandomStartSpec>) return Owner::kRandom;
  if constexpr (std::is_same_v<S, Pose6>) return Owner::kPose;
  return Owner::kNone;
}

/// A member's value as a SettingValue (a seed as its decimal text, a choice as its name), and
/// back; nullopt: nothing to write (an optional not given).
template <class T>
struct Conv {
  static std::optional<SettingValue> to(const T& v) {
    if constexpr (std::is_same_v<T, bool>) {
      return SettingValue(v);
    } else if constexpr (std::is_same_v<T, double>) {
      return SettingValue(v);
    } else if constexpr (std::is_same_v<T, std::string>) {
      return SettingValue(v);
    } else if constexpr (std::is_same_v<T, std::uint64_t>) {
      return SettingValue(std::to_string(v));
    } else {
      return SettingValue(static_cast<long long>(v));
    }
  }
  static T from(const SettingValue& v) {
    if constexpr (std::is_same_v<T, bool> || std::is_same_v<T, double> ||
                  std::is_same_v<T, std::string>) {
      return std::get<T>(v);
    } else if constexpr (std::is_same_v<T, std::uint64_t>) {
      const std::string& s = std::get<std::string>(v);
      std::uint64_t out = 0;
      std::from_chars(s.data(), s.data() + s.size(), out);
      return out;
    } else {
      return static_cast<T>(std::get<long long>(v));
    }
  }
};
template <class T>
struct Conv<std::optional<T>> {
  static std::optional<SettingValue> to(const std::optional<T>& v) {
    return v ? Conv<T>::to(*v) : std::nullopt;
  }
  static std::optional<T> from(const SettingValue& v) { return Conv<T>::from(v); }
};

Row base_row(std::string section, std::string types, std::string key, Kind kind, Owner owner,
             std::string member_name, SettingBound bound, std::string unit, std::string doc) {
  Row r;
  r.section = std::move(section);
  r.types = std::move(types);
  r.key = std::move(key);
  r.kind = kind;
  r.owner = owner;
  r.member = std::move(member_name);
  r.bound = std::move(bound);
  r.unit = std::move(unit);
  r.doc = std::move(doc);
  return r;
}

/// A row whose value is one member of S.
template <class S, class T>
Row field(std::string section, std::string types, std::string key, Kind kind, T S::*member,
          std::string member_name, SettingBound bound, std::string unit, std::string doc) {
  Row r = base_row(std::move(section), std::move(types), std::move(key), kind, owner_of<S>(),
                   std::move(member_name), std::move(bound), std::move(unit), std::move(doc));
  r.get = [member](const void* p) { return Conv<T>::to(static_cast<const S*>(p)->*member); };
  r.set = [member](void* p, const SettingValue& v) {
    static_cast<S*>(p)->*member = Conv<T>::from(v);
  };
  static const S defaults{};
  const std::optional<SettingValue> d = r.get(&defaults);
  r.value = d ? value_text(*d) : "none";
  return r;
}

/// A row whose value is a name of an enum member of S.
template <class S, class E, std::size_t N>
Row choice(std::string section, std::string types, std::string key, E S::*member,
           const EnumName<E> (&names)[N], std::string member_name, std::string doc) {
  std::vector<std::string> choices;
  for (const EnumName<E>& n : names) choices.push_back(n.name);
  Row r =
      base_row(std::move(section), std::move(types), std::move(key), Kind::kChoice, owner_of<S>(),
               std::move(member_name), SettingBound::one_of(choices), "", std::move(doc));
  r.get = [member, &names](const void* p) {
    return std::optional<SettingValue>(
        std::string(name_of(names, static_cast<const S*>(p)->*member)));
  };
  r.set = [member, &names](void* p, const SettingValue& v) {
    static_cast<S*>(p)->*member = *find_enum(names, std::get<std::string>(v));
  };
  static const S defaults{};
  r.value = name_of(names, defaults.*member);
  return r;
}

/// A row read by code of its own (a path, a list, a mapping).
Row structure(std::string section, std::string types, std::string key, std::string member,
              std::string value, std::string expected, std::string unit, std::string doc) {
  Row r;
  r.section = std::move(section);
  r.types = std::move(types);
  r.key = std::move(key);
  r.member = std::move(member);
  r.value = std::move(value);
  r.bound_text = std::move(expected);
  r.unit = std::move(unit);
  r.doc = std::move(doc);
  return r;
}

Row with_value(Row r, std::string value) {
  r.value = std::move(value);
  return r;
}
Row custom(Row r) {
  r.custom = true;
  return r;
}

const SettingBound kPositive = SettingBound::above(0.0);

}  // namespace

/// The text of a value as the docs and the resolved config show it.
std::string value_text(const SettingValue& v) {
  if (const bool* b = std::get_if<bool>(&v)) return *b ? "true" : "false";
  if (const long long* i = std::get_if<long long>(&v)) return std::to_string(*i);
  if (const double* d = std::get_if<double>(&v)) return shortest(*d);
  if (const std::string* s = std::get_if<std::string>(&v)) return *s;
  return "";
}

/// The one table of the experiment config's keys.
const std::vector<Row>& schema() {
  using C = ExperimentConfig;
  using X = ExperimentSpec;
  static const std::vector<Row> rows = [] {
    const std::string sampled = "basin random";
    const std::string posed = "k yaw xy xy_yaw";
    std::vector<Row> r{
        // --- the top level
        structure(kTop, "", "description", "", "none", "a text", "", "What the config is for."),
        structure(kTop, "", "source", "ExperimentConfig::source", "required",
                  "a map file, or a mapping (see source, target)", "",
                  "The source map: a file read as is, or a frame window cut out of one."),
        structure(kTop, "", "target", "ExperimentConfig::target", "required",
                  "a map file, or a mapping (see source, target)", "",
                  "The target map, as source."),
        structure(kTop, "", "ground_truth", "ExperimentConfig::ground_truth", "none",
                  "identity, none, or a 4x4 transform file", "",
                  "The true T_target_source of the undisplaced source."),
        structure(kTop, "", "strategies", "ExperimentConfig::strategies", "the paper's four",
                  "a list of strategies (lmalign options NAME)", "",
                  "The strategies every experiment runs unless it names its own."),
        field(kTop, "", "k", Kind::kInt, &C::k, "ExperimentConfig::k",
              SettingBound::closed(1, kMaxK), "count",
              "Neighbourhood size of the weighted kNN, for every experiment but type k."),
        field(kTop, "", "max_iterations", Kind::kInt, &C::max_iterations,
              "ExperimentConfig::max_iterations", SettingBound::closed(1, 1000000), "count",
              "Iteration limit of every strategy, as lmalign align --max-iterations (none: each "
              "its own)."),
        field(kTop, "", "max_distance_m", Kind::kReal, &C::max_distance_m,
              "ExperimentConfig::max_distance_m", SettingBound::above_or_inf(0.0), "m",
              "Correspondence distance cap, as lmalign align --max-distance (none: each its own)."),
        structure(kTop, "", "scale", "ExperimentConfig::scale, strategy_scales", "auto",
                  "one of auto, free, fixed; or a mapping STRATEGY: MODE", "",
                  "Whether the scale is estimated too, as lmalign align --scale (docs/scale.md): "
                  "for every strategy, or per strategy."),
        structure(kTop, "", "settings", "ExperimentConfig::settings", "none",
                  "a mapping STRATEGY: {KEY: VALUE} (the preset settings below)", "",
                  "Settings per strategy, as lmalign align --set KEY=VALUE."),
        choice(kTop, "", "covariance_norm", &C::covariance_norm, kCovarianceNormNames,
               "ExperimentConfig::covariance_norm", "The matrix norm of Eq. 1."),
        structure(kTop, "", "success", "ExperimentConfig::success", "see success",
                  "a mapping (see success)", "", "How a run is judged."),
        field(kTop, "", "seed", Kind::kSeed, &C::seed, "ExperimentConfig::seed",
              SettingBound::at_least(0), "1", "Default seed of the basin and random experiments."),
        field(kTop, "", "plot_case", Kind::kText, &C::plot_case, "ExperimentConfig::plot_case", {},
              "", "The case whose history and alignment are plotted (none: the first).")};
    r.back().value = "none";
    r.back().bound_text = "a case index or <experiment>/<label>";
    r.push_back(structure(kTop, "", "experiments", "ExperimentConfig::experiments", "required",
                          "a non-empty list of experiments (see experiments[])", "",
                          "The experiments, each of one type."));
    // --- source, target
    r.push_back(structure(kMapSection, "", "map", "MapSpec::path", "required",
                          "a file path (relative to the config; ${LMALIGN_DATA} expanded)", "",
                          "The map file."));
    r.push_back(
        custom(field(kMapSection, "", "min_observations", Kind::kInt, &MapSpec::min_observations,
                     "MapSpec::min_observations", SettingBound::closed(0, 1000000), "count",
                     "Landmarks kept need this many observations (at least 1 with "
                     "frames, 2 with retriangulate).")));
    r.push_back(structure(kMapSection, "", "frames", "MapSpec::first_frame_id, last_frame_id",
                          "the whole map", "[FIRST, LAST], non-negative frame ids", "",
                          "Cut this frame window out of the map (split_map)."));
    r.push_back(field(kMapSection, "", "retriangulate", Kind::kBool, &MapSpec::retriangulate,
                      "MapSpec::retriangulate", {}, "flag",
                      "With frames: re-estimate each landmark from the window's observations."));
    r.push_back(field(kMapSection, "", "min_parallax_deg", Kind::kReal, &MapSpec::min_parallax_deg,
                      "MapSpec::min_parallax_deg", SettingBound::closed(0, 180), "deg",
                      "With retriangulate: the minimum parallax."));
    // --- success
    r.push_back(field(kSuccessSection, "", "rotation_deg", Kind::kReal,
                      &SuccessCriteria::rotation_deg, "SuccessCriteria::rotation_deg", kPositive,
                      "deg", "With ground truth: success below this rotation error..."));
    r.push_back(field(kSuccessSection, "", "translation_m", Kind::kReal,
                      &SuccessCriteria::translation_m, "SuccessCriteria::translation_m", kPositive,
                      "m", "...and this translation error."));
    r.push_back(field(kSuccessSection, "", "score_m2", Kind::kReal, &SuccessCriteria::score_m2,
                      "SuccessCriteria::score_m2", kPositive, "m^2",
                      "Without ground truth: success below this final score (the paper's value)."));
    // --- experiments[]
    r.push_back(
        with_value(field(kExperiments, "", "name", Kind::kText, &X::name, "ExperimentSpec::name",
                         {}, "", "A unique name of 1-64 letters, digits, '_', '-' or '.'."),
                   "required"));
    r.back().bound_text = "a name";
    r.push_back(with_value(
        choice(kExperiments, "", "type", &X::type, kExperimentTypeNames, "ExperimentSpec::type",
               "What varies: k (Table 1), yaw (Table 2), xy (Table 3), "
               "xy_yaw (Table 4), poses, basin, random."),
        "required"));
    r.back().custom = true;
    r.push_back(structure(kExperiments, "", "strategies", "ExperimentSpec::strategies",
                          "the config's strategies", "a list of strategies", "",
                          "The strategies of this experiment."));
    r.push_back(with_value(field(kExperiments, "yaw xy xy_yaw poses basin random", "k", Kind::kInt,
                                 &X::k, "ExperimentSpec::k", SettingBound::closed(1, kMaxK),
                                 "count", "Neighbourhood size of the weighted kNN."),
                           "the config's k"));
    r.push_back(structure(kExperiments, "k", "k_values", "ExperimentSpec::k_values", "required",
                          "a non-empty list of distinct integers in [1, 4096]", "count",
                          "The neighbourhood sizes to try."));
    r.push_back(structure(kExperiments, "yaw xy_yaw", "yaw_deg", "ExperimentSpec::yaw_deg",
                          "required", "a non-empty list of distinct numbers", "deg",
                          "The yaws to try."));
    r.push_back(structure(kExperiments, "xy", "offsets_m", "ExperimentSpec::offsets_m",
                          "either this or escalate",
                          "a mapping QUADRANT: [offsets > 0] (+X+Y, -X+Y, -X-Y, +X-Y)", "m",
                          "Fixed offsets |x| = |y| per quadrant."));
    r.push_back(structure(kExperiments, "xy", "escalate", "ExperimentSpec::escalation",
                          "either this or offsets_m", "a mapping (see experiments[].escalate)", "",
                          "Escalating offsets per quadrant (Table 3)."));
    r.push_back(field(kExperiments, "xy_yaw", "offset_m", Kind::kReal, &X::offset_m,
                      "ExperimentSpec::offset_m", kPositive, "m", "|x| = |y| in every quadrant."));
    r.push_back(structure(kExperiments, "xy xy_yaw", "quadrants", "ExperimentSpec::quadrants",
                          "all four", "a list of distinct quadrants (+X+Y, -X+Y, -X-Y, +X-Y)", "",
                          "The quadrants (xy: with escalate only)."));
    r.push_back(structure(kExperiments, posed, "pose", "ExperimentSpec::pose", "all 0",
                          "a mapping (see pose), without the components varied", "",
                          "The displacement's components that are not varied."));
    r.push_back(structure(kExperiments, "poses", "poses", "ExperimentSpec::poses", "required",
                          "a non-empty list of poses (see pose)", "", "The displacements."));
    r.push_back(structure(kExperiments, "basin", "levels", "BasinSpec",
                          "yaw 0, 30, ..., 180; translation 0, 0.5, ..., 3",
                          "a mapping (see experiments[].levels)", "",
                          "The levels of each axis (an axis left out is skipped)."));
    r.push_back(field(kExperiments, "basin", "samples", Kind::kInt, &BasinSpec::samples,
                      "BasinSpec::samples", SettingBound::closed(1, 100000), "count",
                      "Draws per level (levels x samples <= 100000)."));
    r.push_back(
        with_value(field(kExperiments, "basin", "seed", Kind::kSeed, &BasinSpec::seed,
                         "BasinSpec::seed", SettingBound::at_least(0), "1", "Seed of the draws."),
                   "the config's seed"));
    r.push_back(choice(kExperiments, "basin", "yaw_pivot", &BasinSpec::yaw_pivot, kYawPivotNames,
                       "BasinSpec::yaw_pivot", "Where a yaw displacement turns about."));
    r.push_back(choice(kExperiments, "basin", "translation_directions",
                       &BasinSpec::translation_directions, kDirectionNames,
                       "BasinSpec::translation_directions",
                       "Directions of a translation: the horizontal circle or the sphere."));
    r.push_back(field(kExperiments, "random", "samples", Kind::kInt, &RandomStartSpec::samples,
                      "RandomStartSpec::samples", SettingBound::closed(1, kMaxCasesPerList),
                      "count", "The number of random starts."));
    r.push_back(with_value(
        field(kExperiments, "random", "seed", Kind::kSeed, &RandomStartSpec::seed,
              "RandomStartSpec::seed", SettingBound::at_least(0), "1", "Seed of the draws."),
        "the config's seed"));
    r.push_back(field(kExperiments, "random", "yaw_deg", Kind::kReal, &RandomStartSpec::yaw_deg,
                      "RandomStartSpec::yaw_deg", SettingBound::closed(0, 180), "deg",
                      "Yaw drawn uniformly in [-yaw_deg, yaw_deg]."));
    r.push_back(field(kExperiments, "random", "translation_m", Kind::kReal,
                      &RandomStartSpec::translation_m, "RandomStartSpec::translation_m",
                      SettingBound::closed(0, 1e6), "m",
                      "Offset across the up axis of length uniform in [0, translation_m]."));
    r.push_back(field(kExperiments, "random", "roll_pitch_deg", Kind::kReal,
                      &RandomStartSpec::roll_pitch_deg, "RandomStartSpec::roll_pitch_deg",
                      SettingBound::closed(0, 90), "deg",
                      "Roll and pitch each uniform in [-roll_pitch_deg, roll_pitch_deg]."));
    r.push_back(choice(kExperiments, "random", "pivot", &RandomStartSpec::pivot, kYawPivotNames,
                       "RandomStartSpec::pivot", "Where the yaw turns about."));
    r.push_back(choice(kExperiments, "random", "up_axis", &RandomStartSpec::up_axis,
                       kCoordinateAxisNames, "RandomStartSpec::up_axis",
                       "The maps' vertical axis."));
    // --- experiments[].escalate
    r.push_back(field(kEscalate, "", "start_m", Kind::kReal, &EscalationSpec::start_m,
                      "EscalationSpec::start_m", kPositive, "m", "The first offset."));
    r.push_back(field(kEscalate, "", "step_m", Kind::kReal, &EscalationSpec::step_m,
                      "EscalationSpec::step_m", kPositive, "m", "The step between offsets."));
    r.push_back(field(kEscalate, "", "max_m", Kind::kReal, &EscalationSpec::max_m,
                      "EscalationSpec::max_m", kPositive, "m",
                      "The last offset (>= start_m; at most 10000 levels)."));
    r.push_back(choice(kEscalate, "", "stop", &EscalationSpec::stop_when_all_fail, kStopNames,
                       "EscalationSpec::stop_when_all_fail",
                       "any: a quadrant stops after the first offset at which a strategy fails; "
                       "all: when every strategy fails."));
    // --- experiments[].levels
    r.push_back(structure(kLevels, "", "yaw_deg", "BasinSpec::yaw_levels_deg", "0, 30, ..., 180",
                          "a list of distinct numbers in [0, 180]", "deg", "The yaw levels."));
    r.push_back(structure(kLevels, "", "translation_m", "BasinSpec::translation_levels_m",
                          "0, 0.5, ..., 3", "a list of distinct numbers >= 0", "m",
                          "The translation levels."));
    // --- pose: p' = R p + t, R = Rz(yaw) Ry(pitch) Rx(roll)
    const std::pair<const char*, double Pose6::*> pose_fields[] = {{"x_m", &Pose6::x_m},
                                                                   {"y_m", &Pose6::y_m},
                                                                   {"z_m", &Pose6::z_m},
                                                                   {"roll_deg", &Pose6::roll_deg},
                                                                   {"pitch_deg", &Pose6::pitch_deg},
                                                                   {"yaw_deg", &Pose6::yaw_deg}};
    for (const auto& [key, member] : pose_fields) {
      const std::string k = key;
      const bool metres = k.size() > 2 && k.compare(k.size() - 2, 2, "_m") == 0;
      r.push_back(field(kPoseSection, "", k, Kind::kReal, member, "Pose6::" + k, {},
                        metres ? "m" : "deg",
                        metres ? "Translation of the displacement, about the world origin."
                               : "Rotation of the displacement, R = Rz(yaw) Ry(pitch) Rx(roll)."));
    }
    return r;
  }();
  return rows;
}

/// The rows of a section (and an experiment type).
std::vector<const Row*> rows_of(const std::string& section, const std::string& type) {
  std::vector<const Row*> out;
  for (const Row& r : schema()) {
    if (r.section == section && r.applies_to(type)) out.push_back(&r);
  }
  return out;
}

std::vector<std::string> keys_of(const std::string& section, const std::string& type) {
  std::vector<std::string> keys;
  for (const Row* r : rows_of(section, type)) keys.push_back(r->key);
  return keys;
}

const Row& row_of(const std::string& section, const std::string& type, const std::string& key) {
  for (const Row* r : rows_of(section, type)) {
    if (r->key == key) return *r;
  }
  throw Error("experiment config schema: no key '" + key + "' in " + section);
}

std::string unit_word(const std::string& unit) {
  if (unit == "deg") return " degrees";
  if (unit == "m") return " metres";
  return "";
}
}  // namespace detail

std::vector<ExperimentConfigKey> experiment_config_schema() {
  std::vector<ExperimentConfigKey> out;
  using detail::Kind;
  for (const detail::Row& r : detail::schema()) {
    ExperimentConfigKey k;
    k.section = r.section;
    k.types = r.types;
    k.key = r.key;
    k.member = r.member;
    k.value = r.value;
    if (r.kind == Kind::kStructure) {
      k.bound = r.bound_text;
    } else if (r.kind == Kind::kText) {
      k.bound = r.bound_text.empty() ? "a text" : r.bound_text;
    } else {
      const SettingType type = r.kind == Kind::kInt || r.kind == Kind::kSeed ? SettingType::kInt
                               : r.kind == Kind::kBool                       ? SettingType::kBool
                               : r.kind == Kind::kChoice                     ? SettingType::kChoice
                                                                             : SettingType::kReal;
      k.bound = r.bound.text(type);
    }
    k.unit = r.unit;
    k.doc = r.doc;
    out.push_back(std::move(k));
  }
  return out;
}

}  // namespace lmalign
