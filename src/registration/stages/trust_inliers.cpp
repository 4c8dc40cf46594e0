// Trust judge "inliers": judge_alignment (uncertainty.hpp): enough source landmarks within
// trust.inlier_distance_m of a target landmark, of all and of those within
// trust.overlap_distance_m, and a small point-to-point covariance on them (which it reports).
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(trust_inliers)

namespace lmalign::stages {

namespace {

class InlierJudge : public TrustJudge {
 public:
  explicit InlierJudge(TrustOptions o) : o_(o) {}
  Verdict judge(const JudgeContext& j) const override {
    PoseCovariance cov;
    const TrustVerdict t = judge_alignment(*j.context.source.positions, j.context.target->tree(),
                                           j.final->T, o_, &cov);
    Verdict v;
    v.trustworthy = t.trustworthy;
    v.reason = t.reason;
    v.inlier_fraction = t.inlier_fraction;
    v.overlap_fraction = t.overlap_fraction;
    v.num_inliers = cov.num_correspondences;
    v.inlier_ratio = t.overlap_fraction > 0.0 ? t.inlier_fraction / t.overlap_fraction : 0.0;
    v.covariance = cov;
    return v;
  }

 private:
  TrustOptions o_;
};

const SettingsBinding<TrustOptions>& binding() {
  static const SettingsBinding<TrustOptions> b =
      SettingsBinding<TrustOptions>("TrustOptions")
          .add("trust.inlier_distance_m", LMALIGN_FIELD(inlier_distance_m),
               SettingBound::above(0.0), "m", "a landmark this close to a target one is an inlier")
          .add("trust.overlap_distance_m", LMALIGN_FIELD(overlap_distance_m),
               SettingBound::above(0.0), "m",
               "a landmark this close is in the overlap (>= the inlier distance)")
          .add("trust.min_inlier_ratio", LMALIGN_FIELD(min_inlier_ratio),
               SettingBound::closed(0.0, 1.0), "1", "inliers over the overlap, at least")
          .add("trust.min_inlier_fraction", LMALIGN_FIELD(min_inlier_fraction),
               SettingBound::closed(0.0, 1.0), "1", "inliers over all source landmarks, at least")
          .add("trust.max_translation_sd_m", LMALIGN_FIELD(max_translation_sd_m),
               SettingBound::above(0.0), "m",
               "translation standard deviation along its worst axis, at most")
          .add("trust.max_rotation_sd_deg", LMALIGN_FIELD(max_rotation_sd_deg),
               SettingBound::above(0.0), "deg",
               "rotation standard deviation about its worst axis, at most");
  return b;
}

}  // namespace

std::vector<SettingRow> trust_inliers_settings() { return binding().rows(); }

std::unique_ptr<Stage> make_trust_inliers(const Settings& s) {
  const TrustOptions o = binding().read(s);
  std::string why;
  if (!o.is_valid(&why)) throw InvalidArgument("trust: " + why);
  return std::make_unique<InlierJudge>(o);
}

}  // namespace lmalign::stages
