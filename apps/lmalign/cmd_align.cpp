// `lmalign align`: align a source map onto a target map with one or more strategies (presets of
// the registration engine, configs/presets/), and print a table (and optionally JSON / PLY). See
// docs/cli.md. Parses, calls align() per strategy, prints: nothing else.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/core/similarity.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/io/ply.hpp"
#include "lmalign/io/transform_io.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/transform.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/stages/data_scales.hpp"

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
  std::vector<std::string> settings;  // --set KEY=VALUE
  std::string covariance_norm = "spectral";
  std::size_t min_observations = 2;
  std::string displace;
  std::string ground_truth;
  double success_rotation_deg = 5.0;
  double success_translation_m = 0.10;
  std::string json_path;
  std::string ply_path;
  std::string aligned_format = "auto";
  std::string format = "auto";  // --format: the reader of SOURCE and TARGET
  bool history = false;
  std::string initial_guess;   // 4x4 file; empty: none
  std::string prior_sigma;     // ROT_DEG,TRANS_M; empty: none
  std::string image_size;      // W,H px (Bundler); empty: none
  std::string scale = "auto";  // --scale auto|free|fixed
  bool max_iterations_given = false;
  bool max_distance_given = false;
};

struct Run {
  Preset preset;
  Summary summary;
  std::optional<SimilarityError> error;
  bool right_basin = false;
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

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const std::string& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

/// The strategies named by --weight / --strategy, in order, each once.
std::vector<Preset> strategies_of(const AlignArgs& a) {
  if (!a.weight.empty() && !a.strategy.empty()) {
    throw InvalidArgument("give --weight or --strategy, not both");
  }
  std::vector<Preset> out;
  auto add = [&](const Preset& p) {
    for (const Preset& q : out) {
      if (q.name == p.name) throw InvalidArgument("--strategy: '" + p.name + "' is listed twice");
    }
    out.push_back(p);
  };
  if (a.weight == "all") {
    for (const std::string& n : preset_names("paper")) add(find_preset(n));
  } else if (!a.weight.empty()) {
    Preset p;
    try {
      p = find_preset(a.weight);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(std::string("--weight: ") + e.what());
    }
    if (p.group != "paper") {
      throw InvalidArgument("--weight '" + a.weight + "': not one of the paper's strategies (" +
                            join(preset_names("paper")) + ")");
    }
    add(p);
  } else if (!a.strategy.empty()) {
    std::string item;
    std::stringstream list(a.strategy);
    while (std::getline(list, item, ',')) {
      if (item == "paper" || item == "all") {
        for (const std::string& n : preset_names("paper")) add(find_preset(n));
      }
      if (item == "beyond" || item == "lmalign" || item == "all") {
        for (const std::string& n : preset_names("lmalign")) add(find_preset(n));
      }
      if (item != "paper" && item != "beyond" && item != "lmalign" && item != "all") {
        Preset p;
        try {
          p = find_preset(item);
        } catch (const InvalidArgument& e) {
          throw InvalidArgument(std::string("--strategy: ") + e.what());
        }
        add(p);
      }
    }
    if (out.empty()) throw InvalidArgument("--strategy: no strategy given");
  } else {
    add(recommended_preset());
  }
  return out;
}

/// Everything `lmalign align` checks before reading a map: the strategies, one request each,
/// the displacement, the weights and the ground truth. Throws InvalidArgument (one line naming
/// the option) or what reading the truth and guess files throws.
struct AlignPlan {
  std::vector<Preset> strategies;
  std::vector<AlignRequest> requests;
  WeightOptions wopt;
  Isometry3 T_displace = Isometry3::Identity();
  std::vector<double> disp;         // the --displace numbers, empty without it
  std::optional<Similarity3> T_gt;  // ground truth for the undisplaced source
};

AlignPlan plan_align(const AlignArgs& a) {
  AlignPlan plan;
  // --- validate everything before any work, so bad input fails fast with one line.
  plan.strategies = strategies_of(a);
  const std::vector<Preset>& strategies = plan.strategies;
  AlignRequest request;
  if (a.max_iterations_given) request.max_iterations = a.max_iterations;
  if (a.max_distance_given) {
    if (std::isnan(a.max_distance_m) || !(a.max_distance_m > 0.0)) {
      throw InvalidArgument("--max-distance " + std::to_string(a.max_distance_m) +
                            ": must be > 0 metres (or inf)");
    }
    request.max_distance_m = a.max_distance_m;
  }
  request.k = a.k;
  try {
    request.scale = parse_scale_mode(a.scale);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(std::string("--scale: ") + e.what());
  }
  request.record_history = a.history;
  add_set_options(a.settings, &request);
  std::vector<AlignRequest>& requests = plan.requests;

  WeightOptions& wopt = plan.wopt;
  wopt.covariance_norm = parse_covariance_norm(a.covariance_norm);
  Isometry3& T_displace = plan.T_displace;
  std::vector<double>& disp = plan.disp;
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
  // Every output checked before any work: a missing directory, a directory or a block device is
  // an error naming it; "-" (or /dev/stdout) writes there and sends this summary to stderr.
  std::vector<OutputOption> outputs{{"--json", a.json_path}};
  if (!a.ply_path.empty()) {
    if (names_standard_output(a.ply_path) && strategies.size() > 1) {
      throw InvalidArgument("--aligned-out '" + a.ply_path +
                            "': " + std::to_string(strategies.size()) +
                            " strategies write one map each; the standard output takes one");
    }
    // With several strategies the files are NAME_<strategy>.ply: none may be an input either.
    for (const Preset& s : strategies) {
      const std::string path = ply_path_for(a.ply_path, s.name, strategies.size() > 1);
      if (written_map_format(path, parse_map_format(a.aligned_format)) == MapFormat::kColmapText) {
        refuse_standard_output_folder("--aligned-out", path);
        refuse_output_over_input("--aligned-out", path, {a.source, a.target});
      } else {
        outputs.emplace_back("--aligned-out", path);
      }
      if (!a.json_path.empty() && !names_standard_output(path) && same_file(path, a.json_path)) {
        throw InvalidArgument("--aligned-out '" + path + "' and --json name the same file");
      }
    }
  }
  check_outputs(outputs, {a.source, a.target});

  if (!a.prior_sigma.empty()) {
    const std::vector<double> v =
        parse_number_list("--prior-sigma", a.prior_sigma, 2, "ROT_DEG,TRANS_M");
    const PriorSigma prior{v[0], v[1]};
    std::string why;
    if (!prior.is_valid(&why)) throw InvalidArgument("--prior-sigma " + a.prior_sigma + ": " + why);
    request.prior = prior;
  }
  if (!a.initial_guess.empty()) {
    const Isometry3 guess = read_transform(a.initial_guess);
    if (!is_rigid_transform(guess)) {
      throw InvalidArgument("--initial-guess " + a.initial_guess +
                            ": not a rigid transform (expected [R t; 0 0 0 1] with R orthonormal "
                            "and det R = +1)");
    }
    check_supported_translation("--initial-guess " + a.initial_guess, guess.translation());
    request.initial_guess = guess;
  }
  // The --set values are text: each strategy reads them by its own table; unknown keys, values
  // outside their bounds and a prior for a strategy that uses none are refused before any map is
  // read (AlignRequest::resolve).
  for (const Preset& p : strategies) {
    AlignRequest r = request;
    r.resolve(p);
    requests.push_back(r);
  }

  std::optional<Similarity3>& T_gt = plan.T_gt;
  if (a.ground_truth == "identity") {
    T_gt = Similarity3{};
  } else if (!a.ground_truth.empty()) {
    T_gt = read_similarity(a.ground_truth);
    check_supported_translation("--ground-truth " + a.ground_truth, T_gt->rigid.translation());
  }

  return plan;
}

/// The maps read, the runs made, and what their report needs.
struct AlignOutcome {
  Map source;
  Map target;
  Similarity3 S_displace;
  std::optional<Similarity3> T_true;  // truth for the displaced source
  std::vector<Run> runs;
  bool scale_columns = false;  // any run estimated the scale, or the truth has one
};

/// The human report on stdout: the table, the trust reasons and the transforms.
void print_table(const AlignArgs& a, const AlignOutcome& o) {
  const std::vector<Run>& runs = o.runs;
  const std::optional<Similarity3>& T_true = o.T_true;
  const bool scale_columns = o.scale_columns;
  // --- human table
  say("%-17s %3s %12s %12s %6s %-19s %9s", "strategy", "k", "init score", "final score", "iters",
      "termination", "time ms");
  if (T_true) say(" %8s %8s %6s", "rot deg", "trans m", "basin");
  if (scale_columns) say(" %10s %8s", "scale", "scale sd");
  if (scale_columns && T_true) say(" %9s", "scale err");
  say(" %6s\n", "trust");
  for (const Run& r : runs) {
    const RegistrationResult& g = r.summary.registration;
    say("%-17s %3s %12s %12s %6d %-19s %9.2f", r.preset.name.c_str(),
        r.preset.uses_k() ? std::to_string(a.k).c_str() : "-",
        fmt_score(g.initial_score_m2).c_str(), fmt_score(g.final_score_m2).c_str(), g.iterations,
        to_string(g.termination).c_str(), g.wall_time_s * 1e3);
    if (r.error) {
      say(" %8.3f %8.4f %6s", r.error->rotation_deg, r.error->translation_m,
          r.right_basin ? "yes" : "NO");
    }
    if (scale_columns) {
      say(" %10.6g %8.2g", r.summary.scale.scale, r.summary.scale.scale_sd);
      if (r.error) say(" %9.2e", r.error->scale_error);
    }
    say(" %6s\n", r.summary.verdict.trustworthy ? "yes" : "NO");
  }
  say("\nscores are PCL fitness scores (mean squared nearest-neighbour distance, m^2)\n");
  say("trust: the verdict without ground truth (docs/accuracy.md), by each strategy's trust "
      "judge (lmalign options NAME)\n");
  for (const Run& r : runs) {
    if (!r.summary.verdict.trustworthy) {
      say("  %-17s not trusted: %s\n", r.preset.name.c_str(), r.summary.verdict.reason.c_str());
    } else if (r.summary.source_left_out + r.summary.target_left_out > 0 ||
               r.summary.covariances_assumed) {
      say("  %-17s trusted: %s\n", r.preset.name.c_str(), r.summary.verdict.reason.c_str());
    }
  }
  say("\nestimated T_target_source (p_target = T * p_source): x y z [m], roll pitch yaw [deg]\n");
  for (const Run& r : runs) {
    const auto v = xyz_rpy_deg_from_pose(r.summary.registration.T_target_source);
    say("  %-17s %9.4f %9.4f %9.4f   %9.3f %9.3f %9.3f\n", r.preset.name.c_str(), v[0], v[1], v[2],
        v[3], v[4], v[5]);
  }
  if (T_true) {
    const auto v = xyz_rpy_deg_from_pose(T_true->rigid);
    say("  %-17s %9.4f %9.4f %9.4f   %9.3f %9.3f %9.3f\n", "(truth)", v[0], v[1], v[2], v[3], v[4],
        v[5]);
  }
  if (scale_columns) {
    say("scale: target units per source unit (p_target = scale * R * p_source + t); the rows "
        "above are R and t\n");
  }
}

/// The aligned source maps (--aligned-out) and the JSON (--json), each written atomically.
void write_outputs(const AlignArgs& a, const AlignPlan& plan, const AlignOutcome& o) {
  const std::vector<Run>& runs = o.runs;
  const std::optional<Similarity3>& T_true = o.T_true;
  const bool scale_columns = o.scale_columns;
  const Map& source = o.source;
  const Map& target = o.target;
  const Isometry3& T_displace = plan.T_displace;
  const Similarity3& S_displace = o.S_displace;
  const std::vector<double>& disp = plan.disp;
  // --- machine-readable outputs
  if (!a.ply_path.empty()) {
    for (const Run& r : runs) {
      const std::string path = ply_path_for(a.ply_path, r.preset.name, runs.size() > 1);
      // The writer by extension: .ply (with covariances), a folder (COLMAP text), else ours.
      write_any_map(
          path,
          r.summary.scale.free
              ? transform_map(source, r.summary.similarity() * S_displace)
              : transform_map(source, r.summary.registration.T_target_source * T_displace),
          parse_map_format(a.aligned_format));
      say("aligned source (%s) written to %s\n", r.preset.name.c_str(), output_name(path).c_str());
    }
  }
  if (!a.json_path.empty()) {
    nlohmann::json j;
    j["source"] = a.source;
    j["target"] = a.target;
    j["source_landmarks"] = source.landmarks.size();
    j["target_landmarks"] = target.landmarks.size();
    j["source_scale"] = map_scale_name(source.header.scale);
    j["target_scale"] = map_scale_name(target.header.scale);
    j["source_covariance_assumed"] = source.header.covariance_assumed;
    j["target_covariance_assumed"] = target.header.covariance_assumed;
    j["frames"] =
        "T_target_source maps displaced-source coordinates to target coordinates (metres)";
    if (!disp.empty()) {
      j["displacement"] = {{"x_m", disp[0]},      {"y_m", disp[1]},       {"z_m", disp[2]},
                           {"roll_deg", disp[3]}, {"pitch_deg", disp[4]}, {"yaw_deg", disp[5]}};
    }
    j["k"] = a.k;
    j["max_iterations"] = a.max_iterations_given ? nlohmann::json(a.max_iterations) : nullptr;
    j["max_correspondence_distance_m"] =
        a.max_distance_given ? json_number(a.max_distance_m) : nlohmann::json();
    j["settings"] = a.settings;
    j["covariance_norm"] = a.covariance_norm;
    if (T_true) {
      j["ground_truth"] = a.ground_truth;
      j["T_target_source_true"] = json_matrix(T_true->rigid);
      if (scale_columns) {
        const Mat4 S = T_true->matrix();
        nlohmann::json m = nlohmann::json::array();
        for (int i = 0; i < 4; ++i) m.push_back({S(i, 0), S(i, 1), S(i, 2), S(i, 3)});
        j["S_target_source_true"] = m;
        j["scale_true"] = T_true->scale;
      }
      j["success_rotation_deg"] = a.success_rotation_deg;
      j["success_translation_m"] = a.success_translation_m;
    }
    nlohmann::json results = nlohmann::json::array();
    for (const Run& r : runs) {
      // The one serialisation of a result (to_json(Summary)), plus what only the CLI knows.
      nlohmann::json e = nlohmann::json::parse(to_json(r.summary));
      e["k"] = r.preset.uses_k() ? nlohmann::json(a.k) : nlohmann::json();
      if (r.error) {
        e["rotation_error_deg"] = r.error->rotation_deg;
        e["translation_error_m"] = r.error->translation_m;
        if (scale_columns) e["scale_error"] = r.error->scale_error;
        e["right_basin"] = r.right_basin;
      }
      results.push_back(e);
    }
    j["results"] = results;
    // Paths need not be UTF-8 (JSON text must be): invalid bytes become U+FFFD.
    write_output(a.json_path, [&](std::ostream& out) {
      out << j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) << "\n";
    });
    say("JSON written to %s\n", output_name(a.json_path).c_str());
  }
}

