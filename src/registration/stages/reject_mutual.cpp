// Rejector "mutual": keeps a pair (s, t) only when s is also the nearest moved source landmark
// of t (keep_mutual, robust.hpp). At levels with a finite maximum distance only: at an unlimited
// level it shrinks the basin (docs/accuracy.md).
#include <cmath>

#include "lmalign/registration/robust.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(reject_mutual)

namespace lmalign::stages {

namespace {

class MutualRejector : public Rejector {
 public:
  bool accepts(int kind) const override { return kind == static_cast<int>(Pairs::Kind::kPoints); }
  void reject(const RefineContext& c, LoopState* loop, Pairs* pairs) const override {
    if (!std::isfinite(loop->max_distance_m)) return;
    keep_mutual(pairs->moved, c.target->points(), pairs->points);
  }
};

}  // namespace

std::vector<SettingRow> reject_mutual_settings() { return {}; }

std::unique_ptr<Stage> make_reject_mutual(const Settings&) {
  return std::make_unique<MutualRejector>();
}

}  // namespace lmalign::stages
