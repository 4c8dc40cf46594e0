// Matchers "nearest" (base ICP: the nearest target landmark) and "weighted_knn" (the paper's
// Eq. 6: among the k nearest, the one of largest confidence), within the schedule's Euclidean
// distance: CorrespondenceFinder (correspondence.hpp), with the exact reuse of neighbours between
// iterations. PCL's CorrespondenceEstimation::determineCorrespondences for "nearest".
#include <deque>

#include "lmalign/registration/score.hpp"
#include "lmalign/weights/weights.hpp"
#include "stage.hpp"

LMALIGN_STAGE_FUNCTIONS(match_nearest)
LMALIGN_STAGE_FUNCTIONS(match_weighted_knn)

namespace lmalign::stages {

namespace {

struct NearestMatchOptions {
  int k = CorrespondenceOptions{}.k;
  WeightKind confidence = WeightKind::kObservations;
  bool reuse_neighbours = true;
};

class NearestMatcher : public Matcher {
 public:
  NearestMatcher(CorrespondenceKind kind, int k, WeightKind weight, bool reuse)
      : kind_(kind), k_(k), weight_(weight), reuse_(reuse) {}

  struct State : StageState {
    std::deque<CorrespondenceFinder> finders;  // stable addresses (the workspace binds one)
    std::vector<double> distances;
    CorrespondenceWorkspace workspace;
    const CorrespondenceFinder* last = nullptr;
  };

  Pairs::Kind kind() const override { return Pairs::Kind::kPoints; }

  WeightKind confidence() const override {
    return kind_ == CorrespondenceKind::kWeightedKnn ? weight_ : WeightKind::kUniform;
  }

  std::unique_ptr<StageState> begin(const RefineContext&) const override {
    return std::make_unique<State>();
  }

  void match(const RefineContext& c, StageState* state, const Isometry3& T, const LoopState& loop,
             Pairs* pairs) const override {
    State& s = static_cast<State&>(*state);
    const CorrespondenceFinder& f = finder(c, s, loop.max_distance_m);
    pairs->kind = Pairs::Kind::kPoints;
    f.find(*c.source.positions, T, pairs->moved, pairs->points, s.workspace, reuse_);
  }

  FitnessScore fitness(const RefineContext& c, StageState* state, const Isometry3& T,
                       double max_range_m) const override {
    State& s = static_cast<State&>(*state);
    if (!reuse_) return fitness_score(*c.source.positions, c.target->tree(), T, max_range_m);
    const CorrespondenceFinder& f =
        s.last != nullptr ? *s.last : finder(c, s, std::numeric_limits<double>::infinity());
    return fitness_score(*c.source.positions, f, T, max_range_m, s.workspace);
  }

 private:
  const CorrespondenceFinder& finder(const RefineContext& c, State& s, double distance_m) const {
    for (std::size_t i = 0; i < s.distances.size(); ++i) {
      if (s.distances[i] == distance_m) return *(s.last = &s.finders[i]);
    }
    CorrespondenceOptions o;
    o.kind = kind_;
    o.k = k_;
    o.max_distance_m = distance_m;
    // The finder borrows the target's weights (no copy).
    static const std::vector<double> no_weights;
    const std::vector<double>& w =
        kind_ == CorrespondenceKind::kWeightedKnn ? c.target->weights(weight_) : no_weights;
    s.finders.push_back(CorrespondenceFinder::borrowing(c.target->tree(), w, o));
    s.distances.push_back(distance_m);
    return *(s.last = &s.finders.back());
  }

  CorrespondenceKind kind_;
  int k_;
  WeightKind weight_;
  bool reuse_;
};

SettingRow reuse_row() {
  return bool_setting("match.reuse_neighbours", "NearestMatchOptions::reuse_neighbours",
                      NearestMatchOptions{}.reuse_neighbours,
                      "reuse the exact nearest-neighbour results between iterations "
                      "(docs/performance.md); never changes a result");
}

}  // namespace

std::vector<SettingRow> match_nearest_settings() { return {reuse_row()}; }

std::unique_ptr<Stage> make_match_nearest(const Settings& s) {
  return std::make_unique<NearestMatcher>(CorrespondenceKind::kNearest, 1, WeightKind::kUniform,
                                          s.boolean("match.reuse_neighbours"));
}

std::vector<SettingRow> match_weighted_knn_settings() {
  const NearestMatchOptions d;
  return {int_setting("match.k", "NearestMatchOptions::k", d.k, SettingBound::closed(1, 4096),
                      "count", "target landmarks examined per source landmark (the paper's k)"),
          choice_setting("match.confidence", "NearestMatchOptions::confidence",
                         to_string(d.confidence), confidence_names(),
                         "the target landmark confidence that picks among the k nearest "
                         "(Eqs. 1-4)"),
          reuse_row()};
}

std::unique_ptr<Stage> make_match_weighted_knn(const Settings& s) {
  return std::make_unique<NearestMatcher>(
      CorrespondenceKind::kWeightedKnn, static_cast<int>(s.integer("match.k")),
      parse_weight_kind(s.choice("match.confidence")), s.boolean("match.reuse_neighbours"));
}

}  // namespace lmalign::stages
