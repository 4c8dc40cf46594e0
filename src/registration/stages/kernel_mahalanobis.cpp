// Kernel "cauchy_mahalanobis": the Cauchy weight 1 / (1 + d^2 / kernel.scale_d2) of each pair's
// Mahalanobis distance d^2 from the gate (the adaptive default), times an optional landmark
// confidence.
#include "lmalign/registration/stages/p2d_step.hpp"
#include "lmalign/weights/weights.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(kernel_cauchy_mahalanobis)

namespace lmalign::stages {

namespace {

struct CauchyMahalanobisOptions {
  double scale_d2 = kChi2Dof3P99;
  WeightKind confidence = WeightKind::kUniform;
};

class CauchyMahalanobis : public Kernel {
 public:
  bool accepts(int kind) const override {
    return kind == static_cast<int>(Pairs::Kind::kDistributions);
  }
  CauchyMahalanobis(double scale_d2, WeightKind confidence)
      : scale_d2_(scale_d2), confidence_(confidence) {}

  WeightKind confidence() const override { return confidence_; }

  void weigh(const RefineContext& c, const LoopState&, const Pairs& pairs, const Isometry3&,
             const Isometry3&, std::vector<double>* weights) const override {
    const std::vector<double>* confidence =
        confidence_ == WeightKind::kUniform ? nullptr : &c.target->weights(confidence_);
    *weights = cauchy_weights(pairs.gated, scale_d2_);
    if (confidence != nullptr) {
      for (std::size_t i = 0; i < weights->size(); ++i) {
        (*weights)[i] = (*confidence)[pairs.gated[i].target_index] * (*weights)[i];
      }
    }
  }

 private:
  double scale_d2_;
  WeightKind confidence_;
};

}  // namespace

std::vector<SettingRow> kernel_cauchy_mahalanobis_settings() {
  const CauchyMahalanobisOptions d;
  return {real_setting("kernel.scale_d2", "CauchyMahalanobisOptions::scale_d2", d.scale_d2,
                       SettingBound::above(0.0), "1",
                       "Cauchy scale on the Mahalanobis d^2 (the gate's chi-square by default)"),
          choice_setting("kernel.confidence", "CauchyMahalanobisOptions::confidence",
                         to_string(d.confidence), confidence_names(),
                         "landmark confidence of the matched target landmark, multiplied into "
                         "each pair's weight")};
}

std::unique_ptr<Stage> make_kernel_cauchy_mahalanobis(const Settings& s) {
  return std::make_unique<CauchyMahalanobis>(s.real("kernel.scale_d2"),
                                             parse_weight_kind(s.choice("kernel.confidence")));
}

}  // namespace lmalign::stages
