// Scorer "gated_inliers": a hypothesis' covariance-gated inlier score, the sum over the pairs the
// matcher keeps at zero pose uncertainty of their evidence, 1 - d^2 / chi2 less for vague pairs
// (pair_evidence, stages/mahalanobis_gate.hpp; Scales::evidence). Each hypothesis is refined on
// score.samples evenly strided source landmarks and scored on every landmark (score.every_landmark;
// false: on the same samples). A pose refined on a sample fits that sample: scored there, a
// wrong hypothesis's rivals and the answer's score move with the draw (docs/accuracy.md, "Refined
// on samples, scored on every landmark"). A hypothesis that loses to its own start is refined
// again from it with a sharp gate when its start could matter (score.sharp_restart_share).
// Except in a first pass, the contenders (score.contenders, within score.contender_share of the
// best) are refined again from their refined poses on score.contender_samples landmarks.
#include "lmalign/registration/stages/complete_search.hpp"  // strided_indices
#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(score_gated)

namespace lmalign::stages {

namespace {

struct GatedScoreOptions {
  int samples = 1024;
  bool every_landmark = true;
  double sharp_restart_share = 0.7;
  int contenders = 3;
  double contender_share = 0.7;
  int contender_samples = 4096;
};

class GatedScorer : public Scorer {
 public:
  explicit GatedScorer(const GatedScoreOptions& o) : o_(o) {}
  bool needs_scales() const override { return true; }
  bool accepts(int kind) const override {
    return kind == static_cast<int>(Pairs::Kind::kDistributions);
  }

  std::vector<std::uint32_t> samples(std::size_t n) const override {
    return strided_indices(n, static_cast<std::size_t>(o_.samples));
  }

  std::vector<std::uint32_t> scoring_samples(std::size_t n) const override {
    return o_.every_landmark ? strided_indices(n, n) : samples(n);
  }

  double score(const RefineContext& c, const Pipeline& pipeline,
               const Isometry3& T) const override {
    Pairs pairs;
    pipeline.matcher().match(c, nullptr, T, LoopState::for_scoring(), &pairs);
    double score = 0.0;
    for (const GatedPair& g : pairs.gated) score += pair_evidence(g, pairs.chi2_threshold);
    return score;
  }

  double sharp_restart_share() const override { return o_.sharp_restart_share; }
  std::size_t contenders() const override { return static_cast<std::size_t>(o_.contenders); }
  double contender_share() const override { return o_.contender_share; }
  std::vector<std::uint32_t> contender_samples(std::size_t n) const override {
    return strided_indices(n, static_cast<std::size_t>(o_.contender_samples));
  }

 private:
  GatedScoreOptions o_;
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
                       "hypothesis, is refined again from its start with a sharp gate; 0: never"),
          int_setting("score.contenders", "GatedScoreOptions::contenders",
                      GatedScoreOptions{}.contenders, SettingBound::closed(0, 64), "count",
                      "except in a first pass, at most this many of the best refined "
                      "hypotheses (each scoring score.contender_share of the best) are refined "
                      "again from their poses with a sharp gate on score.contender_samples "
                      "landmarks; 0: never"),
          real_setting("score.contender_share", "GatedScoreOptions::contender_share",
                       GatedScoreOptions{}.contender_share, SettingBound::closed(0.0, 1.0), "1",
                       "a refined hypothesis is a contender when it scores at least this share "
                       "of the best (score.contenders)"),
          int_setting("score.contender_samples", "GatedScoreOptions::contender_samples",
                      GatedScoreOptions{}.contender_samples, SettingBound::closed(16, 2147483647),
                      "count",
                      "source landmarks (evenly strided; every landmark of a smaller map) on "
                      "which the contenders are refined again")};
}

std::unique_ptr<Stage> make_score_gated(const Settings& s) {
  GatedScoreOptions o;
  o.samples = static_cast<int>(s.integer("score.samples"));
  o.every_landmark = s.boolean("score.every_landmark");
  o.sharp_restart_share = s.real("score.sharp_restart_share");
  o.contenders = static_cast<int>(s.integer("score.contenders"));
  o.contender_share = s.real("score.contender_share");
  o.contender_samples = static_cast<int>(s.integer("score.contender_samples"));
  return std::make_unique<GatedScorer>(o);
}

}  // namespace lmalign::stages
