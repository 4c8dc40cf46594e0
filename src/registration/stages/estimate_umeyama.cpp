// Estimator "umeyama": the weighted closed-form rigid transform of the point pairs (Umeyama /
// Kabsch without scale, estimation.hpp; PCL's TransformationEstimationSVD), composed on the left
// of the estimate. Its covariance: point_to_point_covariance (uncertainty.hpp) of the pairs.
#include "lmalign/registration/estimation.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(estimate_umeyama)

namespace lmalign::stages {

namespace {

class Umeyama : public Estimator {
 public:
  Pairs::Kind needs() const override { return Pairs::Kind::kPoints; }

  Step solve(const RefineContext& c, const LoopState&, const Pairs& pairs, const Pose& current,
             const Isometry3&) const override {
    Step step;
    EstimationReport report;
    step.increment =
        estimate_rigid_transform(pairs.moved, c.target->points(), pairs.points,
                                 pairs.weights.empty() ? nullptr : &pairs.weights, &report);
    step.degenerate = report.degenerate;
    step.estimate.T_target_source = step.increment * current.T_target_source;
    return step;
  }

  PoseCovariance covariance(const RefineContext& c, const Pipeline&, const LoopState&,
                            const Pairs& pairs, const Pose&, const Step*,
                            std::size_t*) const override {
    return point_to_point_covariance(pairs.moved, c.target->points(), pairs.points,
                                     pairs.weights.empty() ? nullptr : &pairs.weights);
  }
};

}  // namespace

std::vector<SettingRow> estimate_umeyama_settings() { return {}; }

std::unique_ptr<Stage> make_estimate_umeyama(const Settings&) {
  return std::make_unique<Umeyama>();
}

}  // namespace lmalign::stages
