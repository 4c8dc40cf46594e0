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
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/score.hpp"

namespace lmalign {

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
  if (!(max_covariance_scale >= 1.0) || !std::isfinite(max_covariance_scale)) {
    return fail("max_covariance_scale must be >= 1 and finite, got " +
                message_number(max_covariance_scale));
  }
  if (!(alias_ambiguity > 0.0 && alias_ambiguity <= 1.0)) {
    return fail("alias_ambiguity must be in (0, 1], got " + message_number(alias_ambiguity));
  }
  if (!(alias_nis_ratio >= 1.0) || !std::isfinite(alias_nis_ratio)) {
    return fail("alias_nis_ratio must be >= 1 and finite, got " + message_number(alias_nis_ratio));
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

  // A preset of the engine (pipeline.hpp).
  const Pipeline pipeline(adaptive_pipeline_spec(options));
  PipelineRequest request;
  if (initial_guess != nullptr) request.initial_guess = *initial_guess;
  if (prior != nullptr) request.prior = *prior;
  const Summary s = pipeline.run(source.view(), target, request);

  AdaptiveResult result;
  result.registration = s.registration;
  result.initialisation = s.scales ? s.initialisation.initialisation
                                   : std::string(prior != nullptr ? "prior" : "global");
  result.score = s.verdict.score;
  result.num_inliers = s.verdict.num_inliers;
  result.mean_nis = s.verdict.mean_nis;
  result.expected_nis = s.verdict.expected_nis;
  result.covariance_scale = s.verdict.covariance_scale;
  result.num_overlap = s.verdict.num_overlap;
  result.inlier_ratio = s.verdict.inlier_ratio;
  result.ambiguity = s.verdict.ambiguity;
  result.rival_T_target_source = s.verdict.rival_T_target_source;
  result.rival_distance_m = s.verdict.rival_distance_m;
  result.rival_angle_deg = s.verdict.rival_angle_deg;
  result.covariance = s.covariance;
  result.num_half_samples = s.num_half_samples;
  result.trustworthy = s.verdict.trustworthy;
  result.trust_reason = s.verdict.reason;
  if (s.scales) {
    result.source_scales = s.scales->source;
    result.target_scales = s.scales->target;
    result.floor_m = s.scales->floor_m;
    result.up_source = s.scales->up_source;
    result.up_target = s.scales->up_target;
  }
  result.vote_cell_m = s.initialisation.resolution_m;
  result.ups_source = s.initialisation.ups_source;
  result.ups_target = s.initialisation.ups_target;
  for (const RefinedHypothesis& h : s.hypotheses) {
    AdaptiveHypothesis a;
    a.T_start = h.start.T_target_source;
    a.T_refined = h.T_refined;
    a.votes = static_cast<std::size_t>(h.start.search_score);
    a.score = h.score;
    a.from_guess = h.start.origin == "guess";
    result.hypotheses.push_back(a);
  }
  result.registration.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return result;
}

PipelineSpec adaptive_pipeline_spec(const AdaptiveOptions& o) {
  PipelineSpec spec;
  spec.name = "adaptive";
  spec.initialiser = o.complete_search ? "complete_search" : "yaw_vote";
  spec.matcher = "mahalanobis_gate";
  spec.kernel = "cauchy_mahalanobis";
  spec.estimator = "p2d_step";
  spec.schedule = "sigma_anneal";
  spec.scorer = "gated_inliers";
  spec.trust = "gated";
  auto set = [&](const char* key, SettingValue v) {
    spec.settings.emplace_back(key, std::move(v));
  };
  auto integer = [](auto v) { return static_cast<long long>(v); };
  set("init.yaw_step_deg", o.search.yaw_step_deg);
  set("init.source_samples", integer(o.search.source_samples));
  set("init.target_samples", integer(o.search.target_samples));
  set("init.hypotheses", integer(o.search.hypotheses));
  set("init.vote_cell_factor", o.vote_cell_factor);
  set("init.start_sigma_factor", o.start_sigma_factor);
  set("init.second_up_min_angle_deg", o.second_up_min_angle_deg);
  if (o.complete_search) {
    const CompleteSearchOptions& c = o.complete;
    set("search.vote_source_samples", integer(c.vote_source_samples));
    set("search.vote_target_samples", integer(c.vote_target_samples));
    set("search.peaks_per_yaw", integer(c.peaks_per_yaw));
    set("search.pool", integer(c.pool));
    set("search.screen_samples", integer(c.screen_samples));
    set("search.snap_samples", integer(c.snap_samples));
    set("search.snap_neighbours", integer(c.snap_neighbours));
    set("search.rank_samples", integer(c.rank_samples));
    set("search.rank_keep", integer(c.rank_keep));
    set("search.round1_iterations", integer(c.round1_iterations));
    set("search.round1_samples", integer(c.round1_samples));
    set("search.round1_keep", integer(c.round1_keep));
    set("search.round2_iterations", integer(c.round2_iterations));
    set("search.round2_samples", integer(c.round2_samples));
  }
  set("match.k", integer(o.gate.k));
  set("match.chi2_threshold", o.gate.chi2_threshold);
  set("kernel.scale_d2", o.gate.chi2_threshold);
  set("estimate.four_dof", o.four_dof);
  set("estimate.covariance_block_factor", o.covariance_block_factor);
  set("estimate.half_sample_planes", integer(o.covariance_half_sample_planes));
  set("estimate.half_sample_min_landmarks", integer(o.min_inliers));
  set("schedule.max_iterations", integer(o.max_iterations));
  set("schedule.max_iterations_per_level", integer(o.max_iterations_per_level));
  set("schedule.sigma_decay", o.sigma_decay);
  set("schedule.settle_ratio", o.settle_ratio);
  set("schedule.level_settle_ratio", o.level_settle_ratio);
  set("score.samples", integer(o.hypothesis_samples));
  set("trust.min_inliers", integer(o.min_inliers));
  set("trust.min_inlier_ratio", o.min_inlier_ratio);
  set("trust.max_covariance_scale", o.max_covariance_scale);
  set("trust.alias_ambiguity", o.alias_ambiguity);
  set("trust.alias_nis_ratio", o.alias_nis_ratio);
  set("trust.max_ambiguity", o.max_ambiguity);
  set("trust.distinct_cells", o.distinct_cells);
  set("scales.floor_m", o.floor_m);
  set("scales.default_up",
      std::vector<double>{o.default_up.x(), o.default_up.y(), o.default_up.z()});
  return spec;
}

}  // namespace lmalign
