// Schedule "distance_levels": a maximum correspondence distance per level, non-increasing (the
// first may be unlimited: the paper's basin). The run moves to the next level when the estimate
// settles (an increment below settle_translation_m and settle_rotation_rad) or after
// max_iterations_per_level, and ends when it settles at the last level or after max_iterations
// in all. Hypotheses of a search are refined on their own shorter schedule
// (hypothesis_levels_m, hypothesis_iterations). The covariance and the diagnostics come from the
// last level's pairs at the estimate.
#include <algorithm>
#include <cmath>
#include <limits>

#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(schedule_distance)

namespace lmalign::stages {

namespace {

struct Levels {
  std::vector<double> distances_m;
  int max_iterations = 300;
  int max_iterations_per_level = 60;
};

// The rows' defaults.
struct DistanceLevelsOptions {
  std::vector<double> levels_m{std::numeric_limits<double>::infinity(), 1.0, 0.5, 0.25, 0.1, 0.05};
  int max_iterations = 300;
  int max_iterations_per_level = 60;
  double settle_translation_m = 1e-5;
  double settle_rotation_rad = 1e-6;
  int min_correspondences = 3;
  std::vector<double> hypothesis_levels_m{std::numeric_limits<double>::infinity(), 0.5, 0.2};
  int hypothesis_iterations = 45;
};

class DistanceSchedule : public Schedule {
 public:
  DistanceSchedule(Levels final, Levels hypothesis, double settle_t, double settle_r,
                   std::size_t min_pairs)
      : final_(std::move(final)),
        hypothesis_(std::move(hypothesis)),
        settle_t_(settle_t),
        settle_r_(settle_r),
        min_pairs_(min_pairs) {}

  EndPass end_pass() const override { return EndPass::kAtEstimate; }
  std::size_t min_pairs() const override { return min_pairs_; }

  std::unique_ptr<StageState> begin(const RefineContext&, const Hypothesis&,
                                    LoopState* loop) const override {
    loop->level = 0;
    loop->level_iterations = 0;
    loop->max_distance_m = levels(*loop).distances_m.front();
    return nullptr;
  }

  // The budget replaces max_iterations (and caps max_iterations_per_level); the distance caps
  // the levels: those above it become one level at it, the finer ones stay (inf, 1, 0.5, 0.25,
  // 0.1, 0.05 capped at 0.3: 0.3, 0.25, 0.1, 0.05). The hypotheses' own levels stay.
  std::vector<std::pair<std::string, SettingValue>> limits(
      const Settings& s, std::optional<int> max_iterations,
      std::optional<double> max_distance_m) const override {
    check_limits(max_iterations, max_distance_m);
    std::vector<std::pair<std::string, SettingValue>> out;
    if (max_iterations) {
      out.emplace_back("schedule.max_iterations", static_cast<long long>(*max_iterations));
      out.emplace_back(
          "schedule.max_iterations_per_level",
          std::min<long long>(s.integer("schedule.max_iterations_per_level"), *max_iterations));
    }
    if (max_distance_m && std::isfinite(*max_distance_m)) {
      std::vector<double> capped{*max_distance_m};
      for (double d : s.reals("schedule.levels_m")) {
        if (d < *max_distance_m) capped.push_back(d);
      }
      out.emplace_back("schedule.levels_m", capped);
    }
    return out;
  }

  TerminationReason after_step(const RefineContext&, StageState*, const Step& step, const Pairs&,
                               LoopState* loop) const override {
    const Levels& l = levels(*loop);
    const bool settled = step.increment.translation().norm() < settle_t_ &&
                         Eigen::AngleAxisd(step.increment.linear()).angle() < settle_r_;
    if (settled || loop->level_iterations >= l.max_iterations_per_level) {
      if (loop->level + 1 == l.distances_m.size()) {
        if (settled) {
          return step.degenerate ? TerminationReason::kDegenerate : TerminationReason::kTransform;
        }
        // not settled at the last level: go on until the budget ends
      } else {
        ++loop->level;
        loop->level_iterations = 0;
        loop->max_distance_m = l.distances_m[loop->level];
      }
    }
    if (loop->iterations >= l.max_iterations) return TerminationReason::kMaxIterations;
    return TerminationReason::kNotTerminated;
  }

 private:
  const Levels& levels(const LoopState& loop) const {
    return loop.phase == Phase::kHypothesis ? hypothesis_ : final_;
  }
  Levels final_;
  Levels hypothesis_;
  double settle_t_;
  double settle_r_;
  std::size_t min_pairs_;
};

SettingBound schedule_bound() {
  SettingBound b = SettingBound::above_or_inf(0.0);
  b.min_size = 1;
  b.max_size = 1000;
  b.non_increasing = true;
  return b;
}

const SettingsBinding<DistanceLevelsOptions>& binding() {
  static const SettingsBinding<DistanceLevelsOptions> b =
      SettingsBinding<DistanceLevelsOptions>("DistanceLevelsOptions")
          .add("schedule.levels_m", LMALIGN_FIELD(levels_m), schedule_bound(), "m",
               "maximum correspondence distance per level (inf = unlimited)")
          .add("schedule.max_iterations", LMALIGN_FIELD(max_iterations),
               SettingBound::closed(1, 2147483647), "count", "iterations over all levels")
          .add("schedule.max_iterations_per_level", LMALIGN_FIELD(max_iterations_per_level),
               SettingBound::closed(1, 2147483647), "count",
               "iterations at one level before the next applies anyway")
          .add("schedule.settle_translation_m", LMALIGN_FIELD(settle_translation_m),
               SettingBound::at_least(0.0), "m",
               "an increment below this translation (and rotation) has settled")
          .add("schedule.settle_rotation_rad", LMALIGN_FIELD(settle_rotation_rad),
               SettingBound::at_least(0.0), "rad",
               "an increment below this rotation (and translation) has settled")
          .add("schedule.min_correspondences", LMALIGN_FIELD(min_correspondences),
               SettingBound::closed(3, 2147483647), "count",
               "fewer pairs end the run (no_correspondences)")
          .add("schedule.hypothesis_levels_m", LMALIGN_FIELD(hypothesis_levels_m), schedule_bound(),
               "m", "levels of the short runs that refine a search's hypotheses")
          .add("schedule.hypothesis_iterations", LMALIGN_FIELD(hypothesis_iterations),
               SettingBound::closed(1, 2147483647), "count",
               "iterations of each hypothesis' short run, over all its levels");
  return b;
}

}  // namespace

std::vector<SettingRow> schedule_distance_settings() { return binding().rows(); }

std::unique_ptr<Stage> make_schedule_distance(const Settings& s) {
  const DistanceLevelsOptions o = binding().read(s);
  Levels final;
  final.distances_m = o.levels_m;
  final.max_iterations = o.max_iterations;
  final.max_iterations_per_level = o.max_iterations_per_level;
  Levels hyp;
  hyp.distances_m = o.hypothesis_levels_m;
  hyp.max_iterations = o.hypothesis_iterations;
  hyp.max_iterations_per_level =
      std::max(1, hyp.max_iterations / static_cast<int>(hyp.distances_m.size()));
  return std::make_unique<DistanceSchedule>(final, hyp, o.settle_translation_m,
                                            o.settle_rotation_rad,
                                            static_cast<std::size_t>(o.min_correspondences));
}

}  // namespace lmalign::stages
