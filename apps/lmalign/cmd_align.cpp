// `lmalign align`: align a source map onto a target map with the recommended strategy, the
// paper's strategies or lmalign's own, and print a table (and optionally JSON / PLY). See
// docs/cli.md.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/io/atomic_file.hpp"
#include "lmalign/io/ply.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/robust.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "lmalign/registration/strategy.hpp"
#include "lmalign/registration/uncertainty.hpp"

namespace lmalign::cli {

namespace {

struct AlignArgs {
  std::string source;
  std::string target;
  std::string weight;    // empty: not given
  std::string strategy;  // empty: not given
  int k = 5;
  int max_iterations = 150;
  double max_distance_m = std::numeric_limits<double>::infinity();
  std::string covariance_norm = "spectral";
  std::size_t min_observations = 2;
  std::string displace;
  std::string ground_truth;
  double success_rotation_deg = 5.0;
  double success_translation_m = 0.10;
  std::string json_path;
  std::string ply_path;
  std::string format = "auto";  // --format: the reader of SOURCE and TARGET
  bool history = false;
  std::string initial_guess;  // 4x4 file; empty: none
  std::string prior_sigma;    // ROT_DEG,TRANS_M; empty: none
  std::string image_size;     // W,H px (Bundler); empty: none
  // Given explicitly on the command line: then they also limit lmalign's own strategies.
  bool max_iterations_given = false;
  bool max_distance_given = false;
};

/// Whether --k matters to a strategy (the weighted-kNN selections).
bool uses_k(PaperStrategy s) {
  return s == PaperStrategy::kCovariance || s == PaperStrategy::kObservations ||
         s == PaperStrategy::kMeanDistance || s == PaperStrategy::kRobustObsKnn;
}

struct StrategyRun {
  PaperStrategy strategy = kRecommendedStrategy;
  RegistrationResult result;
  std::optional<TransformError> error;
  bool right_basin = false;
  StrategyOutcome outcome;  // the trust verdict (no ground truth involved) and the covariance
};

std::string ply_path_for(const std::string& base, const std::string& strategy, bool several) {
  if (!several) return base;
  if (writes_colmap_text(base)) {  // a COLMAP folder: one folder per strategy
    const std::string stem = base.back() == '/' ? base.substr(0, base.size() - 1) : base;
    return stem + "_" + strategy + "/";
  }
  std::filesystem::path p(base);
  const std::string ext = p.has_extension() ? p.extension().string() : ".ply";
  p.replace_extension();
  return p.string() + "_" + strategy + ext;
}

std::string fmt_score(double v) {
  if (!std::isfinite(v)) return "inf";
  char b[32];
  std::snprintf(b, sizeof b, "%.4e", v);
  return b;
}

int run_align(const AlignArgs& a) {
  // --- validate everything before any work, so bad input fails fast with one line.
  std::vector<PaperStrategy> strategies;
  if (!a.weight.empty() && !a.strategy.empty()) {
    throw InvalidArgument("give --weight or --strategy, not both");
  }
  if (a.weight == "all") {
    strategies = all_paper_strategies();
  } else if (!a.weight.empty()) {
    strategies = {parse_paper_strategy(a.weight)};
  } else if (!a.strategy.empty()) {
    std::string item;
    std::stringstream list(a.strategy);
    while (std::getline(list, item, ',')) {
      std::vector<PaperStrategy> add;
      if (item == "paper") {
        add = all_paper_strategies();
      } else if (item == "beyond") {
        add = beyond_paper_strategies();
      } else if (item == "all") {
        add = all_paper_strategies();
        for (PaperStrategy s : beyond_paper_strategies()) add.push_back(s);
      } else {
        add = {parse_paper_strategy(item)};
      }
      for (PaperStrategy s : add) {
        if (std::find(strategies.begin(), strategies.end(), s) != strategies.end()) {
          throw InvalidArgument("--strategy: '" + to_string(s) + "' is listed twice");
        }
        strategies.push_back(s);
      }
    }
    if (strategies.empty()) throw InvalidArgument("--strategy: no strategy given");
  } else {
    strategies = {kRecommendedStrategy};
  }
  WeightOptions wopt;
  wopt.covariance_norm = parse_covariance_norm(a.covariance_norm);
  Isometry3 T_displace = Isometry3::Identity();
  std::vector<double> disp;
  if (!a.displace.empty()) {
    disp = parse_number_list("--displace", a.displace, 6,
                             "x,y,z,roll,pitch,yaw (m, m, m, deg, deg, deg)");
    check_supported_translation("--displace " + a.displace, Vec3(disp[0], disp[1], disp[2]));
    for (int i = 3; i < 6; ++i) {
      check_supported_magnitude("--displace " + a.displace, disp[i], kMaxAngleDeg, "degrees");
    }
    T_displace = pose_from_xyz_rpy_deg(disp[0], disp[1], disp[2], disp[3], disp[4], disp[5]);
  }
  if (!(a.success_rotation_deg > 0) || !(a.success_translation_m > 0)) {
    throw InvalidArgument("--success-rotation-deg and --success-translation-m must be > 0");
  }
  if (!a.json_path.empty()) refuse_output_over_input("--json", a.json_path, {a.source, a.target});
  if (!a.ply_path.empty()) {
    refuse_output_over_input("--aligned-out", a.ply_path, {a.source, a.target});
    // With several strategies the files are NAME_<strategy>.ply: none may be an input either.
    for (PaperStrategy s : strategies) {
      const std::string path = ply_path_for(a.ply_path, to_string(s), strategies.size() > 1);
      refuse_output_over_input("--aligned-out", path, {a.source, a.target});
      if (!a.json_path.empty() && same_file(path, a.json_path)) {
        throw InvalidArgument("--aligned-out '" + path + "' and --json name the same file");
      }
    }
  }
  if (std::isnan(a.max_distance_m) || !(a.max_distance_m > 0.0)) {
    throw InvalidArgument("--max-distance " + std::to_string(a.max_distance_m) +
                          ": must be > 0 metres (or inf)");
  }

  std::optional<PriorSigma> prior;
  if (!a.prior_sigma.empty()) {
    const std::vector<double> v =
        parse_number_list("--prior-sigma", a.prior_sigma, 2, "ROT_DEG,TRANS_M");
    prior = PriorSigma{v[0], v[1]};
    std::string why;
    if (!prior->is_valid(&why))
      throw InvalidArgument("--prior-sigma " + a.prior_sigma + ": " + why);
    for (PaperStrategy s : strategies) {
      if (s != PaperStrategy::kAdaptive) {
        throw InvalidArgument("--prior-sigma: only the adaptive strategy uses a prior (got '" +
                              to_string(s) + "')");
      }
    }
  }
  std::optional<Isometry3> initial_guess;
  if (!a.initial_guess.empty()) {
    initial_guess = read_transform(a.initial_guess);
    if (!is_rigid_transform(*initial_guess)) {
      throw InvalidArgument("--initial-guess " + a.initial_guess +
                            ": not a rigid transform (expected [R t; 0 0 0 1] with R orthonormal "
                            "and det R = +1)");
    }
    check_supported_translation("--initial-guess " + a.initial_guess, initial_guess->translation());
  }

  std::optional<Isometry3> T_gt;  // ground truth for the undisplaced source
  if (a.ground_truth == "identity") {
    T_gt = Isometry3::Identity();
  } else if (!a.ground_truth.empty()) {
    T_gt = read_transform(a.ground_truth);
    check_supported_translation("--ground-truth " + a.ground_truth, T_gt->translation());
  }

  MapReadOptions ropt;
  ropt.min_observations = a.min_observations;
  AnyMapReadOptions any(ropt, parse_map_format(a.format));
  if (!a.image_size.empty()) any.image_size_px = parse_image_size(a.image_size);
  const Map source = read_any_map(a.source, any);
  const Map target = read_any_map(a.target, any);
  if (source.landmarks.empty())
    throw InvalidArgument("source map '" + a.source +
                          "' has no landmarks (after the --min-observations filter)");
  if (target.landmarks.empty())
    throw InvalidArgument("target map '" + a.target +
                          "' has no landmarks (after the --min-observations filter)");

  // The paper displaces the source about the world origin, then starts ICP at the identity.
  const Points3 source_points = transform_points(T_displace, source.positions());
  // Their covariances move with them (C' = R C R^T), for the point-to-distribution strategies.
  const std::vector<Mat3> source_covariances =
      transform_covariances(T_displace, source.covariances_m2());
  // Truth for the displaced source. Errors are measured on the recovered map-to-map transform
  // T_est * T_displace against T_gt, so they do not depend on the artificial displacement.
  std::optional<Isometry3> T_true;
  if (T_gt) T_true = *T_gt * T_displace.inverse();

  const PreparedTarget prepared(target, wopt);

  std::printf("lmalign align: source %s (%zu landmarks) -> target %s (%zu landmarks)\n",
              a.source.c_str(), source.landmarks.size(), a.target.c_str(), target.landmarks.size());
  if (!disp.empty()) {
    std::printf(
        "source displaced about the world origin by x=%g y=%g z=%g m, roll=%g pitch=%g yaw=%g "
        "deg\n",
        disp[0], disp[1], disp[2], disp[3], disp[4], disp[5]);
  }
  std::printf("k=%d, max iterations=%d, max correspondence distance=%s m, covariance norm=%s\n",
              a.k, a.max_iterations,
              std::isinf(a.max_distance_m) ? "inf" : std::to_string(a.max_distance_m).c_str(),
              a.covariance_norm.c_str());
  const bool any_own = std::any_of(strategies.begin(), strategies.end(),
                                   [](PaperStrategy s) { return !is_paper_strategy(s); });
  if (any_own) {
    std::printf("lmalign's own strategies: %s\n",
                a.max_iterations_given || a.max_distance_given
                    ? "preset distance schedule and budget, limited by the options above"
                    : "preset distance schedule (inf .. 0.05 m) and budget (300 iterations); "
                      "the limits above apply to the paper's strategies");
  }
  if (T_true) {
    std::printf(
        "ground truth: %s; right basin = rotation error < %g deg and translation error < %g m\n",
        a.ground_truth.c_str(), a.success_rotation_deg, a.success_translation_m);
  }
  std::printf("\n");

  StrategySource src;
  src.positions = source_points;
  src.covariances_m2 = source_covariances;
  if (const std::optional<Vec3> up = estimate_up_axis(source)) src.up = T_displace.linear() * *up;
  std::vector<StrategyRun> runs;
  for (PaperStrategy s : strategies) {
    StrategyRequest req;
    req.strategy = s;
    req.k = a.k;
    req.initial_guess = initial_guess;
    req.prior = prior;
    if (is_paper_strategy(s)) {
      req.max_iterations = a.max_iterations;
      req.max_distance_m = a.max_distance_m;
      req.record_history = a.history;
    } else {
      if (a.max_iterations_given) req.max_iterations = a.max_iterations;
      if (a.max_distance_given && s != PaperStrategy::kAdaptive) {
        req.max_distance_m = a.max_distance_m;
      }
    }
    StrategyRun run;
    run.strategy = s;
    run.outcome = run_strategy(src, prepared, req);
    run.result = run.outcome.result;
    if (T_true) {
      run.error = transform_error(run.result.T_target_source * T_displace, *T_gt);
      run.right_basin = run.error->rotation_deg < a.success_rotation_deg &&
                        run.error->translation_m < a.success_translation_m;
    }
    runs.push_back(run);
  }

  // --- human table
  std::printf("%-13s %3s %12s %12s %6s %-19s %9s", "strategy", "k", "init score", "final score",
              "iters", "termination", "time ms");
  if (T_true) std::printf(" %8s %8s %6s", "rot deg", "trans m", "basin");
  std::printf(" %6s\n", "trust");
  for (const StrategyRun& r : runs) {
    const bool weighted = uses_k(r.strategy);
    std::printf("%-13s %3s %12s %12s %6d %-19s %9.2f", to_string(r.strategy).c_str(),
                weighted ? std::to_string(a.k).c_str() : "-",
                fmt_score(r.result.initial_score_m2).c_str(),
                fmt_score(r.result.final_score_m2).c_str(), r.result.iterations,
                to_string(r.result.termination).c_str(), r.result.wall_time_s * 1e3);
    if (r.error) {
      std::printf(" %8.3f %8.4f %6s", r.error->rotation_deg, r.error->translation_m,
                  r.right_basin ? "yes" : "NO");
    }
    std::printf(" %6s\n", r.outcome.trustworthy ? "yes" : "NO");
  }
  std::printf("\nscores are PCL fitness scores (mean squared nearest-neighbour distance, m^2)\n");
  std::printf(
      "trust: the verdict without ground truth (docs/accuracy.md): adaptive: covariance-gated "
      "inliers and no distinct pose scoring nearly as well; the others: inliers within 5 cm, of "
      "all source landmarks and of those within 20 cm, and the covariance on them\n");
  for (const StrategyRun& r : runs) {
    if (!r.outcome.trustworthy) {
      std::printf("  %-13s not trusted: %s\n", to_string(r.strategy).c_str(),
                  r.outcome.trust_reason.c_str());
    } else if (r.outcome.source_left_out + r.outcome.target_left_out > 0) {
      std::printf("  %-13s trusted: %s\n", to_string(r.strategy).c_str(),
                  r.outcome.trust_reason.c_str());
    }
  }
  std::printf(
      "\nestimated T_target_source (p_target = T * p_source): x y z [m], roll pitch yaw [deg]\n");
  for (const StrategyRun& r : runs) {
    const auto v = xyz_rpy_deg_from_pose(r.result.T_target_source);
    std::printf("  %-13s %9.4f %9.4f %9.4f   %9.3f %9.3f %9.3f\n", to_string(r.strategy).c_str(),
                v[0], v[1], v[2], v[3], v[4], v[5]);
  }
  if (T_true) {
    const auto v = xyz_rpy_deg_from_pose(*T_true);
    std::printf("  %-13s %9.4f %9.4f %9.4f   %9.3f %9.3f %9.3f\n", "(truth)", v[0], v[1], v[2],
                v[3], v[4], v[5]);
  }

  // --- machine-readable outputs
  if (!a.ply_path.empty()) {
    for (const StrategyRun& r : runs) {
      const std::string path = ply_path_for(a.ply_path, to_string(r.strategy), runs.size() > 1);
      // The writer by extension: .ply (with covariances), a folder (COLMAP text), else ours.
      write_any_map(path, transform_map(source, r.result.T_target_source * T_displace));
      std::printf("aligned source (%s) written to %s\n", to_string(r.strategy).c_str(),
                  path.c_str());
    }
  }
  if (!a.json_path.empty()) {
    nlohmann::json j;
    j["source"] = a.source;
    j["target"] = a.target;
    j["source_landmarks"] = source.landmarks.size();
    j["target_landmarks"] = target.landmarks.size();
    j["frames"] =
        "T_target_source maps displaced-source coordinates to target coordinates (metres)";
    if (!disp.empty()) {
      j["displacement"] = {{"x_m", disp[0]},      {"y_m", disp[1]},       {"z_m", disp[2]},
                           {"roll_deg", disp[3]}, {"pitch_deg", disp[4]}, {"yaw_deg", disp[5]}};
    }
    j["k"] = a.k;
    j["max_iterations"] = a.max_iterations;
    j["max_correspondence_distance_m"] = json_number(a.max_distance_m);
    j["covariance_norm"] = a.covariance_norm;
    if (T_true) {
      j["ground_truth"] = a.ground_truth;
      j["T_target_source_true"] = json_matrix(*T_true);
      j["success_rotation_deg"] = a.success_rotation_deg;
      j["success_translation_m"] = a.success_translation_m;
    }
    nlohmann::json results = nlohmann::json::array();
    for (const StrategyRun& r : runs) {
      nlohmann::json e;
      e["strategy"] = to_string(r.strategy);
      e["k"] = uses_k(r.strategy) ? nlohmann::json(a.k) : nlohmann::json();
      e["T_target_source"] = json_matrix(r.result.T_target_source);
      e["converged"] = r.result.converged;
      e["termination"] = to_string(r.result.termination);
      e["iterations"] = r.result.iterations;
      e["num_correspondences"] = r.result.num_correspondences;
      e["initial_score_m2"] = json_number(r.result.initial_score_m2);
      e["final_score_m2"] = json_number(r.result.final_score_m2);
      e["wall_time_s"] = r.result.wall_time_s;
      e["trustworthy"] = r.outcome.trustworthy;
      e["trust_reason"] = r.outcome.trust_reason;
      e["source_landmarks_left_out"] = r.outcome.source_left_out;
      e["target_landmarks_left_out"] = r.outcome.target_left_out;
      if (r.outcome.verdict) {
        e["inlier_fraction"] = r.outcome.verdict->inlier_fraction;
        e["overlap_fraction"] = r.outcome.verdict->overlap_fraction;
      }
      if (r.outcome.adaptive) {
        const AdaptiveResult& ad = *r.outcome.adaptive;
        e["initialisation"] = ad.initialisation;
        e["gated_inliers"] = ad.num_inliers;
        e["gated_score"] = ad.score;
        e["gated_inlier_ratio"] = ad.inlier_ratio;
        e["ambiguity"] = ad.ambiguity;
        e["mean_nis"] = ad.mean_nis;
        e["expected_nis"] = ad.expected_nis;
        e["covariance_floor_m"] = ad.floor_m;
        e["vote_cell_m"] = ad.vote_cell_m;
        e["hypotheses"] = ad.hypotheses.size();
      }
      e["translation_sd_m"] = json_number(r.outcome.covariance.translation_sd_m());
      e["rotation_sd_deg"] = json_number(r.outcome.covariance.rotation_sd_deg());
      {
        // Row-major 6x6, xi = (rho [m], phi [rad]) on the left in the target frame; null if the
        // inliers do not determine the transform.
        nlohmann::json c = nlohmann::json::array();
        const PoseCovariance& cov = r.outcome.covariance;
        if (cov.valid) {
          for (int i = 0; i < 6; ++i) {
            for (int k = 0; k < 6; ++k) c.push_back(cov.covariance(i, k));
          }
        }
        e["covariance_6x6"] = cov.valid ? c : nlohmann::json();
      }
      if (r.error) {
        e["rotation_error_deg"] = r.error->rotation_deg;
        e["translation_error_m"] = r.error->translation_m;
        e["right_basin"] = r.right_basin;
      }
      if (a.history) {
        nlohmann::json h = nlohmann::json::array();
        for (const IterationRecord& it : r.result.history) {
          h.push_back({{"iteration", it.iteration},
                       {"num_correspondences", it.num_correspondences},
                       {"mse_m2", json_number(it.mse_m2)},
                       {"score_m2", json_number(it.score_m2)}});
        }
        e["history"] = h;
      }
      results.push_back(e);
    }
    j["results"] = results;
    const std::filesystem::path jp(a.json_path);
    if (jp.has_parent_path()) {
      std::error_code ec;
      std::filesystem::create_directories(jp.parent_path(), ec);
      if (ec) {
        throw IoError("cannot write '" + a.json_path +
                      "': cannot create its folder: " + ec.message());
      }
    }
    // Paths need not be UTF-8 (JSON text must be): invalid bytes become U+FFFD.
    write_file_atomically(a.json_path, [&](std::ostream& out) {
      out << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
    });
    std::printf("JSON written to %s\n", a.json_path.c_str());
  }
  return 0;
}

}  // namespace

CommandRunner add_align_command(CLI::App& root) {
  auto args = std::make_shared<AlignArgs>();
  CLI::App* cmd = root.add_subcommand(
      "align",
      "Align SOURCE onto TARGET (map files, docs/map-format.md) with ICP and the paper's\n"
      "confidence-weighted correspondences, or lmalign's own strategies (by default the\n"
      "recommended one, adaptive: no initial guess needed). Prints one row per strategy.\n"
      "Result: T_target_source, with p_target = T_target_source * p_source (metres).");
  cmd->add_option("SOURCE", args->source, "source map file (moved onto the target)")->required();
  cmd->add_option("TARGET", args->target, "target map file (fixed)")->required();
  cmd->add_option("--weight", args->weight,
                  "one of the paper's strategies: none (base ICP, nearest neighbour), covariance, "
                  "observations, distance (mean observation distance), or all four")
      ->check(CLI::IsMember({"none", "base", "covariance", "observations", "distance", "all"}));
  cmd->add_option(
      "--strategy", args->strategy,
      "comma-separated strategies by name: the paper's (base, covariance, "
      "observations, distance) and lmalign's own (shrink, shrink_cauchy, trimmed, "
      "mutual, robust_obs, robust_obs_knn, robust_obs_4dof, global, global_robust_obs, p2d, "
      "robust_p2d, adaptive); 'paper', "
      "'beyond' and "
      "'all' name groups. Default (neither --weight nor --strategy): adaptive, the "
      "recommended strategy (docs/accuracy.md): scales from the data, a global yaw search "
      "(or one bounded by --prior-sigma), covariance-gated point-to-distribution ICP. "
      "lmalign's robust presets run their preset "
      "(a distance schedule inf, 1, 0.5, 0.25, 0.1, 0.05 m; 300 iterations) unless "
      "--max-iterations or --max-distance is given: then the budget is replaced and the "
      "schedule capped at that distance (adaptive: --max-iterations caps each refinement; "
      "--max-distance does not apply)");
  cmd->add_option("--k", args->k, "neighbourhood size of the weighted strategies, [1, 4096]")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  CLI::Option* max_iterations =
      cmd->add_option("--max-iterations", args->max_iterations,
                      "ICP iteration budget, >= 1 (paper's strategies: 150 by default)")
          ->check(CLI::PositiveNumber)
          ->capture_default_str();
  CLI::Option* max_distance =
      cmd->add_option("--max-distance", args->max_distance_m,
                      "maximum correspondence distance, metres (paper's strategies: infinite by "
                      "default, as the paper; lmalign's: caps the distance schedule)")
          ->check(CLI::PositiveNumber);
  cmd->add_option("--covariance-norm", args->covariance_norm,
                  "matrix norm of the covariance weight: spectral (the paper's L2) or frobenius")
      ->check(CLI::IsMember({"spectral", "frobenius"}))
      ->capture_default_str();
  cmd->add_option("--min-observations", args->min_observations,
                  "drop landmarks with fewer observations on load")
      ->capture_default_str();
  cmd->add_option("--displace", args->displace,
                  "move the source before aligning: x,y,z,roll,pitch,yaw in metres and degrees, "
                  "about the world origin, R = Rz(yaw) Ry(pitch) Rx(roll) (the paper's protocol)");
  cmd->add_option(
      "--ground-truth", args->ground_truth,
      "true T_target_source of the undisplaced source: 'identity' or a 4x4 matrix file; "
      "adds rotation (deg) and translation (m) errors");
  cmd->add_option("--success-rotation-deg", args->success_rotation_deg,
                  "right-basin threshold on the rotation error, degrees")
      ->capture_default_str();
  cmd->add_option("--success-translation-m", args->success_translation_m,
                  "right-basin threshold on the translation error, metres")
      ->capture_default_str();
  cmd->add_option("--json", args->json_path, "also write the results as JSON to this file");
  cmd->add_option("--aligned-out", args->ply_path,
                  "write the aligned source map (target frame): FILE.ply as PLY with "
                  "covariances, a folder as COLMAP text, any other name as an lmalign map; with "
                  "several strategies, one each: NAME_<strategy>.ply");
  cmd->add_option("--format", args->format,
                  "reader of SOURCE and TARGET: auto (by content), lmalign, colmap-text, "
                  "colmap-bin, ply, stella-vslam (docs/map-format.md)");
  cmd->add_option("--image-size", args->image_size,
                  "Bundler maps: the image size W,H in pixels (Bundler pixels are centred)");
  cmd->add_option("--initial-guess", args->initial_guess,
                  "a first estimate of T_target_source (of the displaced source, if --displace): "
                  "a 4x4 matrix file (p_target = T * p_source, metres). Every strategy starts "
                  "from it; adaptive adds it to its hypotheses, or bounds its search around it "
                  "with --prior-sigma");
  cmd->add_option("--prior-sigma", args->prior_sigma,
                  "ROT_DEG,TRANS_M: standard deviations of --initial-guess (identity if none), "
                  "degrees and metres, each > 0: the adaptive search stays within 3 sigma of it");
  cmd->add_flag("--history", args->history,
                "record per-iteration correspondences, MSE and score (into --json)");
  return [args, max_iterations, max_distance]() {
    args->max_iterations_given = max_iterations->count() > 0;
    args->max_distance_given = max_distance->count() > 0;
    return run_align(*args);
  };
}

}  // namespace lmalign::cli
