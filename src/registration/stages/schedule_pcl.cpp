// Schedule "pcl": one fixed maximum correspondence distance and PCL's
// DefaultConvergenceCriteria as IterativeClosestPoint configures it (convergence.hpp; the
// paper's ICP, method.md §3). A run whose last step was a minimiser among many reports
// kDegenerate instead of the criterion that stopped it (docs/robustness.md).
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(schedule_pcl)

namespace lmalign::stages {

namespace {

/// The schedule's settings: PCL's criteria and its one correspondence distance.
struct PclScheduleOptions {
  ConvergenceOptions convergence;
  double max_distance_m = CorrespondenceOptions{}.max_distance_m;
};

class PclSchedule : public Schedule {
 public:
  explicit PclSchedule(const PclScheduleOptions& o)
      : o_(o.convergence), max_distance_m_(o.max_distance_m) {}

  struct State : StageState {
    explicit State(const ConvergenceOptions& o) : criteria(o) {}
    ConvergenceCriteria criteria;
  };

  std::unique_ptr<StageState> begin(const RefineContext&, const Hypothesis&,
                                    LoopState* loop) const override {
    loop->max_distance_m = max_distance_m_;
    return std::make_unique<State>(o_);
  }
  std::size_t min_pairs() const override {
    return static_cast<std::size_t>(o_.min_correspondences);
  }
  TerminationReason after_step(const RefineContext&, StageState* state, const Step& step,
                               const Pairs& pairs, LoopState* loop) const override {
    return static_cast<State*>(state)->criteria.check(loop->iterations, step.increment,
                                                      pairs.points);
  }
  std::vector<std::pair<std::string, SettingValue>> limits(
      const Settings&, std::optional<int> max_iterations,
      std::optional<double> max_distance_m) const override {
    std::vector<std::pair<std::string, SettingValue>> out;
    check_limits(max_iterations, max_distance_m);
    if (max_iterations)
      out.emplace_back("schedule.max_iterations", static_cast<long long>(*max_iterations));
    if (max_distance_m) out.emplace_back("schedule.max_distance_m", *max_distance_m);
    return out;
  }
  TerminationReason finish(TerminationReason reason, bool last_degenerate) const override {
    // The rotation of a rank-deficient last step is one minimiser among many: say so.
    if (last_degenerate && reason != TerminationReason::kNoCorrespondences) {
      return TerminationReason::kDegenerate;
    }
    return reason;
  }

 private:
  ConvergenceOptions o_;
  double max_distance_m_;
};

const SettingsBinding<PclScheduleOptions>& binding() {
  static const SettingsBinding<PclScheduleOptions> b =
      SettingsBinding<PclScheduleOptions>("PclScheduleOptions")
          .add("schedule.max_distance_m", LMALIGN_FIELD(max_distance_m),
               SettingBound::above_or_inf(0.0), "m",
               "maximum correspondence distance (the paper's: unlimited)")
          .add("schedule.max_iterations", LMALIGN_FIELD(convergence.max_iterations),
               SettingBound::closed(1, 2147483647), "count",
               "iteration budget (PCL setMaximumIterations)")
          .add("schedule.transformation_epsilon_m2",
               LMALIGN_FIELD(convergence.transformation_epsilon_m2), SettingBound::at_least(0.0),
               "m^2",
               "PCL setTransformationEpsilon: an increment whose squared translation is at most "
               "this (and rotation passes) ends the run")
          .add("schedule.transformation_rotation_epsilon_cos",
               LMALIGN_FIELD(convergence.transformation_rotation_epsilon_cos),
               SettingBound::closed(-std::numeric_limits<double>::max(), 1.0), "1",
               "PCL setTransformationRotationEpsilon (cosine; <= 0: 1 - the translation epsilon)")
          .add("schedule.euclidean_fitness_epsilon",
               LMALIGN_FIELD(convergence.euclidean_fitness_epsilon), SettingBound{}, "1",
               "PCL setEuclideanFitnessEpsilon: relative MSE change (the lowest number: off)")
          .add("schedule.absolute_mse_epsilon_m2",
               LMALIGN_FIELD(convergence.absolute_mse_epsilon_m2), SettingBound{}, "m^2",
               "DefaultConvergenceCriteria's absolute MSE change")
          .add("schedule.max_iterations_similar_transforms",
               LMALIGN_FIELD(convergence.max_iterations_similar_transforms),
               SettingBound::closed(0, 2147483647), "count",
               "PCL setMaximumIterationsSimilarTransforms")
          .add("schedule.min_correspondences", LMALIGN_FIELD(convergence.min_correspondences),
               SettingBound::closed(3, 2147483647), "count",
               "fewer pairs end the run (no_correspondences)");
  return b;
}

}  // namespace
}  // namespace lmalign::stages

LMALIGN_BOUND_STAGE(schedule_pcl, PclSchedule)