int run_align(const AlignArgs& a) {
  // --- validate everything before any work, so bad input fails fast with one line.
  AlignPlan plan = plan_align(a);
  const std::vector<Preset>& strategies = plan.strategies;
  const std::vector<double>& disp = plan.disp;
  const Isometry3& T_displace = plan.T_displace;
  const std::optional<Similarity3>& T_gt = plan.T_gt;
  AlignOutcome o;
  MapReadOptions ropt;
  ropt.min_observations = a.min_observations;
  AnyMapReadOptions any(ropt, parse_map_format(a.format));
  if (!a.image_size.empty()) any.image_size_px = parse_image_size(a.image_size);
  MapReadStats source_stats, target_stats;
  o.source = read_any_map(a.source, any, &source_stats);
  o.target = read_any_map(a.target, any, &target_stats);
  for (const auto& [path, stats] :
       {std::pair{&a.source, &source_stats}, {&a.target, &target_stats}}) {
    if (stats->camera_centres_left_out == 0) continue;
    say("%s: left out %zu vertices that are OpenMVG's camera centres, not landmarks (%s)\n",
        path->c_str(), stats->camera_centres_left_out, stats->camera_centres_rule.c_str());
  }
  const Map& source = o.source;
  const Map& target = o.target;
  // An aligned source its writer would refuse fails now, not after the alignment.
  for (const Preset& s : strategies) {
    if (a.ply_path.empty()) break;
    check_map_writable(ply_path_for(a.ply_path, s.name, strategies.size() > 1), source,
                       parse_map_format(a.aligned_format));
  }
  if (source.landmarks.empty())
    throw InvalidArgument("source map '" + a.source +
                          "' has no landmarks (after the --min-observations filter)");
  if (target.landmarks.empty())
    throw InvalidArgument("target map '" + a.target +
                          "' has no landmarks (after the --min-observations filter)");

  // The paper displaces the source about the world origin, then starts ICP at the identity. Its
  // covariances, up axis and viewing directions move with it (C' = R C R^T).
  const SourceLandmarks src = SourceLandmarks::from_map(source).moved(T_displace);
  // Truth for the displaced source. Errors are measured on the recovered map-to-map transform
  // T_est * T_displace against T_gt, so they do not depend on the artificial displacement.
  o.S_displace = Similarity3{1.0, T_displace};
  const Similarity3& S_displace = o.S_displace;
  if (T_gt) o.T_true = *T_gt * S_displace.inverse();
  const std::optional<Similarity3>& T_true = o.T_true;

  const PreparedTarget prepared(target, plan.wopt);
  for (AlignRequest& r : plan.requests) r.describe_maps(source.header, target.header);

  say("lmalign align: source %s (%zu landmarks) -> target %s (%zu landmarks)\n", a.source.c_str(),
      source.landmarks.size(), a.target.c_str(), target.landmarks.size());
  for (const auto& [role, map] : {std::pair<const char*, const Map*>{"source", &source},
                                  std::pair<const char*, const Map*>{"target", &target}}) {
    if (map->header.covariance_assumed) {
      say("%s: covariances assumed (the map stores none): isotropic, half the median distance to "
          "the 6 nearest landmarks\n",
          role);
    }
  }
  if (!disp.empty()) {
    say("source displaced about the world origin by x=%g y=%g z=%g m, roll=%g pitch=%g yaw=%g "
        "deg\n",
        disp[0], disp[1], disp[2], disp[3], disp[4], disp[5]);
  }
  say("k=%d (weighted kNN), covariance norm=%s; limits: %s; settings: %s\n", a.k,
      a.covariance_norm.c_str(),
      a.max_iterations_given || a.max_distance_given
          ? ("max iterations " + (a.max_iterations_given ? std::to_string(a.max_iterations) : "-") +
             ", max distance " +
             (a.max_distance_given ? message_number(a.max_distance_m) + " m" : "-"))
                .c_str()
          : "the strategies' own",
      a.settings.empty() ? "the strategies' own" : join(a.settings).c_str());
  if (T_true) {
    say("ground truth: %s; right basin = rotation error < %g deg and translation error < %g m\n",
        a.ground_truth.c_str(), a.success_rotation_deg, a.success_translation_m);
  }
  say("\n");

  std::vector<Run>& runs = o.runs;
  for (std::size_t i = 0; i < strategies.size(); ++i) {
    Run run;
    run.preset = strategies[i];
    run.summary = align(strategies[i], src.view(), prepared, plan.requests[i]);
    if (T_true) {
      run.error = similarity_error(run.summary.similarity() * S_displace, *T_gt);
      run.right_basin = run.error->rotation_deg < a.success_rotation_deg &&
                        run.error->translation_m < a.success_translation_m;
    }
    runs.push_back(std::move(run));
  }

  // The scale's columns when any run estimated it or the truth has one.
  o.scale_columns = T_gt && T_gt->scale != 1.0;
  for (const Run& r : runs) o.scale_columns = o.scale_columns || r.summary.scale.free;

  print_table(a, o);
  write_outputs(a, plan, o);
  return 0;
}

