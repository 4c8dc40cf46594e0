#include "lmalign/registration/adaptive.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/score.hpp"
#include "lmalign/registration/stages/p2d_step.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign {

namespace {

std::vector<std::uint32_t> strided_indices(std::size_t n, std::size_t want) {
  std::vector<std::uint32_t> out;
  const std::size_t m = std::min(n, want);
  out.reserve(m);
  for (std::size_t i = 0; i < m; ++i) out.push_back(static_cast<std::uint32_t>(i * n / m));
  return out;
}

// One refinement: the gate's pose uncertainty starts at `sigma0` and halves each time the
// estimate settles (or after max_iterations_per_level), down to zero; ends when it settles at
// zero, or after max_iterations.
struct Refinement {
  Isometry3 T = Isometry3::Identity();
  TerminationReason termination = TerminationReason::kNotTerminated;
  int iterations = 0;
  std::size_t num_pairs = 0;
  P2DStep last_step;
  Vec3 pivot = Vec3::Zero();
  /// The pairs of the last iteration (those last_step was solved on).
  std::vector<GatedPair> last_pairs;
};

struct Context {
  const SourceLandmarks* source;
  const PreparedTarget* target;
  const AdaptiveOptions* options;
  GateSide side;
  double floor_m;
  double source_radius_m;
  Vec3 source_centre;
  Vec3 up_target;
};

Refinement refine(const Context& c, const Isometry3& T0, PoseSigma sigma0,
                  const std::vector<std::uint32_t>* subset) {
  const AdaptiveOptions& o = *c.options;
  Refinement out;
  out.T = T0;
  PoseSigma sigma = sigma0;
  const double settle_t = o.settle_ratio * c.floor_m;
  const double settle_r = settle_t / c.source_radius_m;
  const Vec3* up4 = o.four_dof ? &c.up_target : nullptr;
  std::vector<GatedPair>& pairs = out.last_pairs;
  GateNeighbourCache neighbours;  // seeds each iteration's searches with the last ones
  int level_iterations = 0;
  while (out.iterations < o.max_iterations) {
    sigma.pivot_m = out.T * c.source_centre;
    gate_correspondences(c.side, *c.target, out.T, c.floor_m, sigma, o.gate, subset, &pairs,
                         &neighbours);
    out.num_pairs = pairs.size();
    if (pairs.size() < (o.four_dof ? 2u : 3u)) {
      out.termination = TerminationReason::kNoCorrespondences;
      return out;
    }
    const P2DStep step =
        solve_p2d_step(pairs, c.target->points(), sigma.pivot_m, o.gate.chi2_threshold, up4);
    out.last_step = step;
    out.pivot = sigma.pivot_m;
    if (!step.ok) {
      out.termination = TerminationReason::kDegenerate;
      return out;
    }
    out.T = apply_step(out.T, step.xi, sigma.pivot_m);
    ++out.iterations;
    ++level_iterations;
    const bool at_zero = sigma.translation_m == 0.0 && sigma.rotation_rad == 0.0;
    // While the gate is wider than the floor, a step well below its width is settled enough.
    const bool settled =
        step.xi.head<3>().norm() < std::max(settle_t, o.level_settle_ratio * sigma.translation_m) &&
        step.xi.tail<3>().norm() < std::max(settle_r, o.level_settle_ratio * sigma.rotation_rad);
    if (settled && at_zero) {
      out.termination = TerminationReason::kTransform;
      return out;
    }
    if ((settled || level_iterations >= o.max_iterations_per_level) && !at_zero) {
      sigma.translation_m *= o.sigma_decay;
      sigma.rotation_rad *= o.sigma_decay;
      if (sigma.translation_m < c.floor_m && sigma.rotation_rad * c.source_radius_m < c.floor_m) {
        sigma.translation_m = 0.0;
        sigma.rotation_rad = 0.0;
      }
      level_iterations = 0;
    }
  }
  out.termination = TerminationReason::kMaxIterations;
  return out;
}

// The half-sample deviations of AdaptiveOptions::covariance_half_sample_planes: for each
// plane (n vertical ones about `up` from the overlap's widest horizontal direction, then the
// horizontal one) and each side of it, the refinement of the landmarks `overlap` on that side
// from T (the gate at its floor), as pose_error_twist against T. Halves with fewer than
// min_inliers landmarks, and refinements that do not end settled or at max_iterations, are left
// out. Deterministic: one refinement per slot, in plane order.
std::vector<Vec6> half_sample_deviations(const Context& c,
                                         const std::vector<std::uint32_t>& overlap, const Vec3& up,
                                         const Isometry3& T) {
  const AdaptiveOptions& o = *c.options;
  const Points3& p = *c.side.points;
  std::vector<Vec6> out;
  if (overlap.size() < 2 * o.min_inliers) return out;
  Vec3 centre = Vec3::Zero();
  for (std::uint32_t i : overlap) centre += p[i];
  centre /= static_cast<double>(overlap.size());
  Mat3 scatter = Mat3::Zero();
  for (std::uint32_t i : overlap) {
    Vec3 q = p[i] - centre;
    q -= up * up.dot(q);
    scatter.noalias() += q * q.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(scatter);
  Vec3 widest = eig.eigenvectors().col(2);
  widest -= up * up.dot(widest);
  if (!(widest.norm() > 0.0)) widest = up.unitOrthogonal();
  widest.normalize();
  const int n = o.covariance_half_sample_planes;
  std::vector<Vec3> normals;
  for (int k = 0; k < n; ++k) {
    normals.push_back(Eigen::AngleAxisd(kPi * k / n, up) * widest);
  }
  normals.push_back(up);
  const std::size_t slots = 2 * normals.size();
  std::vector<std::optional<Vec6>> dev(slots);
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t s = 0; s < static_cast<std::ptrdiff_t>(slots); ++s) {
    const Vec3& normal = normals[static_cast<std::size_t>(s) / 2];
    const bool below = s % 2 == 0;
    std::vector<std::uint32_t> half;
    for (std::uint32_t i : overlap) {
      if ((normal.dot(p[i] - centre) < 0.0) == below) half.push_back(i);
    }
    if (half.size() < o.min_inliers) continue;
    const Refinement r = refine(c, T, PoseSigma{}, &half);
    if (r.termination != TerminationReason::kTransform &&
        r.termination != TerminationReason::kMaxIterations) {
      continue;
    }
    dev[static_cast<std::size_t>(s)] = pose_error_twist(r.T, T);
  }
  for (const auto& d : dev) {
    if (d && d->allFinite()) out.push_back(*d);
  }
  return out;
}

// Two estimates are distinct poses when they move a landmark at the source's typical distance
// from its centre apart by more than `distance_m`.
bool distinct(const Isometry3& a, const Isometry3& b, const Vec3& centre, double radius_m,
              double distance_m) {
  const double angle = Eigen::AngleAxisd(a.linear() * b.linear().transpose()).angle();
  return ((a * centre) - (b * centre)).norm() + angle * radius_m > distance_m;
}

}  // namespace

