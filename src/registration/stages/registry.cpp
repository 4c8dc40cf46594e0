// The registry of stages: one row per stage (its seam, its name in preset files and settings,
// one line of what it does). A new stage is one file (its class, its settings rows and its
// factory, declared with LMALIGN_STAGE_FUNCTIONS) and one row here.
#include "lmalign/weights/weights.hpp"
#include "stage.hpp"

//  X(seam, identifier in the stage file, name, doc)
#define LMALIGN_STAGES(X)                                                                          \
  X(kInitialiser, init_guess, "guess", "the initial guess alone (identity if none)")               \
  X(kInitialiser, init_yaw_vote, "yaw_vote",                                                       \
    "every yaw about the maps' up axes, translation by a vote; bounded by a prior if given")       \
  X(kInitialiser, init_complete_search, "complete_search",                                         \
    "every pair of up axes, yaw and translation: 3-D vote, finer votes, refinement rounds; "       \
    "bounded by a prior if given")                                                                 \
  X(kInitialiser, init_yaw_centroid, "yaw_centroid",                                               \
    "the guess and evenly spaced yaws about the centroids")                                        \
  X(kMatcher, match_nearest, "nearest", "the nearest target landmark within the level's distance") \
  X(kMatcher, match_weighted_knn, "weighted_knn",                                                  \
    "the most confident of the k nearest within the level's distance (the paper's Eq. 6)")         \
  X(kMatcher, match_gate, "mahalanobis_gate",                                                      \
    "the Mahalanobis-nearest of the k nearest, gated under both covariances and the pose "         \
    "uncertainty")                                                                                 \
  X(kRejector, reject_mutual, "mutual", "keeps mutual nearest neighbours (finite levels)")         \
  X(kRejector, reject_trim, "trim",                                                                \
    "keeps the closest fraction, given or estimated (finite levels)")                              \
  X(kKernel, kernel_none, "none", "weight = landmark confidence")                                  \
  X(kKernel, kernel_huber, "huber", "Huber IRLS x landmark confidence")                            \
  X(kKernel, kernel_cauchy, "cauchy", "Cauchy IRLS x landmark confidence")                         \
  X(kKernel, kernel_geman_mcclure, "geman_mcclure", "Geman-McClure IRLS x landmark confidence")    \
  X(kKernel, kernel_cauchy_mahalanobis, "cauchy_mahalanobis",                                      \
    "Cauchy weight of the gate's Mahalanobis distance")                                            \
  X(kEstimator, estimate_umeyama, "umeyama",                                                       \
    "weighted closed-form rigid transform (SVD), or 4 DoF: x, y, z and yaw")                       \
  X(kEstimator, estimate_p2d_step, "p2d_step",                                                     \
    "one point-to-distribution Gauss-Newton step on the gated pairs per iteration")                \
  X(kSchedule, schedule_pcl, "pcl", "PCL's ICP convergence criteria at one fixed distance")        \
  X(kSchedule, schedule_distance, "distance_levels",                                               \
    "a shrinking maximum distance, the next level when the estimate settles")                      \
  X(kSchedule, schedule_sigma, "sigma_anneal",                                                     \
    "the gate's pose uncertainty halves each time the estimate settles, down to zero")             \
  X(kScorer, score_none, "none", "no hypothesis scoring: the first hypothesis is refined")         \
  X(kScorer, score_gated, "gated_inliers", "covariance-gated inlier score on strided samples")     \
  X(kScorer, score_consensus, "consensus", "landmarks within a distance, on every n-th")           \
  X(kTrustJudge, trust_none, "none", "no verdict")                                                 \
  X(kTrustJudge, trust_inliers, "inliers",                                                         \
    "Euclidean inliers of all and of the overlap, and a small covariance")                         \
  X(kTrustJudge, trust_gated, "gated",                                                             \
    "covariance-gated inliers, their NIS, the overlap, no distinct pose scoring as well")

#define LMALIGN_DECLARE(seam, ident, name, doc) LMALIGN_STAGE_FUNCTIONS(ident)
LMALIGN_STAGES(LMALIGN_DECLARE)
#undef LMALIGN_DECLARE

namespace lmalign {

namespace stages {

void check_limits(std::optional<int> max_iterations, std::optional<double> max_distance_m) {
  if (max_iterations && *max_iterations < 1) {
    throw InvalidArgument("max_iterations = " + std::to_string(*max_iterations) +
                          " (expected >= 1)");
  }
  if (max_distance_m && !(*max_distance_m > 0.0)) {
    throw InvalidArgument("max_distance_m = " + message_number(*max_distance_m) +
                          " (expected > 0 metres, or inf)");
  }
}

SettingBound vector3_bound() {
  SettingBound b;
  b.min_size = b.max_size = 3;
  return b;
}

Vec3 unit_vector(const Settings& settings, const std::string& key) {
  const std::vector<double>& v = settings.reals(key);
  const Vec3 u(v[0], v[1], v[2]);
  if (!u.allFinite() || !(u.norm() > 0.0)) {
    throw InvalidArgument(key + " = " + settings.row(key).text(v) + " must be finite and non-zero");
  }
  return u.normalized();
}

std::vector<std::string> confidence_names() {
  std::vector<std::string> names;
  for (WeightKind k : all_weight_kinds()) names.push_back(to_string(k));
  return names;
}

// The two "none" rows of optional seams: no settings, no stage.
std::vector<SettingRow> score_none_settings() { return {}; }
std::unique_ptr<Stage> make_score_none(const Settings&) { return nullptr; }
std::vector<SettingRow> trust_none_settings() { return {}; }
std::unique_ptr<Stage> make_trust_none(const Settings&) { return nullptr; }

}  // namespace stages

const std::vector<StageInfo>& stage_registry() {
#define LMALIGN_ROW(seam, ident, name, doc) \
  {Seam::seam, name, doc, &stages::ident##_settings, &stages::make_##ident},
  static const std::vector<StageInfo> rows{LMALIGN_STAGES(LMALIGN_ROW)};
#undef LMALIGN_ROW
  return rows;
}

const StageInfo* find_stage(Seam seam, const std::string& name) {
  for (const StageInfo& s : stage_registry()) {
    if (s.seam == seam && s.name == name) return &s;
  }
  return nullptr;
}

}  // namespace lmalign
