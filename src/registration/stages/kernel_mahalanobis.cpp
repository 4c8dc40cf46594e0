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
  explicit CauchyMahalanobis(const CauchyMahalanobisOptions& o)
      : scale_d2_(o.scale_d2), confidence_(o.confidence) {}

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

const SettingsBinding<CauchyMahalanobisOptions>& binding() {
  static const SettingsBinding<CauchyMahalanobisOptions> b =
      SettingsBinding<CauchyMahalanobisOptions>("CauchyMahalanobisOptions")
          .add("kernel.scale_d2", LMALIGN_FIELD(scale_d2), SettingBound::above(0.0), "1",
               "Cauchy scale on the Mahalanobis d^2 (the gate's chi-square by default)");
  return b;
}

}  // namespace

std::vector<SettingRow> kernel_cauchy_mahalanobis_settings() {
  // The confidence is a name of weights.hpp's WeightKind, read by parse_weight_kind.
  std::vector<SettingRow> rows = binding().rows();
  rows.push_back(choice_setting("kernel.confidence", "CauchyMahalanobisOptions::confidence",
                                to_string(CauchyMahalanobisOptions{}.confidence),
                                confidence_names(),
                                "landmark confidence of the matched target landmark, multiplied "
                                "into each pair's weight"));
  return rows;
}

std::unique_ptr<Stage> make_kernel_cauchy_mahalanobis(const Settings& s) {
  CauchyMahalanobisOptions o = binding().read(s);
  o.confidence = parse_weight_kind(s.choice("kernel.confidence"));
  return std::make_unique<CauchyMahalanobis>(o);
}

}  // namespace lmalign::stages
