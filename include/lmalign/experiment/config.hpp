// The experiment protocol as data (docs/experiments.md): which maps, which ground truth, which
// strategies and settings, and which experiments (the paper's Tables 1-4, explicit poses, and
// convergence-basin sweeps). Loaded from YAML by load_experiment_config(); yaml-cpp stays private.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/scale_search.hpp"
#include "lmalign/registration/settings.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign {

/// Where a map comes from: a map file read as is, or a frame window cut out of a map by
/// split_map() (method.md §6).
struct MapSpec {
  /// Map file, resolved (absolute, ${LMALIGN_DATA} expanded).
  std::string path;
  /// Landmarks kept need at least this many observations (in the window, when split).
  std::size_t min_observations = 2;
  /// Cut the frame window [first_frame_id, last_frame_id] with split_map().
  bool split = false;
  Id first_frame_id = 0;
  Id last_frame_id = 0;
  /// split only: re-estimate each landmark from the window's observations (triangulation).
  bool retriangulate = false;
  /// split with retriangulate only: minimum parallax, degrees.
  double min_parallax_deg = 2.0;
};

/// The true T_target_source of the undisplaced source map.
struct GroundTruthSpec {
  enum class Kind { kNone, kIdentity, kFile };
  Kind kind = Kind::kNone;
  /// kFile: a 4x4 transform file (read_transform()), resolved.
  std::string path;
};

/// How a run is judged (docs/experiments.md, "Success").
struct SuccessCriteria {
  /// With ground truth: the right basin was found when the rotation error is below this (deg)...
  double rotation_deg = 5.0;
  /// ...and the translation error below this (m).
  double translation_m = 0.10;
  /// Without ground truth: success when the final score is below this (m^2); the paper's value
  /// for its own map pair.
  double score_m2 = 0.0037;
};

/// The paper's displacement of the source, about the world origin (method.md §5):
/// p' = R p + t, R = Rz(yaw) Ry(pitch) Rx(roll). Metres and degrees.
struct Pose6 {
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
  double roll_deg = 0.0;
  double pitch_deg = 0.0;
  double yaw_deg = 0.0;

  Isometry3 transform() const;
  bool operator==(const Pose6& o) const {
    return x_m == o.x_m && y_m == o.y_m && z_m == o.z_m && roll_deg == o.roll_deg &&
           pitch_deg == o.pitch_deg && yaw_deg == o.yaw_deg;
  }
};

/// One of the four XY quadrants of the paper's Tables 3-4: the signs of x and y.
struct Quadrant {
  int sign_x = 1;
  int sign_y = 1;
  /// "+X+Y", "-X+Y", "-X-Y", "+X-Y".
  std::string name() const;
  /// Inverse of name(); false if `text` is not one of the four names.
  static bool parse(const std::string& text, Quadrant* out);
  /// The paper's order: +X+Y, -X+Y, -X-Y, +X-Y.
  static std::vector<Quadrant> all();
  bool operator==(const Quadrant& o) const { return sign_x == o.sign_x && sign_y == o.sign_y; }
};

enum class ExperimentType {
  kNeighbourhood,  ///< "k": vary k at one fixed displacement (Table 1)
  kYaw,            ///< "yaw": vary the yaw (Table 2)
  kXy,             ///< "xy": |x| = |y| offsets per quadrant, fixed or escalating (Table 3)
  kXyYaw,          ///< "xy_yaw": one offset per quadrant with several yaws (Table 4)
  kPoses,          ///< "poses": an explicit list of displacements
  kBasin,          ///< "basin": seeded random displacements per level (convergence basins)
  kRandom,         ///< "random": seeded random starts, yaw, offset, roll and pitch all drawn
};
/// "k", "yaw", "xy", "xy_yaw", "poses", "basin", "random"
std::string to_string(ExperimentType type);

/// Table 3's escalation: offsets start_m, start_m + step_m, ... <= max_m per quadrant; a
/// quadrant stops after the first offset at which at least one strategy fails (`stop: any`), or
/// at which every strategy fails (`stop: all`).
struct EscalationSpec {
  double start_m = 0.25;
  double step_m = 0.25;
  double max_m = 3.0;
  /// false (the paper's rule): stop after the first offset at which at least one strategy
  /// fails. true: go on while at least one strategy still succeeds.
  bool stop_when_all_fail = false;
};

