// Estimator "umeyama": the weighted closed-form rigid transform of the point pairs (Umeyama /
// Kabsch without scale, estimation.hpp; PCL's TransformationEstimationSVD), composed on the left
// of the estimate; with the loop's free scale, Umeyama's similarity (eq. 42). With estimate.dof
// 4: x, y, z and the yaw about estimate.up only, in closed form (estimation_4dof.hpp), roll and
// pitch kept (gravity-aligned maps). Its covariance: point_to_point_covariance (uncertainty.hpp)
// of the pairs, 7x7 with the scale.
#include "lmalign/registration/estimation.hpp"
#include "lmalign/registration/estimation_4dof.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(estimate_umeyama)

namespace lmalign::stages {

namespace {

struct UmeyamaOptions {
  int dof = 6;              ///< 6, or 4 (x, y, z and the yaw about `up`)
  Vec3 up = Vec3::UnitZ();  ///< the maps' shared vertical (unit; 4 DoF)
};

class Umeyama : public Estimator {
 public:
  explicit Umeyama(UmeyamaOptions o) : o_(o) {}
  Pairs::Kind needs() const override { return Pairs::Kind::kPoints; }
  int degrees_of_freedom() const override { return o_.dof; }
  bool estimates_scale() const override { return o_.dof == 6; }

  Step solve(const RefineContext& c, const LoopState& loop, const Pairs& pairs, const Pose& current,
             const Isometry3&) const override {
    Step step;
    EstimationReport report;
    const std::vector<double>* w = pairs.weights.empty() ? nullptr : &pairs.weights;
    if (o_.dof == 4) {
      step.increment =
          estimate_4dof_transform(pairs.moved, c.target->points(), pairs.points, w, o_.up);
      step.estimate.T_target_source = step.increment * current.T_target_source;
      return step;
    }
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
                            const Pairs& pairs, const Pose&, const Step*) const override {
    return point_to_point_covariance(pairs.moved, c.target->points(), pairs.points,
                                     pairs.weights.empty() ? nullptr : &pairs.weights,
                                     loop.free_scale && o_.dof == 6);
  }

 private:
  UmeyamaOptions o_;
};

}  // namespace

std::vector<SettingRow> estimate_umeyama_settings() {
  const UmeyamaOptions d;
  return {
      choice_setting("estimate.dof", "UmeyamaOptions::dof", std::to_string(d.dof), {"6", "4"},
                     "degrees of freedom: 6, or 4 (x, y, z and the yaw about estimate.up; roll "
                     "and pitch kept)"),
      reals_setting("estimate.up", "UmeyamaOptions::up", {d.up.x(), d.up.y(), d.up.z()},
                    vector3_bound(), "1",
                    "4 DoF: the maps' shared vertical, each in its own frame (normalised)"),
  };
}

std::unique_ptr<Stage> make_estimate_umeyama(const Settings& s) {
  UmeyamaOptions o;
  o.dof = std::stoi(s.choice("estimate.dof"));
  o.up = unit_vector(s, "estimate.up");
  return std::make_unique<Umeyama>(o);
}

}  // namespace lmalign::stages
