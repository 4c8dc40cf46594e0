// Scorer "gated_inliers": a hypothesis' covariance-gated inlier score, the sum over the pairs the
// matcher keeps at zero pose uncertainty of their evidence, 1 - d^2 / chi2 less for vague pairs
// (pair_evidence, stages/mahalanobis_gate.hpp; Scales::evidence), on score.samples evenly
// strided source landmarks.
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(score_gated)

namespace lmalign::stages {

namespace {

struct GatedScoreOptions {
  int samples = 1024;
};

class GatedScorer : public Scorer {
 public:
  explicit GatedScorer(std::size_t samples) : samples_(samples) {}
  bool needs_scales() const override { return true; }
  bool accepts(int kind) const override {
    return kind == static_cast<int>(Pairs::Kind::kDistributions);
  }

  std::vector<std::uint32_t> samples(std::size_t n) const override {
    std::vector<std::uint32_t> out;
    const std::size_t m = std::min(n, samples_);
    out.reserve(m);
    for (std::size_t i = 0; i < m; ++i) out.push_back(static_cast<std::uint32_t>(i * n / m));
    return out;
  }

  double score(const RefineContext& c, const Pipeline& pipeline,
               const Isometry3& T) const override {
    Pairs pairs;
    pipeline.matcher().match(c, nullptr, T, LoopState::for_scoring(), &pairs);
    double score = 0.0;
    for (const GatedPair& g : pairs.gated) score += pair_evidence(g, pairs.chi2_threshold);
    return score;
  }

 private:
  std::size_t samples_;
};

}  // namespace

std::vector<SettingRow> score_gated_settings() {
  return {int_setting("score.samples", "GatedScoreOptions::samples", GatedScoreOptions{}.samples,
                      SettingBound::closed(16, 2147483647), "count",
                      "source landmarks (evenly strided) on which each hypothesis is refined and "
                      "scored; the best is then refined on all")};
}

std::unique_ptr<Stage> make_score_gated(const Settings& s) {
  return std::make_unique<GatedScorer>(static_cast<std::size_t>(s.integer("score.samples")));
}

}  // namespace lmalign::stages