/// Basin draws: where a yaw displacement turns about, and in which directions a translation goes.
enum class YawPivot {
  kLandmark,  ///< a vertical axis through a source landmark drawn at random (default)
  kCentroid,  ///< the vertical axis through the source centroid (draws differ only in sign)
  kOrigin,    ///< the world z axis, as the paper's displacements
};
std::string to_string(YawPivot pivot);  ///< "landmark", "centroid", "origin"
enum class TranslationDirections {
  kXy,   ///< uniform on the horizontal circle (default; the SLAM drift plane)
  kXyz,  ///< uniform on the sphere
};
std::string to_string(TranslationDirections d);  ///< "xy", "xyz"

struct BasinSpec {
  /// Levels of the yaw axis (degrees, >= 0) and of the translation axis (metres, >= 0). An empty
  /// list skips that axis. Defaults: yaw 0, 30, ..., 180; translation 0, 0.5, ..., 3.
  std::vector<double> yaw_levels_deg{0, 30, 60, 90, 120, 150, 180};
  std::vector<double> translation_levels_m{0, 0.5, 1, 1.5, 2, 2.5, 3};
  /// Draws per level, >= 1 (a level of 0 gets one: every draw would be the identity).
  int samples = 10;
  /// Seed of the draws, made serially when cases are expanded: each level of each axis has its
  /// own std::mt19937_64, seeded from (seed, axis, level), so a level's draws do not change when
  /// other levels are added or removed.
  std::uint64_t seed = 1;
  YawPivot yaw_pivot = YawPivot::kLandmark;
  TranslationDirections translation_directions = TranslationDirections::kXy;
};

/// A coordinate axis as a config names it (x, y or z): the random starts' vertical.
enum class CoordinateAxis { kX, kY, kZ };
inline constexpr EnumName<CoordinateAxis> kCoordinateAxisNames[] = {
    {CoordinateAxis::kX, "x"}, {CoordinateAxis::kY, "y"}, {CoordinateAxis::kZ, "z"}};

/// Random starts (the accuracy benchmark's, docs/accuracy.md): `samples` displacements, each drawn
/// independently: yaw uniform in [-yaw_deg, yaw_deg] about the up axis through the pivot, roll and
/// pitch each uniform in [-roll_pitch_deg, roll_pitch_deg] (R = Rz(yaw) Ry(pitch) Rx(roll) in a
/// frame whose z is up), then an offset across the up axis of length uniform in
/// [0, translation_m] in a uniform direction: D p = R (p - pivot) + pivot + offset.
struct RandomStartSpec {
  int samples = 100;  ///< >= 1
  /// Seed of the draws: draw i comes from its own std::mt19937_64 seeded from (seed, i), so a
  /// draw does not change when samples changes.
  std::uint64_t seed = 1;
  double yaw_deg = 180.0;       ///< in [0, 180]
  double translation_m = 3.0;   ///< >= 0, finite
  double roll_pitch_deg = 3.0;  ///< in [0, 90]
  /// landmark: a source landmark drawn per start; centroid (default): the source centroid;
  /// origin: the frame's origin.
  YawPivot pivot = YawPivot::kCentroid;
  /// The maps' vertical, as the config names a coordinate axis (its sign does not matter: yaw,
  /// roll and pitch are drawn symmetrically): z in TUM's motion-capture frame, y in camera frames
  /// (KITTI, road_sim.hpp).
  CoordinateAxis up_axis = CoordinateAxis::kZ;
};

/// One experiment of the config (one entry of `experiments:`).
struct ExperimentSpec {
  std::string name;
  ExperimentType type = ExperimentType::kPoses;
  /// Neighbourhood size for every type but kNeighbourhood (default: the config's k).
  int k = 5;
  std::vector<std::string> strategies;  ///< preset names (configs/presets/)
  /// 1-based line of the entry in the config (0 if not from a file).
  std::size_t line = 0;

  /// kNeighbourhood: the fixed displacement. kYaw, kXy, kXyYaw: the components not varied.
  Pose6 pose;
  /// kNeighbourhood: the k values.
  std::vector<int> k_values;
  /// kYaw, kXyYaw: the yaws, degrees.
  std::vector<double> yaw_deg;
  /// kXy fixed: per quadrant, the offsets |x| = |y| (m), in the order written.
  std::vector<std::pair<Quadrant, std::vector<double>>> offsets_m;
  /// kXy: escalate instead of fixed offsets.
  bool escalate = false;
  EscalationSpec escalation;
  /// kXy with escalate, kXyYaw: the quadrants (default: all four, the paper's order).
  std::vector<Quadrant> quadrants;
  /// kXyYaw: |x| = |y|, metres.
  double offset_m = 0.5;
  /// kPoses.
  std::vector<Pose6> poses;
  /// kBasin.
  BasinSpec basin;
  /// kRandom.
  RandomStartSpec random;
};

