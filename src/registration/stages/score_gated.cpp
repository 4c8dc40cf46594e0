// Scorer "gated_inliers": a hypothesis' covariance-gated inlier score, the sum over the pairs the
// matcher keeps at zero pose uncertainty of their evidence, 1 - d^2 / chi2 less for vague pairs
// (pair_evidence, stages/mahalanobis_gate.hpp; Scales::evidence). Each hypothesis is refined on
// score.samples evenly strided source landmarks and scored on every landmark (score.every_landmark;
// false: on the same samples). A pose refined on a sample fits that sample: scored there, a
// wrong hypothesis's rivals and the answer's score move with the draw (docs/accuracy.md, "Refined
// on samples, scored on every landmark"). A hypothesis that loses to its own start is refined
// again from it with a sharp gate when its start could matter (score.sharp_restart_share).
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(score_gated)

namespace lmalign::stages {

namespace {

struct GatedScoreOptions {
  int samples = 1024;
  bool every_landmark = true;
  double sharp_restart_share = 0.7;
};

class GatedScorer : public Scorer {
 public:
  GatedScorer(std::size_t samples, bool every_landmark, double sharp_restart_share)
      : samples_(samples),
        every_landmark_(every_landmark),
        sharp_restart_share_(sharp_restart_share) {}
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

  std::vector<std::uint32_t> scoring_samples(std::size_t n) const override {
    if (!every_landmark_) return samples(n);
    std::vector<std::uint32_t> out(n);
    for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<std::uint32_t>(i);
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

  double sharp_restart_share() const override { return sharp_restart_share_; }

 private:
  std::size_t samples_;
  bool every_landmark_;
  double sharp_restart_share_;
};

}  // namespace

std::vector<SettingRow> score_gated_settings() {
  return {int_setting("score.samples", "GatedScoreOptions::samples", GatedScoreOptions{}.samples,
                      SettingBound::closed(16, 2147483647), "count",
                      "source landmarks (evenly strided) on which each hypothesis is refined; the "
                      "best is then refined on all"),
          bool_setting("score.every_landmark", "GatedScoreOptions::every_landmark",
                       GatedScoreOptions{}.every_landmark,
                       "each refined hypothesis is scored, ranked and compared with its rivals on "
                       "every source landmark (false: on the samples it was refined on)"),
          real_setting("score.sharp_restart_share", "GatedScoreOptions::sharp_restart_share",
                       GatedScoreOptions{}.sharp_restart_share, SettingBound::closed(0.0, 1.0), "1",
                       "a search's hypothesis whose refinement scores below its start on the "
                       "samples, and whose start scores this share of the best refined "
                       "hypothesis, is refined again from its start with a sharp gate; 0: never")};
}

std::unique_ptr<Stage> make_score_gated(const Settings& s) {
  return std::make_unique<GatedScorer>(static_cast<std::size_t>(s.integer("score.samples")),
                                       s.boolean("score.every_landmark"),
                                       s.real("score.sharp_restart_share"));
}

}  // namespace lmalign::stages
