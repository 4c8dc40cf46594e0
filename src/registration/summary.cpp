// The result of an alignment as text and JSON (include/lmalign/registration/pipeline.hpp): the one
// serialisation that the CLI, the experiment runner, Python and the merge use.
#include <cmath>
#include <cstdio>

#include <nlohmann/json.hpp>

#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/pipeline.hpp"

namespace lmalign {

namespace {

using json = nlohmann::json;

json number(double v) { return std::isfinite(v) ? json(v) : json(); }

json matrix4(const Isometry3& T) {
  json m = json::array();
  for (int r = 0; r < 4; ++r) {
    json row = json::array();
    for (int c = 0; c < 4; ++c) row.push_back(T.matrix()(r, c));
    m.push_back(row);
  }
  return m;
}

json covariance6(const PoseCovariance& c) {
  if (!c.valid) return json();
  json v = json::array();
  for (int i = 0; i < 6; ++i) {
    for (int k = 0; k < 6; ++k) v.push_back(c.covariance(i, k));
  }
  return v;
}

json vec3(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

std::string fmt(const char* format, double v) {
  char b[64];
  std::snprintf(b, sizeof b, format, v);
  return b;
}

// The verdict's evidence: Euclidean inlier fractions (judge "inliers"), or covariance-gated.
bool gated(const Summary& s) {
  return std::isnan(s.verdict.inlier_fraction) && s.verdict.expected_nis > 0.0;
}

}  // namespace

bool Summary::IsSolutionUsable() const {
  return is_finite(registration.T_target_source) &&
         registration.termination != TerminationReason::kNoCorrespondences &&
         registration.termination != TerminationReason::kDegenerate &&
         registration.termination != TerminationReason::kNotTerminated;
}

std::string Summary::BriefReport() const {
  std::string s = preset + ": " + registration.brief_report() + "; " +
                  (scale.free ? "scale " + fmt("%.6g", scale.scale) + " +- " +
                                    fmt("%.2g", scale.scale_sd) + "; "
                              : std::string()) +
                  (verdict.trustworthy ? std::string("trusted") : "not trusted: " + verdict.reason);
  return s;
}

std::string Summary::FullReport() const {
  std::string r;
  auto line = [&](const std::string& k, const std::string& v) { r += "  " + k + ": " + v + "\n"; };
  r += "lmalign alignment summary (" + preset + ")\n";
  line(
      "stages", "initialiser " + stages.initialiser + ", matcher " + stages.matcher +
                    (stages.rejectors.empty() ? std::string() : ", rejectors") +
                    [&] {
                      std::string t;
                      for (const std::string& x : stages.rejectors) t += " " + x;
                      return t;
                    }() +
                    ", kernel " + stages.kernel + ", estimator " + stages.estimator +
                    ", schedule " + stages.schedule + ", scorer " + stages.scorer + ", trust " +
                    stages.trust);
  if (!stages.settings.empty()) {
    std::string changed;
    for (const auto& [key, value] : settings) {
      for (const auto& kv : stages.settings) {
        if (kv.first == key) {
          changed += (changed.empty() ? "" : ", ") + key + "=" + value;
          break;
        }
      }
    }
    line("settings (not the defaults)", changed);
  }
  if (scales) {
    line("scales", "spacing " + fmt("%.4g", scales->source.spacing_m) + " / " +
                       fmt("%.4g", scales->target.spacing_m) + " m, floor " +
                       fmt("%.4g", scales->floor_m) + " m, radius " +
                       fmt("%.4g", scales->source.radius_m) + " m");
  }
  if (scale.free) {
    line("scale", "free: " + fmt("%.6g", scale.scale) + " +- " + fmt("%.2g", scale.scale_sd) +
                      " target units per source unit (initial " + fmt("%.4g", scale.initial_scale) +
                      (std::isfinite(scale.measured_factor)
                           ? ": the spacings' times " + fmt("%.4g", scale.measured_factor) +
                                 " measured by the correspondences, "
                       : std::isfinite(scale.lead_factor)
                           ? ": the spacings' times " + fmt("%.4g", scale.lead_factor) +
                                 ", where the correspondences' cliques were largest, "
                           : " from the spacings, ") +
                      std::to_string(scale.rounds) + " 7-DoF refinements kept, " +
                      std::to_string(scale.attempts) + " scales concluded over " +
                      std::to_string(scale.searches) + " searches)");
  }
  line("initialisation",
       initialisation.initialisation +
           (initialisation.resolution_m > 0.0
                ? ", resolution " + fmt("%.4g", initialisation.resolution_m) + " m / " +
                      fmt("%.3g", initialisation.resolution_rad * 180.0 / kPi) + " deg"
                : std::string()) +
           (std::isnan(initialisation.best_search_score)
                ? std::string()
                : ", best search score " + fmt("%.6g", initialisation.best_search_score)) +
           (std::isnan(initialisation.second_search_score)
                ? std::string()
                : ", second " + fmt("%.6g", initialisation.second_search_score)) +
           (initialisation.prior_checked ? ", the prior checked by the global search"
                                         : std::string()));
  if (!hypotheses.empty()) {
    std::string h = std::to_string(hypotheses.size()) + " refined, scores";
    for (std::size_t i = 0; i < hypotheses.size() && i < 8; ++i) {
      h += " " + fmt("%.4g", hypotheses[i].score);
    }
    line("hypotheses", h);
  }
  line("refinement", registration.brief_report());
  if (at_estimate.computed) {
    line("at the estimate", std::to_string(at_estimate.num_pairs) + " pairs, inlier ratio " +
                                fmt("%.4g", at_estimate.inlier_ratio) + ", overlap ratio " +
                                fmt("%.4g", at_estimate.overlap_ratio) + ", RMS " +
                                fmt("%.4g", at_estimate.inlier_rms_m) + " m within " +
                                fmt("%.4g", at_estimate.max_distance_m) + " m");
  }
  auto cov = [&](const PoseCovariance& c) {
    return c.valid ? "translation sd " + fmt("%.4g", c.translation_sd_m()) + " m, rotation sd " +
                         fmt("%.4g", c.rotation_sd_deg()) + " deg"
                   : std::string("not determined");
  };
  line("estimator covariance",
       cov(estimator_covariance) + (num_half_samples > 0
                                        ? ", " + std::to_string(num_half_samples) + " half samples"
                                        : std::string()));
  if (verdict.covariance) line("judge's covariance", cov(covariance));
  std::string v = verdict.trustworthy ? "trusted" : "not trusted: " + verdict.reason;
  if (gated(*this)) {
    v += " (" + std::to_string(verdict.num_inliers) + " gated inliers of " +
         std::to_string(verdict.num_overlap) + " near, mean NIS " + fmt("%.4g", verdict.mean_nis) +
         " / " + fmt("%.4g", verdict.expected_nis) + ", ambiguity " +
         fmt("%.3g", verdict.ambiguity) + ", covariance scale " +
         fmt("%.3g", verdict.covariance_scale) + ")";
  } else if (!std::isnan(verdict.inlier_fraction)) {
    v += " (inlier fraction " + fmt("%.4g", verdict.inlier_fraction) + ", overlap fraction " +
         fmt("%.4g", verdict.overlap_fraction) + ")";
  }
  line("verdict", v);
  line("usable", IsSolutionUsable() ? "yes" : "no");
  return r;
}

std::string to_json(const Summary& s, int indent) {
  const RegistrationResult& r = s.registration;
  json e;
  e["strategy"] = s.preset;
  e["stages"] = {{"initialiser", s.stages.initialiser}, {"matcher", s.stages.matcher},
                 {"rejectors", s.stages.rejectors},     {"kernel", s.stages.kernel},
                 {"estimator", s.stages.estimator},     {"schedule", s.stages.schedule},
                 {"scorer", s.stages.scorer},           {"trust", s.stages.trust}};
  e["T_target_source"] = matrix4(r.T_target_source);
  // The scale (target units per source unit; 1 when fixed) and the whole similarity [sR t; 0 1].
  e["scale_mode"] = s.scale.free ? "free" : "fixed";
  e["scale"] = s.scale.scale;
  e["scale_sd"] = number(s.scale.scale_sd);
  {
    json m = json::array();
    const Mat4 S = s.similarity().matrix();
    for (int i = 0; i < 4; ++i) m.push_back({S(i, 0), S(i, 1), S(i, 2), S(i, 3)});
    e["S_target_source"] = m;
  }
  if (s.scale.free) {
    json c;
    if (s.scale.covariance_7x7) {
      c = json::array();
      for (int i = 0; i < 7; ++i) {
        for (int k = 0; k < 7; ++k) c.push_back((*s.scale.covariance_7x7)(i, k));
      }
    }
    e["scale_report"] = {
        {"initial_scale", s.scale.initial_scale},
        {"measured_factor",
         std::isfinite(s.scale.measured_factor) ? json(s.scale.measured_factor) : json(nullptr)},
        {"lead_factor",
         std::isfinite(s.scale.lead_factor) ? json(s.scale.lead_factor) : json(nullptr)},
        {"rounds", s.scale.rounds},
        {"attempts", s.scale.attempts},
        {"searches", s.scale.searches},
        {"covariance_7x7", c}};
  }
  e["converged"] = r.converged;
  e["termination"] = to_string(r.termination);
  e["iterations"] = r.iterations;
  e["num_correspondences"] = r.num_correspondences;
  e["initial_score_m2"] = number(r.initial_score_m2);
  e["final_score_m2"] = number(r.final_score_m2);
  e["wall_time_s"] = r.wall_time_s;
  // The whole call: the verdict, the scale's rounds and its retried initial scales included.
  e["total_time_s"] = s.total_time_s;
  e["usable"] = s.IsSolutionUsable();
  e["trustworthy"] = s.verdict.trustworthy;
  e["trust_reason"] = s.verdict.reason;
  e["source_landmarks_left_out"] = s.source_left_out;
  e["target_landmarks_left_out"] = s.target_left_out;
  e["covariances_assumed"] = s.covariances_assumed;
  e["initialisation"] = s.initialisation.initialisation;
  e["hypotheses"] = s.hypotheses.size();
  if (gated(s)) {
    e["gated_inliers"] = s.verdict.num_inliers;
    e["gated_score"] = s.verdict.score;
    e["gated_inlier_ratio"] = s.verdict.inlier_ratio;
    e["ambiguity"] = s.verdict.ambiguity;
    e["mean_nis"] = s.verdict.mean_nis;
    e["expected_nis"] = s.verdict.expected_nis;
    e["covariance_scale"] = s.verdict.covariance_scale;
    e["alias_waived_by_prior"] = s.verdict.alias_waived_by_prior;
    if (s.verdict.rival_T_target_source) {
      e["rival"] = {{"T_target_source", matrix4(*s.verdict.rival_T_target_source)},
                    {"distance_m", s.verdict.rival_distance_m},
                    {"angle_deg", s.verdict.rival_angle_deg}};
    } else {
      e["rival"] = nullptr;
    }
  } else if (!std::isnan(s.verdict.inlier_fraction)) {
    e["inlier_fraction"] = s.verdict.inlier_fraction;
    e["overlap_fraction"] = s.verdict.overlap_fraction;
  }
  if (s.scales) {
    e["covariance_floor_m"] = s.scales->floor_m;
    e["scales"] = {{"source_spacing_m", s.scales->source.spacing_m},
                   {"target_spacing_m", s.scales->target.spacing_m},
                   {"source_radius_m", s.scales->source.radius_m},
                   {"up_source", vec3(s.scales->up_source)},
                   {"up_target", vec3(s.scales->up_target)}};
  }
  if (s.initialisation.resolution_m > 0.0) e["vote_cell_m"] = s.initialisation.resolution_m;
  {
    json init = {{"initialisation", s.initialisation.initialisation},
                 {"resolution_m", s.initialisation.resolution_m},
                 {"resolution_rad", s.initialisation.resolution_rad},
                 {"best_search_score", number(s.initialisation.best_search_score)},
                 {"second_search_score", number(s.initialisation.second_search_score)},
                 {"prior_checked", s.initialisation.prior_checked}};
    for (const auto& [k, v] : s.initialisation.notes) init[k] = number(v);
    e["initialiser_report"] = init;
  }
  json hyps = json::array();
  for (const RefinedHypothesis& h : s.hypotheses) {
    hyps.push_back({{"origin", h.start.origin},
                    {"search_score", h.start.search_score},
                    {"score", h.score},
                    {"iterations", h.iterations},
                    {"termination", to_string(h.termination)},
                    {"sharp_restart", h.sharp_restart},
                    {"refined_again", h.refined_again},
                    {"T_start", matrix4(h.start.T_target_source)},
                    {"T_refined", matrix4(h.T_refined)}});
  }
  e["refined_hypotheses"] = hyps;
  if (s.at_estimate.computed) {
    e["at_estimate"] = {{"num_pairs", s.at_estimate.num_pairs},
                        {"inlier_ratio", s.at_estimate.inlier_ratio},
                        {"overlap_ratio", s.at_estimate.overlap_ratio},
                        {"max_distance_m", number(s.at_estimate.max_distance_m)},
                        {"inlier_rms_m", s.at_estimate.inlier_rms_m}};
  }
  e["translation_sd_m"] = number(s.covariance.translation_sd_m());
  e["rotation_sd_deg"] = number(s.covariance.rotation_sd_deg());
  // Row-major 6x6, xi = (rho [m], phi [rad]) on the left in the target frame; null if not
  // determined.
  e["covariance_6x6"] = covariance6(s.covariance);
  e["estimator_covariance_6x6"] = covariance6(s.estimator_covariance);
  e["half_samples"] = s.num_half_samples;
  e["settings"] = json::object();
  for (const auto& [k, v] : s.settings) e["settings"][k] = v;
  if (!r.history.empty()) {
    json h = json::array();
    for (const IterationRecord& it : r.history) {
      h.push_back({{"iteration", it.iteration},
                   {"num_correspondences", it.num_correspondences},
                   {"mse_m2", number(it.mse_m2)},
                   {"score_m2", number(it.score_m2)}});
    }
    e["history"] = h;
  }
  return e.dump(indent, ' ', false, json::error_handler_t::replace);
}

}  // namespace lmalign
