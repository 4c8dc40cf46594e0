// Estimator "umeyama": the weighted closed-form rigid transform of the point pairs (Umeyama /
// Kabsch without scale, estimation.hpp; PCL's TransformationEstimationSVD), composed on the left
// of the estimate; with the loop's free scale, Umeyama's similarity (eq. 42). Its covariance:
// point_to_point_covariance (uncertainty.hpp) of the pairs, 7x7 with the scale.
#include "lmalign/registration/estimation.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(estimate_umeyama)

namespace lmalign::stages {

namespace {

class Umeyama : public Estimator {
 public:
  Pairs::Kind needs() const override { return Pairs::Kind::kPoints; }
  bool estimates_scale() const override { return true; }

  Step solve(const RefineContext& c, const LoopState& loop, const Pairs& pairs, const Pose& current,
             const Isometry3&) const override {
    Step step;
    EstimationReport report;
    const std::vector<double>* w = pairs.weights.empty() ? nullptr : &pairs.weights;
    if (!loop.free_scale) {
      step.increment =
          estimate_rigid_transform(pairs.moved, c.target->points(), pairs.points, w, &report);
      step.degenerate = report.degenerate;
      step.estimate.T_target_source = step.increment * current.T_target_source;
      return step;
    }
    // dS (T p) = dR R (s p) + s dR t + dt: the rigid part for the source rescaled by s.
    const Similarity3 dS =
        estimate_similarity_transform(pairs.moved, c.target->points(), pairs.points, w, &report);
    step.increment = dS.rigid;
    step.degenerate = report.degenerate;
    step.estimate.scale = dS.scale;
    step.estimate.T_target_source.linear() = dS.rigid.linear() * current.T_target_source.linear();
    step.estimate.T_target_source.translation() =
        dS.scale * (dS.rigid.linear() * current.T_target_source.translation()) +
        dS.rigid.translation();
    return step;
  }

  PoseCovariance covariance(const RefineContext& c, const Pipeline&, const LoopState& loop,
                            const Pairs& pairs, const Pose&, const Step*,
                            std::size_t*) const override {
    return point_to_point_covariance(pairs.moved, c.target->points(), pairs.points,
                                     pairs.weights.empty() ? nullptr : &pairs.weights,
                                     loop.free_scale);
  }
};

}  // namespace

std::vector<SettingRow> estimate_umeyama_settings() { return {}; }

std::unique_ptr<Stage> make_estimate_umeyama(const Settings&) {
  return std::make_unique<Umeyama>();
}

}  // namespace lmalign::stages
