// Schedule "sigma_anneal": the gate's pose uncertainty starts at the hypothesis' (a fraction of
// the search's resolution, or of the prior) and is multiplied by sigma_decay each time the
// estimate settles (or after max_iterations_per_level), down to zero once below the covariance
// floor: the gate is never unbounded. The run ends when a step settles at zero uncertainty (a
// step below settle_ratio x the floor, and that over the source's radius in rotation), or after
// max_iterations; a cycle at zero uncertainty (2 to cycle_length steps that together settle:
// pairs that change their target landmark and change it back) ends it too.
// Final and resampled refinements start at zero. The covariance comes from the last step's
// normal equations.
#include <algorithm>
#include <vector>

#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(schedule_sigma)

namespace lmalign::stages {

namespace {

struct SigmaOptions {
  int max_iterations = 120;
  int max_iterations_per_level = 15;
  double sigma_decay = 0.5;
  double settle_ratio = 1e-3;
  double level_settle_ratio = 0.0;
  int cycle_length = 8;
};

class SigmaSchedule : public Schedule {
 public:
  explicit SigmaSchedule(SigmaOptions o) : o_(o) {}
  bool needs_scales() const override { return true; }
  EndPass end_pass() const override { return EndPass::kLastStep; }
  // A scale step counts in after_step() as the move it gives a landmark at the source's radius,
  // held to the same settle threshold as the translation.
  bool settles_scale() const override { return true; }

  // The last cycle_length steps at zero pose uncertainty, newest last: increment and log scale
  // step (the cycle test, below).
  struct State : StageState {
    std::vector<std::pair<Isometry3, double>> recent;
  };

  std::unique_ptr<StageState> begin(const RefineContext&, const Hypothesis& start,
                                    LoopState* loop) const override {
    loop->sigma = PoseSigma{};
    if (loop->phase == Phase::kHypothesis) {
      loop->sigma.translation_m = start.start_sigma_m;
      loop->sigma.rotation_rad = start.start_sigma_rad;
    }
    loop->level_iterations = 0;
    return std::make_unique<State>();
  }

  // The gate follows the covariances: there is no correspondence distance to cap.
  std::vector<std::pair<std::string, SettingValue>> limits(
      const Settings&, std::optional<int> max_iterations,
      std::optional<double> max_distance_m) const override {
    check_limits(max_iterations, max_distance_m);
    std::vector<std::pair<std::string, SettingValue>> out;
    if (max_iterations)
      out.emplace_back("schedule.max_iterations", static_cast<long long>(*max_iterations));
    return out;
  }

  bool may_iterate(const LoopState& loop) const override {
    return loop.iterations < o_.max_iterations;
  }

