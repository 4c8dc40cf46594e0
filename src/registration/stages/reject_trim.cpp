// Rejector "trim": keeps the given fraction of the pairs of smallest distance, or estimates it
// each iteration (trimmed ICP, Chetverikov et al. 2005; estimate_overlap_ratio, robust.hpp). At
// levels with a finite maximum distance only; the diagnostics at the estimate reuse the last
// ratio.
#include <cmath>

#include "lmalign/registration/robust.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(reject_trim)

namespace lmalign::stages {

namespace {

class TrimRejector : public Rejector {
 public:
  bool accepts(int kind) const override { return kind == static_cast<int>(Pairs::Kind::kPoints); }
  TrimRejector(double ratio, bool estimate, double min_ratio)
      : ratio_(ratio), estimate_(estimate), min_ratio_(min_ratio) {}

  void reject(const RefineContext&, LoopState* loop, Pairs* pairs) const override {
    Correspondences& corr = pairs->points;
    if (loop->final_pass) {
      if (loop->overlap_ratio < 1.0) trim_correspondences(corr, loop->overlap_ratio);
      return;
    }
    const bool gated = std::isfinite(loop->max_distance_m);
    double ratio = gated ? ratio_ : 1.0;
    if (gated && estimate_ && corr.size() >= 2) {
      std::vector<double> residuals_sq;
      residuals_sq.reserve(corr.size());
      for (const Correspondence& c : corr) residuals_sq.push_back(c.distance_sq_m2);
      ratio = estimate_overlap_ratio(residuals_sq, min_ratio_);
    }
    if (ratio < 1.0) trim_correspondences(corr, ratio);
    loop->overlap_ratio = ratio;
  }

 private:
  double ratio_;
  bool estimate_;
  double min_ratio_;
};

}  // namespace

std::vector<SettingRow> reject_trim_settings() {
  return {real_setting("reject.trim_ratio", "RobustRegistrationOptions::trim_ratio", 1.0,
                       SettingBound::open_closed(0.0, 1.0), "1",
                       "fraction of the pairs kept, those of smallest distance"),
          bool_setting("reject.estimate_overlap", "RobustRegistrationOptions::estimate_overlap",
                       false, "estimate the fraction each iteration instead (trimmed ICP)"),
          real_setting("reject.min_overlap_ratio", "RobustRegistrationOptions::min_overlap_ratio",
                       0.4, SettingBound::open_closed(0.0, 1.0), "1",
                       "lower bound of the estimated fraction")};
}

std::unique_ptr<Stage> make_reject_trim(const Settings& s) {
  return std::make_unique<TrimRejector>(s.real("reject.trim_ratio"),
                                        s.boolean("reject.estimate_overlap"),
                                        s.real("reject.min_overlap_ratio"));
}

}  // namespace lmalign::stages
