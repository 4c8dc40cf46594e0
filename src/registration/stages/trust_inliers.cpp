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

}  // namespace

std::vector<SettingRow> trust_inliers_settings() {
  const TrustOptions d;
  return {
      real_setting("trust.inlier_distance_m", "TrustOptions::inlier_distance_m",
                   d.inlier_distance_m, SettingBound::above(0.0), "m",
                   "a landmark this close to a target one is an inlier"),
      real_setting("trust.overlap_distance_m", "TrustOptions::overlap_distance_m",
                   d.overlap_distance_m, SettingBound::above(0.0), "m",
                   "a landmark this close is in the overlap (>= the inlier distance)"),
      real_setting("trust.min_inlier_ratio", "TrustOptions::min_inlier_ratio", d.min_inlier_ratio,
                   SettingBound::closed(0.0, 1.0), "1", "inliers over the overlap, at least"),
      real_setting("trust.min_inlier_fraction", "TrustOptions::min_inlier_fraction",
                   d.min_inlier_fraction, SettingBound::closed(0.0, 1.0), "1",
                   "inliers over all source landmarks, at least"),
      real_setting("trust.max_translation_sd_m", "TrustOptions::max_translation_sd_m",
                   d.max_translation_sd_m, SettingBound::above(0.0), "m",
                   "translation standard deviation along its worst axis, at most"),
      real_setting("trust.max_rotation_sd_deg", "TrustOptions::max_rotation_sd_deg",
                   d.max_rotation_sd_deg, SettingBound::above(0.0), "deg",
                   "rotation standard deviation about its worst axis, at most"),
  };
}

std::unique_ptr<Stage> make_trust_inliers(const Settings& s) {
  TrustOptions o;
  o.inlier_distance_m = s.real("trust.inlier_distance_m");
  o.overlap_distance_m = s.real("trust.overlap_distance_m");
  o.min_inlier_ratio = s.real("trust.min_inlier_ratio");
  o.min_inlier_fraction = s.real("trust.min_inlier_fraction");
  o.max_translation_sd_m = s.real("trust.max_translation_sd_m");
  o.max_rotation_sd_deg = s.real("trust.max_rotation_sd_deg");
  std::string why;
  if (!o.is_valid(&why)) throw InvalidArgument("trust: " + why);
  return std::make_unique<InlierJudge>(o);
}

}  // namespace lmalign::stages
