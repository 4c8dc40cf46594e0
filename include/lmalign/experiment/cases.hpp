// Expanding an experiment config into the cases it runs (docs/experiments.md, "Cases").
// A case is one displacement of the source at one k; every strategy of its experiment runs on it.
// All random draws (basin experiments) are made here, serially, from the configured seed.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/experiment/config.hpp"
#include "lmalign/registration/registration.hpp"

namespace lmalign {

struct Case {
  /// 0-based position in the expansion; the `case` column of results.csv.
  std::size_t index = 0;
  /// Index into ExperimentConfig::experiments, and that experiment's name.
  std::size_t experiment_index = 0;
  std::string experiment;
  /// Readable, unique within its experiment: "k=5", "yaw=30", "+X+Y 0.57", "+X-Y yaw=-10",
  /// "pose 2", "yaw=60 #3", "t=1.5 #3".
  std::string label;
  /// The quadrant (xy, xy_yaw), the axis ("yaw" or "translation", basin), or empty.
  std::string group;
  /// What the experiment varies ("k", "yaw_deg", "offset_m", "pose", "translation_m") and its
  /// value in this case (the level of a basin case; the pose's position for "poses").
  std::string variable;
  double value = 0.0;
  /// The displacement applied to the source, in the paper's parametrisation (about the world
  /// origin) and as the transform actually applied (D = displacement.transform(), except for
  /// basin draws, whose D is built directly and whose parameters are xyz_rpy_deg_from_pose(D)).
  Pose6 displacement;
  Isometry3 D = Isometry3::Identity();
  int k = 5;
  std::vector<std::string> strategies;  ///< preset names (configs/presets/)
  /// Escalation (xy with escalate): the group (one per quadrant, numbered across the config) and
  /// the level within it, 0-based; -1 when the case is not part of an escalation.
  int escalation_group = -1;
  int escalation_level = 0;

  /// "<experiment>/<label>".
  std::string id() const { return experiment + "/" + label; }
};

/// True if some experiment draws from the source landmarks (a basin or random experiment with
/// pivot landmark or centroid), so expand_cases() needs them.
bool cases_need_source_points(const ExperimentConfig& config);

/// The cases of `config`, in config order; within an experiment:
///   k:      one case per k value;
///   yaw:    one per yaw;
///   xy:     quadrant by quadrant, offsets ascending as written (escalate: every offset from start
///           to max; the runner stops a quadrant early);
///   xy_yaw: quadrant by quadrant, each with every yaw;
///   poses:  one per pose;
///   basin:  the yaw axis then the translation axis, level by level, `samples` draws each;
///   random: `samples` starts, "start #i", variable "offset_m" = the drawn offset length.
/// `source_points` (the undisplaced source landmarks) are needed only if
/// cases_need_source_points(); throws InvalidArgument if they are then empty.
std::vector<Case> expand_cases(const ExperimentConfig& config, const Points3& source_points = {});

/// The case named by `id`: a case index ("12") or "<experiment>/<label>". nullopt if none.
std::optional<std::size_t> find_case(const std::vector<Case>& cases, const std::string& id);

/// The case to plot in detail: config.plot_case if set (throws InvalidArgument if it names no
/// case), else the first case with k = 5 of a "k" experiment, else case 0. nullopt if no cases.
std::optional<std::size_t> default_plot_case(const ExperimentConfig& config,
                                             const std::vector<Case>& cases);

}  // namespace lmalign
