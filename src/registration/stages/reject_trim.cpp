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

struct TrimOptions {
  double trim_ratio = 1.0;
  bool estimate_overlap = false;
  double min_overlap_ratio = 0.4;
};

class TrimRejector : public Rejector {
 public:
  bool accepts(int kind) const override { return kind == static_cast<int>(Pairs::Kind::kPoints); }
  explicit TrimRejector(TrimOptions o) : o_(o) {}

  void reject(const RefineContext&, LoopState* loop, Pairs* pairs) const override {
    Correspondences& corr = pairs->points;
    if (loop->final_pass) {
      if (loop->overlap_ratio < 1.0) trim_correspondences(corr, loop->overlap_ratio);
      return;
    }
    const bool gated = std::isfinite(loop->max_distance_m);
    double ratio = gated ? o_.trim_ratio : 1.0;
    if (gated && o_.estimate_overlap && corr.size() >= 2) {
      std::vector<double> residuals_sq;
      residuals_sq.reserve(corr.size());
      for (const Correspondence& c : corr) residuals_sq.push_back(c.distance_sq_m2);
      ratio = estimate_overlap_ratio(residuals_sq, o_.min_overlap_ratio);
    }
    if (ratio < 1.0) trim_correspondences(corr, ratio);
    loop->overlap_ratio = ratio;
  }

 private:
  TrimOptions o_;
};

const SettingsBinding<TrimOptions>& binding() {
  static const SettingsBinding<TrimOptions> b =
      SettingsBinding<TrimOptions>("TrimOptions")
          .add("reject.trim_ratio", LMALIGN_FIELD(trim_ratio), SettingBound::open_closed(0.0, 1.0),
               "1", "fraction of the pairs kept, those of smallest distance")
          .flag("reject.estimate_overlap", LMALIGN_FIELD(estimate_overlap),
                "estimate the fraction each iteration instead (trimmed ICP)")
          .add("reject.min_overlap_ratio", LMALIGN_FIELD(min_overlap_ratio),
               SettingBound::open_closed(0.0, 1.0), "1", "lower bound of the estimated fraction");
  return b;
}

}  // namespace
}  // namespace lmalign::stages

LMALIGN_BOUND_STAGE(reject_trim, TrimRejector)
