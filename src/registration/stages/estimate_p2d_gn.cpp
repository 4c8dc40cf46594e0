// Estimator "p2d_gn": at levels whose maximum distance is at most
// estimate.p2d_max_level_distance_m, Gauss-Newton on SE(3) of the point-to-distribution cost
// with both maps' landmark covariances (estimate_point_to_distribution, estimation_p2d.hpp),
// from the re-weighting's estimate so far; at coarser levels, Umeyama. The new estimate is the
// Gauss-Newton one itself (not a composition), which keeps it rigid.
#include "lmalign/registration/estimation.hpp"
#include "lmalign/registration/estimation_p2d.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(estimate_p2d_gn)

namespace lmalign::stages {

namespace {

class P2DGaussNewton : public Estimator {
 public:
  P2DGaussNewton(PointToDistributionOptions o, double max_level_m)
      : o_(o), max_level_m_(max_level_m) {}
  Pairs::Kind needs() const override { return Pairs::Kind::kPoints; }
  bool distribution_step(const LoopState& loop) const override {
    return loop.max_distance_m <= max_level_m_;
  }

  Step solve(const RefineContext& c, const LoopState& loop, const Pairs& pairs, const Pose& current,
             const Isometry3& increment) const override {
    const Isometry3& T = current.T_target_source;
    Step step;
    const std::vector<double>* w = pairs.weights.empty() ? nullptr : &pairs.weights;
    if (!distribution_step(loop)) {
      EstimationReport report;
      step.increment =
          estimate_rigid_transform(pairs.moved, c.target->points(), pairs.points, w, &report);
      step.degenerate = report.degenerate;
      step.estimate.T_target_source = step.increment * T;
      return step;
    }
    // On the source in its own frame (its covariances need no rotating).
    const std::vector<double> ones(pairs.points.size(), 1.0);
    const PointToDistributionResult g = estimate_point_to_distribution(
        *c.source.positions, c.target->points(), pairs.points, *c.source.covariances_m2,
        c.target->covariances_m2(), w != nullptr ? w : &ones, o_, increment * T);
    step.estimate.T_target_source = g.T_target_source;
    step.increment = g.T_target_source * T.inverse();
    step.degenerate = g.degenerate;
    return step;
  }

  PoseCovariance covariance(const RefineContext& c, const Pipeline&, const LoopState& loop,
                            const Pairs& pairs, const Pose& estimate, const Step*,
                            std::size_t*) const override {
    const std::vector<double>* w = pairs.weights.empty() ? nullptr : &pairs.weights;
    if (!distribution_step(loop)) {
      return point_to_point_covariance(pairs.moved, c.target->points(), pairs.points, w);
    }
    PoseCovariance pc;
    pc.num_correspondences = pairs.points.size();
    PointToDistributionOptions eval = o_;
    eval.max_iterations = 0;  // the normal equations at the estimate only
    const std::vector<double> ones(pairs.points.size(), 1.0);
    const PointToDistributionResult g = estimate_point_to_distribution(
        *c.source.positions, c.target->points(), pairs.points, *c.source.covariances_m2,
        c.target->covariances_m2(), w != nullptr ? w : &ones, eval, estimate.T_target_source);
    if (!g.degenerate) {
      pc.covariance = g.variance_factor * g.covariance;
      pc.sigma_m = std::sqrt(g.variance_factor);
      pc.valid = pc.covariance.allFinite();
    }
    return pc;
  }

 private:
  PointToDistributionOptions o_;
  double max_level_m_;
};

}  // namespace

std::vector<SettingRow> estimate_p2d_gn_settings() {
  return {
      int_setting("estimate.p2d_iterations", "PointToDistributionOptions::max_iterations", 1,
                  SettingBound::closed(0, 1000), "count",
                  "Gauss-Newton steps per re-weighting (the loop iterates anyway)"),
      real_setting("estimate.p2d_step_tolerance", "PointToDistributionOptions::step_tolerance",
                   1e-12, SettingBound::at_least(0.0), "1",
                   "stop once a step moves less than this (|rho| m + |phi| rad)"),
      real_setting("estimate.p2d_floor_m", "PointToDistributionOptions::covariance_floor_m", 0.005,
                   SettingBound::at_least(1e-9), "m",
                   "covariance floor added to every pair's combined covariance"),
      real_setting("estimate.p2d_max_level_distance_m",
                   "RobustRegistrationOptions::p2d_max_level_distance_m", 0.1,
                   SettingBound::above_or_inf(0.0), "m",
                   "the point-to-distribution cost acts at levels whose maximum distance is at "
                   "most this (coarser levels: Umeyama)"),
  };
}

std::unique_ptr<Stage> make_estimate_p2d_gn(const Settings& s) {
  PointToDistributionOptions o;
  o.max_iterations = static_cast<int>(s.integer("estimate.p2d_iterations"));
  o.step_tolerance = s.real("estimate.p2d_step_tolerance");
  o.covariance_floor_m = s.real("estimate.p2d_floor_m");
  return std::make_unique<P2DGaussNewton>(o, s.real("estimate.p2d_max_level_distance_m"));
}

}  // namespace lmalign::stages
