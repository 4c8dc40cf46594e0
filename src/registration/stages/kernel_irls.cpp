// Kernels "none", "huber", "cauchy", "geman_mcclure": each pair's weight is the target
// landmark's confidence (weights.hpp) times the IRLS weight of its residual (robust_weight,
// robust.hpp) at the scale max(kernel.scale_m, kernel.scale_ratio x the level's maximum
// distance), re-weighted kernel.irls_iterations times per iteration on fixed pairs (Zhang 1997),
// on the Euclidean residual at the re-weighting's estimate.
#include <cmath>

#include "lmalign/registration/robust.hpp"
#include "lmalign/weights/weights.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(kernel_none)
LMALIGN_STAGE_FUNCTIONS(kernel_huber)
LMALIGN_STAGE_FUNCTIONS(kernel_cauchy)
LMALIGN_STAGE_FUNCTIONS(kernel_geman_mcclure)

namespace lmalign::stages {

namespace {

struct IrlsOptions {
  RobustKernel kernel = RobustKernel::kNone;
  WeightKind confidence = WeightKind::kUniform;
  double scale_m = 0.02;
  double scale_ratio = 0.5;
  int irls_iterations = 3;
};

class IrlsKernel : public Kernel {
 public:
  explicit IrlsKernel(IrlsOptions o) : o_(o) {}

  WeightKind confidence() const override { return o_.confidence; }

  int reweightings() const override {
    return o_.kernel == RobustKernel::kNone ? 1 : o_.irls_iterations;
  }

  void weigh(const RefineContext& c, const LoopState& loop, const Pairs& pairs, const Isometry3&,
             const Isometry3& increment, std::vector<double>* weights) const override {
    const std::vector<double>* confidence =
        o_.confidence == WeightKind::kUniform ? nullptr : &c.target->weights(o_.confidence);
    if (o_.kernel == RobustKernel::kNone && confidence == nullptr) {
      weights->clear();  // all 1
      return;
    }
    const Points3& tp = c.target->points();
    weights->resize(pairs.size());
    if (pairs.kind == Pairs::Kind::kDistributions) {
      // The kernel of the Euclidean residual at the estimate increment * T.
      const double scale = std::max(o_.scale_m, o_.scale_ratio * loop.max_distance_m);
      for (std::size_t i = 0; i < pairs.gated.size(); ++i) {
        const GatedPair& g = pairs.gated[i];
        const double conf = confidence ? (*confidence)[g.target_index] : 1.0;
        const Vec3 r = increment * g.moved_source_m - tp[g.target_index];
        (*weights)[i] = conf * robust_weight(o_.kernel, r.norm(), scale);
      }
      return;
    }
    const double scale = std::max(o_.scale_m, o_.scale_ratio * loop.max_distance_m);
    for (std::size_t i = 0; i < pairs.points.size(); ++i) {
      const Correspondence& p = pairs.points[i];
      const double conf = confidence ? (*confidence)[p.target_index] : 1.0;
      // After the last step, the pair's own distance; during the loop, the residual at the
      // re-weighting's estimate.
      double rn = 0.0;
      if (loop.final_pass) {
        rn = std::sqrt(p.distance_sq_m2);
      } else {
        const Vec3 r = increment * pairs.moved[p.source_index] - tp[p.target_index];
        rn = r.norm();
      }
      (*weights)[i] = conf * robust_weight(o_.kernel, rn, scale);
    }
  }

 private:
  IrlsOptions o_;
};

SettingRow confidence_row() {
  const IrlsOptions d;
  return choice_setting("kernel.confidence", "IrlsOptions::confidence", to_string(d.confidence),
                        confidence_names(),
                        "landmark confidence of the matched target landmark, multiplied into each "
                        "pair's weight (Eqs. 1-4)");
}

const SettingsBinding<IrlsOptions>& robust_binding() {
  static const SettingsBinding<IrlsOptions> b =
      SettingsBinding<IrlsOptions>("IrlsOptions")
          .add("kernel.scale_m", LMALIGN_FIELD(scale_m), SettingBound::above(0.0), "m",
               "kernel scale at the finest levels: max(this, scale_ratio x the level's maximum "
               "distance)")
          .add("kernel.scale_ratio", LMALIGN_FIELD(scale_ratio), SettingBound::at_least(0.0), "1",
               "kernel scale as a fraction of the level's maximum distance (an unlimited level is "
               "unweighted)")
          .add("kernel.irls_iterations", LMALIGN_FIELD(irls_iterations),
               SettingBound::closed(1, 1000), "count",
               "re-weightings per iteration on fixed pairs");
  return b;
}

std::vector<SettingRow> robust_rows() {
  std::vector<SettingRow> rows = {confidence_row()};
  rows.insert(rows.end(), robust_binding().rows().begin(), robust_binding().rows().end());
  return rows;
}

std::unique_ptr<Stage> make(RobustKernel kernel, const Settings& s) {
  IrlsOptions o;
  o.kernel = kernel;
  o.confidence = parse_weight_kind(s.choice("kernel.confidence"));
  if (kernel != RobustKernel::kNone) robust_binding().read(s, &o);
  return std::make_unique<IrlsKernel>(o);
}

}  // namespace

std::vector<SettingRow> kernel_none_settings() { return {confidence_row()}; }
std::unique_ptr<Stage> make_kernel_none(const Settings& s) { return make(RobustKernel::kNone, s); }
std::vector<SettingRow> kernel_huber_settings() { return robust_rows(); }
std::unique_ptr<Stage> make_kernel_huber(const Settings& s) {
  return make(RobustKernel::kHuber, s);
}
std::vector<SettingRow> kernel_cauchy_settings() { return robust_rows(); }
std::unique_ptr<Stage> make_kernel_cauchy(const Settings& s) {
  return make(RobustKernel::kCauchy, s);
}
std::vector<SettingRow> kernel_geman_mcclure_settings() { return robust_rows(); }
std::unique_ptr<Stage> make_kernel_geman_mcclure(const Settings& s) {
  return make(RobustKernel::kGemanMcClure, s);
}

}  // namespace lmalign::stages
