// Matcher "mahalanobis_gate": of the k Euclidean nearest target landmarks, the one of smallest
// Mahalanobis distance under both landmarks' covariances, the floor and the loop's pose
// uncertainty, kept when it passes a chi-square test (stages/mahalanobis_gate.hpp).
#include "lmalign/registration/stages/mahalanobis_gate.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(match_gate)

namespace lmalign::stages {

namespace {

class GateMatcher : public Matcher {
 public:
  explicit GateMatcher(MahalanobisGateOptions o) : options_(o) {}

  struct State : StageState {
    GateNeighbourCache cache;  // seeds each iteration's searches with the last ones
  };

  bool needs_scales() const override { return true; }
  // The cache's searches are exact wherever the landmark now is (nearest(), mahalanobis_gate.cpp).
  bool state_follows_the_source() const override { return true; }
  Pairs::Kind kind() const override { return Pairs::Kind::kDistributions; }

  std::unique_ptr<StageState> begin(const RefineContext&) const override {
    return std::make_unique<State>();
  }

  // The whole's seeds of each landmark of the part: the searches they seed are exact, so the
  // part matches as with a fresh state (GateNeighbourCache).
  std::unique_ptr<StageState> part_state(const StageState& whole,
                                         const std::vector<std::uint32_t>& indices) const override {
    const GateNeighbourCache& from = static_cast<const State&>(whole).cache;
    auto part = std::make_unique<State>();
    if (from.width <= 0) return part;
    const std::size_t w = static_cast<std::size_t>(from.width);
    GateNeighbourCache& to = part->cache;
    to.k = from.k;
    to.width = from.width;
    to.counts.assign(indices.size(), 0);
    to.indices.assign(indices.size() * w, 0);
    to.reach_m2.assign(indices.size(), 0.0);
    to.at_m.assign(indices.size(), Vec3::Zero());
    for (std::size_t j = 0; j < indices.size(); ++j) {
      const std::size_t i = indices[j];
      if (i >= from.counts.size()) continue;
      to.counts[j] = from.counts[i];
      to.reach_m2[j] = from.reach_m2[i];
      to.at_m[j] = from.at_m[i];
      std::copy_n(from.indices.begin() + static_cast<std::ptrdiff_t>(i * w), w,
                  to.indices.begin() + static_cast<std::ptrdiff_t>(j * w));
    }
    return part;
  }

  void match(const RefineContext& c, StageState* state, const Isometry3& T, const LoopState& loop,
             Pairs* pairs) const override {
    GateSide side;
    side.points = c.source.positions;
    side.covariances_m2 = c.source.covariances_m2;
    if (loop.scoring) side.view_directions = c.source.view_directions;  // (LoopState::scoring)
    pairs->kind = Pairs::Kind::kDistributions;
    pairs->chi2_threshold = options_.chi2_threshold;
    const EvidenceScales evidence = c.scales->evidence();
    gate_correspondences(
        side, *c.target, T, c.scales->floor_m, loop.sigma, options_, nullptr, &pairs->gated,
        state != nullptr ? &static_cast<State*>(state)->cache : nullptr, &evidence);
  }

 private:
  MahalanobisGateOptions options_;
};

const SettingsBinding<MahalanobisGateOptions>& binding() {
  static const SettingsBinding<MahalanobisGateOptions> b =
      SettingsBinding<MahalanobisGateOptions>("MahalanobisGateOptions")
          .add("match.k", LMALIGN_FIELD(k), SettingBound::closed(1, 64), "count",
               "Euclidean nearest target landmarks examined per source landmark")
          .add("match.chi2_threshold", LMALIGN_FIELD(chi2_threshold), SettingBound::above(0.0), "1",
               "gate on the Mahalanobis d^2 (chi-square, 3 dof, 0.99)")
          .add("match.max_view_angle_deg", LMALIGN_FIELD(max_view_angle_deg),
               SettingBound::open_closed(0.0, 180.0), "deg",
               "largest angle between two landmarks' mean viewing directions (the source's rotated "
               "into the target frame) for them to be paired; 180: off; unknown directions pass");
  return b;
}

}  // namespace
}  // namespace lmalign::stages

LMALIGN_BOUND_STAGE(match_gate, GateMatcher)