/// A whole experiment config.
struct ExperimentConfig {
  /// The config file as given, and its stem (used for the default output folder).
  std::string path;
  std::string name;
  MapSpec source;
  MapSpec target;
  GroundTruthSpec ground_truth;
  /// Defaults of every experiment.
  /// Preset names (default: the paper's four).
  std::vector<std::string> strategies = preset_names("paper");
  int k = 5;
  /// Limits given to every strategy, as `lmalign align --max-iterations / --max-distance`
  /// (AlignRequest): none given, each strategy keeps its own (the paper's: 150 iterations, an
  /// unlimited distance).
  std::optional<int> max_iterations;
  std::optional<double> max_distance_m;
  /// Whether the strategies estimate the scale too, as `lmalign align --scale` (AlignRequest::
  /// scale, docs/scale.md): `scale: MODE` for every strategy, or `scale: {STRATEGY: MODE}` per
  /// strategy (the others keep `scale`, auto).
  ScaleMode scale = ScaleMode::kAuto;
  std::vector<std::pair<std::string, ScaleMode>> strategy_scales;
  /// Settings per strategy (`settings: {STRATEGY: {KEY: VALUE}}`), checked against that
  /// strategy's table when the config is read.
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, SettingValue>>>> settings;
  CovarianceNorm covariance_norm = CovarianceNorm::kSpectral;
  SuccessCriteria success;
  /// Default seed of basin experiments.
  std::uint64_t seed = 1;
  /// The case whose score history and alignment are plotted: a case index or
  /// "<experiment>/<label>"; empty = the first case with k = 5 of a "k" experiment, else case 0.
  std::string plot_case;
  std::vector<ExperimentSpec> experiments;

  bool has_ground_truth() const { return ground_truth.kind != GroundTruthSpec::Kind::kNone; }
  /// The scale mode of `strategy`: its entry of strategy_scales, else `scale`.
  ScaleMode scale_of(const std::string& strategy) const;
};

/// One key of the experiment config's schema, as docs/settings.md prints it. The same table
/// drives the reading (which keys a mapping accepts, the bound of each value and the message
/// naming the key, the value and the bound) and resolved_config_yaml().
struct ExperimentConfigKey {
  /// Where the key is written: "" (the top level), "source, target", "success",
  /// "experiments[]", "experiments[].escalate", "experiments[].levels", "pose".
  std::string section;
  /// experiments[] keys: the experiment types that take it, separated by spaces ("" = every).
  std::string types;
  std::string key;
  std::string member;  ///< the C++ member it fills, e.g. "SuccessCriteria::rotation_deg"
  std::string value;   ///< the default, as text ("required" for a required key)
  std::string bound;   ///< what a value may be: "[1, 4096]", "one of x, y, z", "a list of ..."
  std::string unit;    ///< "m", "deg", "m^2", "1", "count" ("" for a structure)
  std::string doc;     ///< one sentence
};
/// Every key of the experiment config, section by section, in the order resolved_config_yaml()
/// writes them.
std::vector<ExperimentConfigKey> experiment_config_schema();

/// docs/settings.md: every preset's settings (key, value, unit, bound, doc) and the experiment
/// config's keys, as Markdown (`lmalign options --markdown` prints it; a test compares it with
/// the file).
std::string settings_reference_markdown();

struct ConfigLoadOptions {
  /// What "${LMALIGN_DATA}" in a path expands to. Empty: a path that uses it is an error
  /// (the CLI passes $LMALIGN_DATA, else ../shared/data beside the repository).
  std::string data_dir;
};

/// Reads and checks a config file. Strict: unknown or duplicate keys, wrong types, out-of-range
/// values and missing required keys throw ParseError "<file>:<line>: <key path>: <expected>",
/// e.g. "paper.yaml:12: experiments[1].yaw_deg: expected a list of numbers". Relative paths are
/// relative to the config's folder. Maps are not read here. IoError if the file is unreadable.
ExperimentConfig load_experiment_config(const std::string& path,
                                        const ConfigLoadOptions& options = {});

/// Same from YAML text; `name` stands for the file in messages, relative paths are taken from
/// `base_dir`.
ExperimentConfig parse_experiment_config(const std::string& yaml_text, const std::string& name,
                                         const std::string& base_dir,
                                         const ConfigLoadOptions& options = {});

/// The config with every default filled in and every path resolved, as YAML that
/// parse_experiment_config() reads back to the same config.
std::string resolved_config_yaml(const ExperimentConfig& config);

/// Keeps only the named experiments (in the config's order). Throws InvalidArgument naming an
/// unknown name and listing the known ones.
void select_experiments(ExperimentConfig& config, const std::vector<std::string>& names);

}  // namespace lmalign
