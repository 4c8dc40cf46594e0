// Estimator "four_dof": x, y, z and the yaw about a map axis only, in closed form
// (estimate_4dof_transform, estimation_4dof.hpp), composed on the left of the estimate; roll and
// pitch are kept. For gravity-aligned maps.
#include "lmalign/registration/estimation_4dof.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(estimate_four_dof)

namespace lmalign::stages {

namespace {

class FourDof : public Estimator {
 public:
  explicit FourDof(UpAxis up) : up_(up) {}
  Pairs::Kind needs() const override { return Pairs::Kind::kPoints; }
  int degrees_of_freedom() const override { return 4; }

  Step solve(const RefineContext& c, const LoopState&, const Pairs& pairs, const Pose& current,
             const Isometry3&) const override {
    Step step;
    step.increment = estimate_4dof_transform(pairs.moved, c.target->points(), pairs.points,
                                             pairs.weights.empty() ? nullptr : &pairs.weights, up_);
    step.estimate.T_target_source = step.increment * current.T_target_source;
    return step;
  }

  PoseCovariance covariance(const RefineContext& c, const Pipeline&, const LoopState&,
                            const Pairs& pairs, const Pose&, const Step*,
                            std::size_t*) const override {
    return point_to_point_covariance(pairs.moved, c.target->points(), pairs.points,
                                     pairs.weights.empty() ? nullptr : &pairs.weights);
  }

 private:
  UpAxis up_;
};

}  // namespace

std::vector<SettingRow> estimate_four_dof_settings() {
  return {choice_setting("estimate.up_axis", "RobustRegistrationOptions::up_axis", "z",
                         {"x", "y", "z"}, "the map axis the yaw turns about (both maps share it)")};
}

std::unique_ptr<Stage> make_estimate_four_dof(const Settings& s) {
  return std::make_unique<FourDof>(parse_up_axis(s.choice("estimate.up_axis")));
}

}  // namespace lmalign::stages
