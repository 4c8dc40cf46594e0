// Schedule "pcl": one fixed maximum correspondence distance and PCL's
// DefaultConvergenceCriteria as IterativeClosestPoint configures it (convergence.hpp; the
// paper's ICP, method.md §3). A run whose last step was a minimiser among many reports
// kDegenerate instead of the criterion that stopped it (docs/robustness.md).
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(schedule_pcl)

namespace lmalign::stages {

namespace {

class PclSchedule : public Schedule {
 public:
  PclSchedule(ConvergenceOptions o, double max_distance_m)
      : o_(o), max_distance_m_(max_distance_m) {}

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

}  // namespace

std::vector<SettingRow> schedule_pcl_settings() {
  const ConvergenceOptions d;
  return {
      real_setting("schedule.max_distance_m", "CorrespondenceOptions::max_distance_m",
                   CorrespondenceOptions{}.max_distance_m, SettingBound::above_or_inf(0.0), "m",
                   "maximum correspondence distance (the paper's: unlimited)"),
      int_setting("schedule.max_iterations", "ConvergenceOptions::max_iterations", d.max_iterations,
                  SettingBound::closed(1, 2147483647), "count",
                  "iteration budget (PCL setMaximumIterations)"),
      real_setting("schedule.transformation_epsilon_m2",
                   "ConvergenceOptions::transformation_epsilon_m2", d.transformation_epsilon_m2,
                   SettingBound::at_least(0.0), "m^2",
                   "PCL setTransformationEpsilon: an increment whose squared translation is at "
                   "most this (and rotation passes) ends the run"),
      real_setting("schedule.transformation_rotation_epsilon_cos",
                   "ConvergenceOptions::transformation_rotation_epsilon_cos",
                   d.transformation_rotation_epsilon_cos,
                   SettingBound::closed(-std::numeric_limits<double>::max(), 1.0), "1",
                   "PCL setTransformationRotationEpsilon (cosine; <= 0: 1 - the translation "
                   "epsilon)"),
      real_setting("schedule.euclidean_fitness_epsilon",
                   "ConvergenceOptions::euclidean_fitness_epsilon", d.euclidean_fitness_epsilon,
                   SettingBound{}, "1",
                   "PCL setEuclideanFitnessEpsilon: relative MSE change (the lowest number: off)"),
      real_setting("schedule.absolute_mse_epsilon_m2",
                   "ConvergenceOptions::absolute_mse_epsilon_m2", d.absolute_mse_epsilon_m2,
                   SettingBound{}, "m^2", "DefaultConvergenceCriteria's absolute MSE change"),
      int_setting("schedule.max_iterations_similar_transforms",
                  "ConvergenceOptions::max_iterations_similar_transforms",
                  d.max_iterations_similar_transforms, SettingBound::closed(0, 2147483647), "count",
                  "PCL setMaximumIterationsSimilarTransforms"),
      int_setting("schedule.min_correspondences", "ConvergenceOptions::min_correspondences",
                  d.min_correspondences, SettingBound::closed(3, 2147483647), "count",
                  "fewer pairs end the run (no_correspondences)"),
  };
}

std::unique_ptr<Stage> make_schedule_pcl(const Settings& s) {
  ConvergenceOptions o;
  o.max_iterations = static_cast<int>(s.integer("schedule.max_iterations"));
  o.transformation_epsilon_m2 = s.real("schedule.transformation_epsilon_m2");
  o.transformation_rotation_epsilon_cos = s.real("schedule.transformation_rotation_epsilon_cos");
  o.euclidean_fitness_epsilon = s.real("schedule.euclidean_fitness_epsilon");
  o.absolute_mse_epsilon_m2 = s.real("schedule.absolute_mse_epsilon_m2");
  o.max_iterations_similar_transforms =
      static_cast<int>(s.integer("schedule.max_iterations_similar_transforms"));
  o.min_correspondences = static_cast<int>(s.integer("schedule.min_correspondences"));
  return std::make_unique<PclSchedule>(o, s.real("schedule.max_distance_m"));
}

}  // namespace lmalign::stages
