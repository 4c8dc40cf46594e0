// Scorer "consensus": a hypothesis' score is the number of source landmarks (every
// score.stride-th) within score.inlier_distance_m of a target landmark at its estimate.
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(score_consensus)

namespace lmalign::stages {

namespace {

struct ConsensusOptions {
  int stride = 4;
  double inlier_distance_m = 0.1;
};

class ConsensusScorer : public Scorer {
 public:
  explicit ConsensusScorer(const ConsensusOptions& o)
      : stride_(static_cast<std::size_t>(o.stride)), distance_m_(o.inlier_distance_m) {}

  std::vector<std::uint32_t> samples(std::size_t n) const override {
    std::vector<std::uint32_t> out;
    for (std::size_t i = 0; i < n; i += stride_) out.push_back(static_cast<std::uint32_t>(i));
    return out;
  }

  double score(const RefineContext& c, const Pipeline&, const Isometry3& T) const override {
    std::size_t n = 0;
    const double d2max = distance_m_ * distance_m_;
    for (const Vec3& p : *c.source.positions) {
      PointIndex idx = 0;
      double d2 = 0.0;
      if (c.target->tree().nearest(T * p, &idx, &d2) && d2 <= d2max) ++n;
    }
    return static_cast<double>(n);
  }

 private:
  std::size_t stride_;
  double distance_m_;
};

const SettingsBinding<ConsensusOptions>& binding() {
  static const SettingsBinding<ConsensusOptions> b =
      SettingsBinding<ConsensusOptions>("ConsensusOptions")
          .add("score.stride", LMALIGN_FIELD(stride), SettingBound::closed(1, 2147483647), "count",
               "every n-th source landmark refines and scores the hypotheses")
          .add("score.inlier_distance_m", LMALIGN_FIELD(inlier_distance_m),
               SettingBound::above(0.0), "m", "a landmark this close to a target landmark counts");
  return b;
}

}  // namespace
}  // namespace lmalign::stages

LMALIGN_BOUND_STAGE(score_consensus, ConsensusScorer)
