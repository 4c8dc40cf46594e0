// Trust judge "gated" (the adaptive default's verdict, docs/accuracy.md): at the estimate,
// enough covariance-gated inliers; enough of the landmarks near a target landmark (those that
// pass the gate widened by one search resolution of pose uncertainty) among them, since a right
// pose puts the overlap within its covariances and a wrong one only near some landmark; their
// mean normalised innovation squared (NIS) within max_nis_ratio of its expectation (repeated
// structure aliases a pose with residuals the covariances do not explain); no distinct refined
// hypothesis scoring nearly as well; a non-degenerate covariance.
#include <cmath>

#include "lmalign/registration/stages/mahalanobis_gate.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(trust_gated)

namespace lmalign::stages {

namespace {

struct GatedTrustOptions {
  std::size_t min_inliers = 12;
  double min_inlier_ratio = 0.2;
  double max_nis_ratio = 1.1;
  double max_ambiguity = 0.85;
  double distinct_cells = 4.0;
};

// Two estimates are distinct poses when they move a landmark at the source's typical distance
// from its centre apart by more than `distance_m`.
bool distinct(const Isometry3& a, const Isometry3& b, const Vec3& centre, double radius_m,
              double distance_m) {
  const double angle = Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle();
  return ((a * centre) - (b * centre)).norm() + angle * radius_m > distance_m;
}

class GatedJudge : public TrustJudge {
 public:
  explicit GatedJudge(GatedTrustOptions o) : o_(o) {}
  bool needs_scales() const override { return true; }
  bool accepts(int kind) const override {
    return kind == static_cast<int>(Pairs::Kind::kDistributions);
  }

  Verdict judge(const JudgeContext& j) const override {
    const RefineContext& c = j.context;
    const Isometry3& T = j.final->T;
    const Scales& sc = *c.scales;
    Verdict v;
    {
      Pairs inliers;
      j.pipeline->matcher().match(c, nullptr, T, LoopState{}, &inliers);
      double sum_d2 = 0.0;
      for (const GatedPair& g : inliers.gated) {
        v.score += 1.0 - g.d2 / inliers.chi2_threshold;
        sum_d2 += g.d2;
      }
      v.num_inliers = inliers.gated.size();
      v.mean_nis = inliers.gated.empty() ? 0.0 : sum_d2 / static_cast<double>(inliers.gated.size());
      v.expected_nis = expected_gated_d2(inliers.chi2_threshold);
    }
    {
      LoopState wide;
      wide.sigma.translation_m = j.init->resolution_m;
      wide.sigma.pivot_m = T * sc.source.centre_m;
      Pairs near;
      j.pipeline->matcher().match(c, nullptr, T, wide, &near);
      v.num_overlap = near.gated.size();
      v.inlier_ratio = near.gated.empty() ? 0.0
                                          : static_cast<double>(v.num_inliers) /
                                                static_cast<double>(near.gated.size());
    }
    const std::vector<RefinedHypothesis>& h = *j.hypotheses;
    for (std::size_t i = 1; i < h.size(); ++i) {
      if (distinct(h[i].T_refined, h.front().T_refined, sc.source.centre_m, sc.source.radius_m,
                   o_.distinct_cells * j.init->resolution_m)) {
        v.ambiguity = h.front().score > 0.0 ? h[i].score / h.front().score : 1.0;
        break;
      }
    }
    const TerminationReason end = j.final->termination;
    if (end == TerminationReason::kNoCorrespondences) {
      v.reason = "no covariance-gated correspondences";
    } else if (end == TerminationReason::kDegenerate || !j.covariance->valid) {
      v.reason = "degenerate: the normal equations are singular";
    } else if (v.num_inliers < o_.min_inliers) {
      v.reason = "too few covariance-gated inliers (" + std::to_string(v.num_inliers) + " < " +
                 std::to_string(o_.min_inliers) + ")";
    } else if (v.inlier_ratio < o_.min_inlier_ratio) {
      v.reason = "few landmarks agree within their covariances (" + std::to_string(v.num_inliers) +
                 " of " + std::to_string(v.num_overlap) + " near a target landmark)";
    } else if (v.mean_nis > o_.max_nis_ratio * v.expected_nis) {
      v.reason = "the inliers' residuals exceed their covariances (mean NIS " +
                 message_number(v.mean_nis) + ", " + message_number(v.expected_nis) +
                 " expected): repeated structure may have aliased the pose";
    } else if (v.ambiguity >= o_.max_ambiguity) {
      v.reason = "ambiguous: a distinct pose scores " +
                 std::to_string(static_cast<int>(std::lround(100.0 * v.ambiguity))) +
                 "% of the best";
    } else {
      v.trustworthy = true;
      v.reason = "ok";
    }
    return v;
  }

 private:
  GatedTrustOptions o_;
};

}  // namespace

std::vector<SettingRow> trust_gated_settings() {
  return {
      int_setting("trust.min_inliers", "AdaptiveOptions::min_inliers", 12,
                  SettingBound::closed(3, 2147483647), "count",
                  "untrusted below this many gated inliers"),
      real_setting("trust.min_inlier_ratio", "AdaptiveOptions::min_inlier_ratio", 0.2,
                   SettingBound::closed(0.0, 1.0), "1",
                   "untrusted when fewer than this fraction of the landmarks near a target "
                   "landmark pass the gate at the estimate"),
      real_setting("trust.max_nis_ratio", "AdaptiveOptions::max_nis_ratio", 1.1,
                   SettingBound::at_least(1.0), "1",
                   "untrusted when the inliers' mean NIS exceeds this multiple of its "
                   "expectation"),
      real_setting("trust.max_ambiguity", "AdaptiveOptions::max_ambiguity", 0.85,
                   SettingBound::open_closed(0.0, 1.0), "1",
                   "untrusted when a distinct pose scores at least this fraction of the best"),
      real_setting("trust.distinct_cells", "AdaptiveOptions::distinct_cells", 4.0,
                   SettingBound::above(0.0), "1",
                   "two poses are distinct when they move a landmark at the source's typical "
                   "distance from its centre apart by more than this many search resolutions"),
  };
}

std::unique_ptr<Stage> make_trust_gated(const Settings& s) {
  GatedTrustOptions o;
  o.min_inliers = static_cast<std::size_t>(s.integer("trust.min_inliers"));
  o.min_inlier_ratio = s.real("trust.min_inlier_ratio");
  o.max_nis_ratio = s.real("trust.max_nis_ratio");
  o.max_ambiguity = s.real("trust.max_ambiguity");
  o.distinct_cells = s.real("trust.distinct_cells");
  return std::make_unique<GatedJudge>(o);
}

}  // namespace lmalign::stages