bool PriorSigma::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  if (!(rotation_deg > 0.0) || !std::isfinite(rotation_deg)) {
    return fail("prior rotation sigma must be > 0 and finite (degrees), got " +
                message_number(rotation_deg));
  }
  if (!(translation_m > 0.0) || !std::isfinite(translation_m)) {
    return fail("prior translation sigma must be > 0 and finite (metres), got " +
                message_number(translation_m));
  }
  return true;
}

SourceLandmarks SourceLandmarks::from_map(const Map& map) {
  map.validate();
  SourceLandmarks s;
  s.positions = map.positions();
  s.covariances_m2 = map.covariances_m2();
  s.up = estimate_up_axis(map);
  return s;
}

bool AdaptiveOptions::is_valid(std::string* why) const {
  auto fail = [&](const std::string& m) {
    if (why != nullptr) *why = m;
    return false;
  };
  std::string inner;
  if (!search.is_valid(&inner)) return fail("search." + inner);
  if (!gate.is_valid(&inner)) return fail("gate." + inner);
  if (!(vote_cell_factor > 0.0) || !std::isfinite(vote_cell_factor)) {
    return fail("vote_cell_factor must be > 0 and finite, got " + message_number(vote_cell_factor));
  }
  if (!(start_sigma_factor > 0.0 && start_sigma_factor <= 10.0)) {
    return fail("start_sigma_factor must be in (0, 10], got " + message_number(start_sigma_factor));
  }
  if (hypothesis_samples < 16) return fail("hypothesis_samples must be >= 16");
  if (!default_up.allFinite() || !(default_up.norm() > 0.0)) {
    return fail("default_up must be finite and non-zero");
  }
  if (!(floor_m >= 0.0) || !std::isfinite(floor_m)) {
    return fail("floor_m must be >= 0 and finite (0 = from the data), got " +
                message_number(floor_m));
  }
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (max_iterations_per_level < 1) return fail("max_iterations_per_level must be >= 1");
  if (!(sigma_decay > 0.0 && sigma_decay < 1.0)) {
    return fail("sigma_decay must be in (0, 1), got " + message_number(sigma_decay));
  }
  if (!(level_settle_ratio >= 0.0 && level_settle_ratio < 1.0)) {
    return fail("level_settle_ratio must be in [0, 1), got " + message_number(level_settle_ratio));
  }
  if (!(settle_ratio > 0.0 && settle_ratio <= 1.0)) {
    return fail("settle_ratio must be in (0, 1], got " + message_number(settle_ratio));
  }
  if (!(max_ambiguity > 0.0 && max_ambiguity <= 1.0)) {
    return fail("max_ambiguity must be in (0, 1], got " + message_number(max_ambiguity));
  }
  if (min_inliers < 3) return fail("min_inliers must be >= 3");
  if (!(min_inlier_ratio >= 0.0 && min_inlier_ratio <= 1.0)) {
    return fail("min_inlier_ratio must be in [0, 1], got " + message_number(min_inlier_ratio));
  }
  if (!(second_up_min_angle_deg >= 0.0 && second_up_min_angle_deg <= 180.0)) {
    return fail("second_up_min_angle_deg must be in [0, 180], got " +
                message_number(second_up_min_angle_deg));
  }
  if (!(max_nis_ratio >= 1.0) || !std::isfinite(max_nis_ratio)) {
    return fail("max_nis_ratio must be >= 1 and finite, got " + message_number(max_nis_ratio));
  }
  if (!(distinct_cells > 0.0) || !std::isfinite(distinct_cells)) {
    return fail("distinct_cells must be > 0 and finite, got " + message_number(distinct_cells));
  }
  if (!(covariance_block_factor > 0.0) || !std::isfinite(covariance_block_factor)) {
    return fail("covariance_block_factor must be > 0 and finite, got " +
                message_number(covariance_block_factor));
  }
  if (covariance_half_sample_planes < 0 || covariance_half_sample_planes > 1000) {
    return fail("covariance_half_sample_planes must be in [0, 1000], got " +
                std::to_string(covariance_half_sample_planes));
  }
  return true;
}