  TerminationReason after_step(const RefineContext& c, StageState* state, const Step& step,
                               const Pairs&, LoopState* loop) const override {
    const double floor = c.scales->floor_m;
    const double settle_t = o_.settle_ratio * floor;
    const double settle_r = settle_t / c.scales->source.radius_m;
    Vec6 xi = step.xi.head<6>();
    if (!step.has_xi) xi = pose_error_twist(step.increment, Isometry3::Identity());
    PoseSigma& sigma = loop->sigma;
    const bool at_zero = sigma.translation_m == 0.0 && sigma.rotation_rad == 0.0;
    // While the gate is wider than the floor, a step well below its width is settled enough. A
    // scale step moves a landmark at the source's radius by |sigma| times it: a translation.
    const double scale_move = std::abs(step.xi(6)) * c.scales->source.radius_m;
    const bool settled =
        xi.head<3>().norm() < std::max(settle_t, o_.level_settle_ratio * sigma.translation_m) &&
        xi.tail<3>().norm() < std::max(settle_r, o_.level_settle_ratio * sigma.rotation_rad) &&
        scale_move < std::max(settle_t, o_.level_settle_ratio * sigma.translation_m);
    if (settled && at_zero) return TerminationReason::kTransform;
    if (at_zero && state != nullptr) {
      // A cycle: the last 2 to cycle_length steps together move the source's centre, turn and
      // scale it less than the settle threshold, each step large: a pair that changes its
      // target landmark, or leaves the gate, and changes it back. The estimate has settled as
      // far as the data allow: converged. Measured: 2-cycles on the real desk pair from a right
      // prior (2,423 pairs, the estimate alternating to the iteration limit); 3-cycles in 2 of a
      // 15,000-landmark street's 18 half-sample refinements (163 of their 610 iterations, run to
      // the limit) and in street seed 10's final refinement, whose right answer was refused as
      // not converged (2026-11-28).
      auto& st = static_cast<State&>(*state);
      st.recent.emplace_back(step.increment, step.xi(6));
      if (st.recent.size() > static_cast<std::size_t>(o_.cycle_length)) {
        st.recent.erase(st.recent.begin());
      }
      const Vec3 pivot = step.estimate.T_target_source * c.scales->source.centre_m;
      const std::size_t n = st.recent.size();
      Isometry3 both = st.recent[n - 1].first;  // the last `back` steps composed
      double log_scale = st.recent[n - 1].second;
      for (std::size_t back = 2; back <= n; ++back) {
        both = both * st.recent[n - back].first;
        log_scale += st.recent[n - back].second;
        const double moved = (both * pivot - pivot).norm();
        const double turned = Eigen::AngleAxisd(both.linear()).angle();
        const double scaled = std::abs(log_scale) * c.scales->source.radius_m;
        if (moved < settle_t && turned < settle_r && scaled < settle_t) {
          return TerminationReason::kTransform;
        }
      }
    }
    const int per_level =
        loop->max_iterations_per_level > 0
            ? std::min(o_.max_iterations_per_level, loop->max_iterations_per_level)
            : o_.max_iterations_per_level;
    if ((settled || loop->level_iterations >= per_level) && !at_zero) {
      sigma.translation_m *= o_.sigma_decay;
      sigma.rotation_rad *= o_.sigma_decay;
      if (sigma.translation_m < floor && sigma.rotation_rad * c.scales->source.radius_m < floor) {
        sigma.translation_m = 0.0;
        sigma.rotation_rad = 0.0;
      }
      loop->level_iterations = 0;
      ++loop->level;
    }
    return TerminationReason::kNotTerminated;
  }

 private:
  SigmaOptions o_;
};

const SettingsBinding<SigmaOptions>& binding() {
  static const SettingsBinding<SigmaOptions> b =
      SettingsBinding<SigmaOptions>("SigmaOptions")
          .add("schedule.max_iterations", LMALIGN_FIELD(max_iterations),
               SettingBound::closed(1, 2147483647), "count", "iterations per refinement")
          .add("schedule.max_iterations_per_level", LMALIGN_FIELD(max_iterations_per_level),
               SettingBound::closed(1, 2147483647), "count",
               "iterations before the pose uncertainty shrinks anyway")
          .add("schedule.sigma_decay", LMALIGN_FIELD(sigma_decay), SettingBound::open(0.0, 1.0),
               "1",
               "each time the estimate settles the gate's pose uncertainty is multiplied by this")
          .add("schedule.settle_ratio", LMALIGN_FIELD(settle_ratio),
               SettingBound::open_closed(0.0, 1.0), "1",
               "settled: a step below this times the floor (and that over the source's radius in "
               "rotation)")
          .add("schedule.level_settle_ratio", LMALIGN_FIELD(level_settle_ratio),
               SettingBound::closed_open(0.0, 1.0), "1",
               "at a level whose pose uncertainty is above zero, a step below this fraction of it "
               "also counts as settled")
          .add("schedule.cycle_length", LMALIGN_FIELD(cycle_length), SettingBound::closed(2, 64),
               "count",
               "at zero pose uncertainty, 2 to this many steps that together settle end the "
               "refinement, converged (a limit cycle); 2: 2-cycles only");
  return b;
}

}  // namespace
}  // namespace lmalign::stages

LMALIGN_BOUND_STAGE(schedule_sigma, SigmaSchedule)