std::string strategy_help() {
  std::string s;
  for (const Preset& p : presets()) {
    s += "\n  " + p.name + (p.recommended ? " (the default)" : "") + ": " + p.doc;
  }
  return s;
}

}  // namespace

CommandRunner add_align_command(CLI::App& root) {
  auto args = std::make_shared<AlignArgs>();
  CLI::App* cmd = root.add_subcommand(
      "align",
      "Align SOURCE onto TARGET (map files, docs/map-format.md) with one or more strategies\n"
      "(by default the recommended one: no initial guess needed). Prints one row per strategy.\n"
      "Result: T_target_source, with p_target = T_target_source * p_source (metres).");
  cmd->add_option("SOURCE", args->source, "source map file (moved onto the target)")->required();
  cmd->add_option("TARGET", args->target, "target map file (fixed)")->required();
  std::string paper;
  for (const std::string& n : preset_names("paper")) paper += n + ", ";
  cmd->add_option("--weight", args->weight,
                  "one of the paper's strategies (" + paper + "or all four); also by the names " +
                      "none (base) and mean_distance (distance)");
  cmd->add_option("--strategy", args->strategy,
                  "comma-separated strategies: names, preset files NAME.yaml, or the groups "
                  "'paper', 'lmalign' and 'all'. Each is a preset of the registration engine "
                  "(lmalign options NAME prints its stages and settings):" +
                      strategy_help());
  cmd->add_option("--k", args->k, "neighbourhood size of the weighted kNN strategies, [1, 4096]")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  CLI::Option* max_iterations =
      cmd->add_option("--max-iterations", args->max_iterations,
                      "iteration budget, >= 1: replaces each strategy's own (the paper's: 150; "
                      "the adaptive default's: per refinement)")
          ->check(CLI::PositiveNumber);
  CLI::Option* max_distance =
      cmd->add_option("--max-distance", args->max_distance_m,
                      "maximum correspondence distance, metres: the paper's strategies' (unlimited "
                      "by default, as the paper), a cap on the shrinking schedules'; the "
                      "covariance-gated default has none")
          ->check(CLI::PositiveNumber);
  cmd->add_option("--set", args->settings,
                  "KEY=VALUE: a setting of the strategies (repeatable; lmalign options NAME lists "
                  "them with their bounds); it wins over --k and the limits");
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
      "true T_target_source of the undisplaced source: 'identity' or a 4x4 matrix file, rigid "
      "[R t; 0 1] or a similarity [sR t; 0 1]; adds rotation (deg), translation (m) and, with "
      "a scale, relative scale errors");
  cmd->add_option("--success-rotation-deg", args->success_rotation_deg,
                  "right-basin threshold on the rotation error, degrees")
      ->capture_default_str();
  cmd->add_option("--success-translation-m", args->success_translation_m,
                  "right-basin threshold on the translation error, metres")
      ->capture_default_str();
  cmd->add_option("--json", args->json_path,
                  "also write the results as JSON to this file; '-' writes it to the standard "
                  "output (this table then goes to the standard error). A symlink is written "
                  "through, a FIFO or device in place; its directory must exist");
  cmd->add_option("--aligned-out", args->ply_path,
                  "write the aligned source map (target frame): FILE.ply as PLY with "
                  "covariances, a folder as COLMAP text, any other name as an lmalign map; with "
                  "several strategies, one each: NAME_<strategy>.ply; '-' (one strategy): the "
                  "standard output");
  cmd->add_option(
         "--aligned-format", args->aligned_format,
         "writer of --aligned-out: auto (by its form, as above), " + written_map_format_names())
      ->capture_default_str();
  cmd->add_option("--format", args->format,
                  "reader of SOURCE and TARGET: " + map_format_names() +
                      " (auto: by content; docs/map-format.md)");
  cmd->add_option(
      "--image-size", args->image_size,
      "Bundler maps: the image size W,H in pixels, for outputs that store pixels from the "
      "top-left corner (Bundler's are centred; reading needs no size)");
  cmd->add_option("--initial-guess", args->initial_guess,
                  "a first estimate of T_target_source (of the displaced source, if --displace): "
                  "a 4x4 matrix file (p_target = T * p_source, metres). Every strategy starts "
                  "from it; a searching one adds it to its hypotheses, or bounds its search "
                  "around it with --prior-sigma");
  cmd->add_option(
      "--prior-sigma", args->prior_sigma,
      "ROT_DEG,TRANS_M: standard deviations of --initial-guess (identity if none), "
      "degrees and metres, each > 0: a hint, checked against the maps. The default runs its "
      "global search too; a pose outside 3 sigma that scores as well makes the answer untrusted, "
      "and an answer outside that window is never trusted (--set init.prior_check=off: the "
      "search within 3 sigma alone; docs/accuracy.md, \"Priors are hints\")");
  cmd->add_option("--scale", args->scale,
                  "auto, free or fixed: whether the scale is estimated too (a similarity, "
                  "p_target = scale * R * p_source + t, for maps without a common metric scale; "
                  "docs/scale.md). auto: free when either map's header says its scale is not "
                  "metric, fixed otherwise")
      ->capture_default_str();
  cmd->add_flag("--history", args->history,
                "record per-iteration correspondences, MSE and score (into --json)");
  return [args, max_iterations, max_distance]() {
    args->max_iterations_given = max_iterations->count() > 0;
    args->max_distance_given = max_distance->count() > 0;
    return run_align(*args);
  };
}

}  // namespace lmalign::cli