bool is_rigid_transform(const Isometry3& T) {
  if (!T.matrix().allFinite()) return false;
  const Mat3 R = T.linear();
  if (!((R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff() < 1e-6)) return false;
  if (!(std::abs(R.determinant() - 1.0) < 1e-6)) return false;
  const Eigen::RowVector4d last = T.matrix().row(3);
  return last.isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-12);
}

AdaptiveResult align_adaptive(const SourceLandmarks& source, const PreparedTarget& target,
                              const AdaptiveOptions& options, const Isometry3* initial_guess,
                              const PriorSigma* prior) {
  const auto t_start = std::chrono::steady_clock::now();
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("adaptive options: " + why);
  if (prior != nullptr && !prior->is_valid(&why)) throw InvalidArgument(why);
  if (initial_guess != nullptr && !is_rigid_transform(*initial_guess)) {
    throw InvalidArgument(
        "initial guess: not a rigid transform (expected a finite 4x4 [R t; 0 0 0 1] with R "
        "orthonormal and det R = +1)");
  }
  if (source.positions.empty()) throw InvalidArgument("adaptive alignment: the source is empty");
  if (target.size() == 0) throw InvalidArgument("adaptive alignment: the target is empty");
  for (std::size_t i = 0; i < source.positions.size(); ++i) {
    if (!source.positions[i].allFinite()) {
      throw InvalidArgument("adaptive alignment: source landmark " + std::to_string(i) +
                            " is not finite");
    }
  }
  if (!source.covariances_m2.empty() && source.covariances_m2.size() != source.positions.size()) {
    throw InvalidArgument("adaptive alignment: " + std::to_string(source.covariances_m2.size()) +
                          " source covariances for " + std::to_string(source.positions.size()) +
                          " landmarks");
  }

  AdaptiveResult result;
  const Isometry3 guess = initial_guess != nullptr ? *initial_guess : Isometry3::Identity();
  result.registration.T_target_source = guess;
  result.initialisation = prior != nullptr ? "prior" : "global";
  auto finish = [&]() -> AdaptiveResult {
    result.registration.wall_time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    return std::move(result);
  };
  if (source.positions.size() < 3 || target.size() < 3) {
    result.registration.termination = TerminationReason::kNoCorrespondences;
    result.trust_reason = "fewer than 3 landmarks in a map";
    return finish();
  }

  // --- scales ---
  result.source_scales = estimate_data_scales(source.positions, &source.covariances_m2);
  const std::vector<Mat3>* tgt_cov = target.has_covariances() ? &target.covariances_m2() : nullptr;
  result.target_scales = estimate_data_scales(target.points(), tgt_cov, 4096, &target.tree());
  result.floor_m = options.floor_m > 0.0
                       ? options.floor_m
                       : std::max(result.source_scales.floor_m, result.target_scales.floor_m);
  result.up_source = source.up.value_or(options.default_up).normalized();
  result.up_target = target.up_axis().value_or(options.default_up).normalized();
  const double step_rad = options.search.yaw_step_deg * kPi / 180.0;
  result.vote_cell_m = options.vote_cell_factor *
                       std::max(result.target_scales.spacing_m,
                                2.0 * std::sin(0.5 * step_rad) * result.source_scales.radius_m);

  Context c;
  c.source = &source;
  c.target = &target;
  c.options = &options;
  c.side.points = &source.positions;
  c.side.covariances_m2 = &source.covariances_m2;
  c.floor_m = result.floor_m;
  c.source_radius_m = result.source_scales.radius_m;
  c.source_centre = result.source_scales.centre_m;
  c.up_target = result.up_target;

  // --- initialisation: hypotheses and the gate's starting pose uncertainty ---
  PoseWindow window;
  if (prior != nullptr) {
    window.T_target_source_guess = guess;
    window.rotation_sd_rad = prior->rotation_deg * kPi / 180.0;
    window.translation_sd_m = prior->translation_m;
  }
  // The prior's translation sigma is about the target origin (uncertainty.hpp); where the
  // source centre lands it grows by the rotation's sigma times that point's distance from there.
  const double centre_sd_m =
      prior == nullptr
          ? 0.0
          : window.translation_sd_m + window.rotation_sd_rad * (guess * c.source_centre).norm();
  const bool search_needed = prior == nullptr || window.rotation_sd_rad > 0.5 * step_rad ||
                             centre_sd_m > result.vote_cell_m;
  std::vector<AdaptiveHypothesis> hyps;
  PoseSigma sigma_search;
  sigma_search.translation_m = options.start_sigma_factor * 2.0 * result.vote_cell_m;
  sigma_search.rotation_rad = options.start_sigma_factor * step_rad;
  if (search_needed) {
    // Up-axis candidates of each map: its frames' (or the default), and its landmark plane's
    // normal when that disagrees by more than second_up_min_angle_deg. Without a prior the
    // search votes once per pair of candidates and keeps the best hypotheses of all of them.
    // With a prior the guess's rotation is the base (and, below, the guess tilted to agree
    // with the frames' up axes); the landmark-plane candidates do not enter.
    const double min_cos = std::cos(options.second_up_min_angle_deg * kPi / 180.0);
    auto candidates = [&](const Vec3& up, const Points3& points) {
      std::vector<Vec3> ups{up};
      if (prior == nullptr) {
        const std::optional<Vec3> plane = landmark_plane_normal(points, up);
        if (plane && plane->dot(up) < min_cos) ups.push_back(*plane);
      }
      return ups;
    };
    result.ups_source = candidates(result.up_source, source.positions);
    result.ups_target = candidates(result.up_target, target.points());
    std::vector<YawHypothesis> yh;
    for (const Vec3& us : result.ups_source) {
      for (const Vec3& ut : result.ups_target) {
        const std::vector<YawHypothesis> part =
            yaw_vote_hypotheses(source.positions, target.points(), us, ut, result.vote_cell_m,
                                options.search, prior != nullptr ? &window : nullptr);
        yh.insert(yh.end(), part.begin(), part.end());
      }
    }
    if (prior != nullptr) {
      // A second base with a prior: the guess tilted (about the target origin, as the prior's
      // perturbation) so that the maps' up axes agree, when that takes more than half a yaw step
      // and stays within 3 sigma of the prior's rotation. The up axes measure the tilt that a
      // yaw search cannot correct.
      const Mat3 R_guess = guess.linear();
      const Mat3 tilt = rotation_between(R_guess * result.up_source, result.up_target);
      const double angle = Eigen::AngleAxisd(tilt).angle();
      if (angle > 0.5 * step_rad && angle <= 3.0 * window.rotation_sd_rad) {
        PoseWindow tilted = window;
        tilted.T_target_source_guess = Isometry3(tilt) * guess;  // about the target origin
        const std::vector<YawHypothesis> part =
            yaw_vote_hypotheses(source.positions, target.points(), result.up_source,
                                result.up_target, result.vote_cell_m, options.search, &tilted);
        yh.insert(yh.end(), part.begin(), part.end());
      }
    }
    // Best first over all pairs of up axes (stable: ties keep the frames' axes first).
    std::stable_sort(yh.begin(), yh.end(), [](const YawHypothesis& a, const YawHypothesis& b) {
      return a.votes > b.votes;
    });
    if (yh.size() > options.search.hypotheses) yh.resize(options.search.hypotheses);
    for (const YawHypothesis& h : yh) {
      AdaptiveHypothesis a;
      a.T_start = h.T_target_source;
      a.votes = h.votes;
      hyps.push_back(a);
    }
  } else {
    result.initialisation = "given";
  }
  if (initial_guess != nullptr || !search_needed) {
    AdaptiveHypothesis a;
    a.T_start = guess;
    a.from_guess = true;
    hyps.push_back(a);
  }
  PoseSigma sigma_guess = sigma_search;
  if (prior != nullptr) {
    // The gate's pose sigma is about the source centre's image (its pivot).
    sigma_guess.translation_m = options.start_sigma_factor * centre_sd_m;
    sigma_guess.rotation_rad = options.start_sigma_factor * window.rotation_sd_rad;
  }

  // --- refine and score every hypothesis on the samples (one per thread: deterministic) ---
  const std::vector<std::uint32_t> samples =
      strided_indices(source.positions.size(), options.hypothesis_samples);
  std::vector<Refinement> refined(hyps.size());
  int total_iterations = 0;
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(hyps.size()); ++i) {
    AdaptiveHypothesis& h = hyps[static_cast<std::size_t>(i)];
    Refinement r = refine(c, h.T_start, h.from_guess ? sigma_guess : sigma_search, &samples);
    h.T_refined = r.T;
    h.score = gated_inlier_score(c.side, target, r.T, c.floor_m, options.gate, &samples);
    r.last_pairs = {};  // only the final refinement's are needed
    refined[static_cast<std::size_t>(i)] = r;
  }
  for (const Refinement& r : refined) total_iterations += r.iterations;
  std::vector<std::size_t> order(hyps.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return hyps[a].score > hyps[b].score; });
  std::vector<AdaptiveHypothesis> sorted;
  for (std::size_t i : order) sorted.push_back(hyps[i]);
  result.hypotheses = sorted;
  const AdaptiveHypothesis& best = sorted.front();
  for (std::size_t i = 1; i < sorted.size(); ++i) {
    if (distinct(sorted[i].T_refined, best.T_refined, c.source_centre, c.source_radius_m,
                 options.distinct_cells * result.vote_cell_m)) {
      result.ambiguity = best.score > 0.0 ? sorted[i].score / best.score : 1.0;
      break;
    }
  }

  // --- the winner on every landmark ---
  PoseSigma final_sigma;  // zero: the hypothesis has settled on the samples
  const Refinement fin = refine(c, best.T_refined, final_sigma, nullptr);
  total_iterations += fin.iterations;
  RegistrationResult& reg = result.registration;
  reg.T_target_source = fin.T;
  reg.termination = fin.termination;
  reg.converged = fin.termination == TerminationReason::kTransform;
  reg.iterations = total_iterations;
  reg.num_correspondences = fin.num_pairs;
  reg.initial_score_m2 = fitness_score(source.positions, target.tree(), guess).mean_sq_m2;
  reg.final_score_m2 = fitness_score(source.positions, target.tree(), fin.T).mean_sq_m2;
  {
    std::vector<GatedPair> inliers;
    gate_correspondences(c.side, target, fin.T, c.floor_m, PoseSigma{}, options.gate, nullptr,
                         &inliers);
    result.score = gated_inlier_score(inliers, options.gate);
    result.num_inliers = inliers.size();
    double sum_d2 = 0.0;
    for (const GatedPair& g : inliers) sum_d2 += g.d2;
    result.mean_nis = inliers.empty() ? 0.0 : sum_d2 / static_cast<double>(inliers.size());
    result.expected_nis = expected_gated_d2(options.gate.chi2_threshold);
  }
  std::vector<std::uint32_t> overlap;  // source indices of the landmarks in the overlap
  {
    PoseSigma wide;
    wide.translation_m = result.vote_cell_m;
    wide.pivot_m = fin.T * c.source_centre;
    std::vector<GatedPair> pairs;
    gate_correspondences(c.side, target, fin.T, c.floor_m, wide, options.gate, nullptr, &pairs);
    result.num_overlap = pairs.size();
    result.inlier_ratio =
        pairs.empty() ? 0.0
                      : static_cast<double>(result.num_inliers) / static_cast<double>(pairs.size());
    overlap.reserve(pairs.size());
    for (const GatedPair& g : pairs) overlap.push_back(g.source_index);
  }
  if (fin.last_step.ok) {
    // Validity (and with it the trust verdict) as the normal equations of the last step say;
    // the values from the cluster-robust covariance of its pairs (6 DoF; blocks of a fixed
    // fraction of the source's radius).
    result.covariance = p2d_covariance(fin.last_step, fin.num_pairs, fin.pivot);
    if (result.covariance.valid && !options.four_dof) {
      const PoseCovariance robust = p2d_cluster_covariance(
          fin.last_pairs, target.points(), fin.pivot, options.gate.chi2_threshold,
          options.covariance_block_factor * c.source_radius_m);
      if (robust.valid) result.covariance = robust;
      if (options.covariance_half_sample_planes > 0) {
        const std::vector<Vec6> deviations =
            half_sample_deviations(c, overlap, result.up_source, fin.T);
        const std::size_t halves =
            2 * static_cast<std::size_t>(options.covariance_half_sample_planes + 1);
        if (2 * deviations.size() >= halves) {
          Mat6 B = Mat6::Zero();
          for (const Vec6& d : deviations) B.noalias() += d * d.transpose();
          B /= static_cast<double>(deviations.size());
          result.covariance.covariance = covariance_max(result.covariance.covariance, B);
          result.num_half_samples = deviations.size();
        }
      }
    }
  }

  // --- trust ---
  if (fin.termination == TerminationReason::kNoCorrespondences) {
    result.trust_reason = "no covariance-gated correspondences";
  } else if (fin.termination == TerminationReason::kDegenerate || !result.covariance.valid) {
    result.trust_reason = "degenerate: the normal equations are singular";
  } else if (result.num_inliers < options.min_inliers) {
    result.trust_reason = "too few covariance-gated inliers (" +
                          std::to_string(result.num_inliers) + " < " +
                          std::to_string(options.min_inliers) + ")";
  } else if (result.inlier_ratio < options.min_inlier_ratio) {
    result.trust_reason = "few landmarks agree within their covariances (" +
                          std::to_string(result.num_inliers) + " of " +
                          std::to_string(result.num_overlap) + " near a target landmark)";
  } else if (result.mean_nis > options.max_nis_ratio * result.expected_nis) {
    result.trust_reason = "the inliers' residuals exceed their covariances (mean NIS " +
                          message_number(result.mean_nis) + ", " +
                          message_number(result.expected_nis) +
                          " expected): repeated structure may have aliased the pose";
  } else if (result.ambiguity >= options.max_ambiguity) {
    result.trust_reason = "ambiguous: a distinct pose scores " +
                          std::to_string(static_cast<int>(std::lround(100.0 * result.ambiguity))) +
                          "% of the best";
  } else {
    result.trustworthy = true;
    result.trust_reason = "ok";
  }
  return finish();
}

}  // namespace lmalign
