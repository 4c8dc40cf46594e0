// `lmalign merge`: merge many mini-maps into one frame (docs/merge.md).
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "commands.hpp"
#include "lmalign/core/error.hpp"
#include "lmalign/core/supported_range.hpp"
#include "lmalign/io/output_file.hpp"
#include "lmalign/merge/evaluation.hpp"
#include "lmalign/merge/folds.hpp"
#include "lmalign/merge/merge.hpp"
#include "lmalign/merge/output.hpp"
#include "lmalign/registration/presets.hpp"

namespace lmalign::cli {

namespace {

namespace fs = std::filesystem;

struct MergeArgs {
  std::string manifest;
  std::string out_dir;
  std::string ground_truth;
  long long max_pairs = 0;
  long long candidates_per_map = static_cast<long long>(CandidateOptions{}.keep_per_map);
  long long verify_per_map = static_cast<long long>(CandidateOptions{}.verify_per_map);
  bool resume = false;
  int threads = 0;
  std::string thresholds = "5,0.1";
  bool no_fuse = false;
  std::string dask_scheduler;
  bool no_plots = false;
  bool plan_only = false;
  std::string scale = "auto";            // --scale auto|free|fixed
  std::string overlap_check = "repair";  // --overlap-check repair|check|off
  std::vector<std::string> settings;     // --set KEY=VALUE, every edge
};

/// --set KEY=VALUE, checked against the default's settings table now (one line naming the key,
/// not one error per edge later), as EdgeOptions::settings.
std::vector<std::pair<std::string, SettingValue>> edge_settings(
    const std::vector<std::string>& assignments) {
  AlignRequest request;
  add_set_options(assignments, &request);
  try {
    request.resolve(recommended_preset());  // every key and value read by its row
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(std::string("--set: ") + e.what());
  }
  return request.settings;
}

/// --dask-scheduler: the pairs run on a Dask cluster through the Python package; this process
/// becomes `python3 -c <bootstrap> ARGS` (lmalign.merge_cli, docs/merge.md "Scale-out on Dask").
/// Returns only if the interpreter cannot be started.
int exec_python_merge(const MergeArgs& a) {
  const char* env = std::getenv("LMALIGN_PYTHON");
  const std::string python = env != nullptr && *env != '\0' ? env : LMALIGN_PYTHON;
  const std::string bootstrap =
      "import sys\n"
      "try:\n"
      "    from lmalign.merge_cli import main\n"
      "except ImportError as e:\n"
      "    sys.exit('lmalign merge --dask-scheduler: needs the Python package lmalign (make "
      "install, or PYTHONPATH=<build>/python) and python3-distributed: %s' % e)\n"
      "sys.exit(main(sys.argv[1:]))\n";
  std::vector<std::string> args{python,
                                "-c",
                                bootstrap,
                                a.manifest,
                                "-o",
                                a.out_dir,
                                "--thresholds",
                                a.thresholds,
                                "--max-pairs",
                                std::to_string(a.max_pairs),
                                "--threads",
                                std::to_string(a.threads),
                                "--scale",
                                a.scale,
                                "--overlap-check",
                                a.overlap_check,
                                "--dask-scheduler",
                                a.dask_scheduler};
  if (!a.ground_truth.empty()) {
    args.push_back("--ground-truth");
    args.push_back(a.ground_truth);
  }
  if (a.resume) args.push_back("--resume");
  if (a.no_fuse) args.push_back("--no-fuse");
  if (a.no_plots) args.push_back("--no-plots");
  std::vector<char*> argv;
  for (std::string& s : args) argv.push_back(s.data());
  argv.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  execvp(argv[0], argv.data());
  std::fprintf(stderr,
               "lmalign merge --dask-scheduler: cannot run the Python interpreter '%s' (%s); set "
               "LMALIGN_PYTHON, or use lmalign.merge(..., dask_client=...) from Python\n",
               python.c_str(), std::strerror(errno));
  return 2;
}

// --plan-only: the candidate pairs (candidates.hpp), written to OUTDIR/candidates.csv, no
// alignment (to inspect a large merge before running it, or to measure the pre-filter).
int plan_only(const std::vector<Map>& maps, const std::vector<std::string>& names,
              const std::vector<std::optional<MapPrior>>& priors, const MergeOptions& options,
              const std::string& out_dir) {
  std::vector<MapSummary> summaries;
  for (std::size_t i = 0; i < maps.size(); ++i) {
    summaries.push_back(summarise_map(maps[i], options.candidates, i + 1));  // as run_merge
  }
  const std::vector<CandidatePair> pairs = plan_candidates(summaries, priors, options.candidates);
  create_output_folder(out_dir);
  const std::string path = (fs::path(out_dir) / "candidates.csv").string();
  write_output(path, [&](std::ostream& os) {
    os << "source,target,rank,prior,verified_matches\n";
    for (const CandidatePair& c : pairs) {
      os << names[c.source] << "," << names[c.target] << "," << c.rank << "," << (c.prior ? 1 : 0)
         << "," << c.verified_matches << "\n";
    }
  });
  say("%zu maps: %zu candidate pairs; wrote %s\n", maps.size(), pairs.size(), path.c_str());
  return 0;
}

// The PNGs of docs/merge.md ("Plots"), drawn by scripts/plot_merge.py (matplotlib), as
// `lmalign experiment` does; without the script or matplotlib: a warning, no plots.
bool plot_merge(const std::string& out_dir) {
  const std::string script = find_script("plot_merge.py", "LMALIGN_MERGE_PLOT_SCRIPT");
  std::error_code ec;
  if (script.empty() || !fs::exists(script, ec)) {
    std::fprintf(stderr,
                 "lmalign merge: warning: no plots: plot_merge.py is neither installed beside "
                 "this executable (../share/lmalign/scripts) nor in its source checkout (set "
                 "LMALIGN_MERGE_PLOT_SCRIPT); the outputs are complete without them\n");
    return false;
  }
  const int rc = draw_plots(script, {out_dir, "--quiet"}, out_dir);
  if (rc != 0) {
    std::fprintf(stderr,
                 "lmalign merge: warning: no plots (%s exited with %d; it needs matplotlib and "
                 "numpy; set LMALIGN_PYTHON to choose the interpreter); the outputs are complete "
                 "without them\n",
                 script.c_str(), rc);
    return false;
  }
  return true;
}

// The merge's summary on the standard output: edges, parts, scales, rejected edges.
void print_merge_summary(const std::vector<Map>& maps, const std::vector<std::string>& names,
                         const MergeRun& run, double contradiction_ratio) {
  std::size_t used = 0, rejected = 0, trusted = 0;
  for (std::size_t e = 0; e < run.edges.size(); ++e) {
    trusted += run.edges[e].trusted ? 1 : 0;
    used += run.result.edges[e].used ? 1 : 0;
    rejected += run.result.edges[e].rejected ? 1 : 0;
  }
  say("merged %zu maps: %zu candidate pairs (%zu reused), %zu trusted, %zu in the graph, %zu "
      "rejected by it; %zu component(s); final chi2 %.3f (edge covariance scale %.3g)\n",
      maps.size(), run.candidates.size(), run.edges_reused, trusted, used, rejected,
      run.result.num_components, run.result.final_chi2, run.result.edge_covariance_scale);
  say("time: edges %.2f s, graph %.2f s, overlap check %.2f s\n", run.seconds_edges,
      run.seconds_graph, run.seconds_check);
  if (!run.repair.dropped.empty() || run.repair.rounds > 0) {
    say("overlap repair: %zu contradicted pair(s) before; %zu edge(s) dropped in %d round(s) "
        "(%d trial solve(s))\n",
        run.repair.contradicted_before, run.repair.dropped.size(), run.repair.rounds,
        run.repair.trials);
  }
  if (run.overlaps.ran) {
    const std::size_t bad = run.overlaps.num_contradicted();
    say("overlap check: %zu pair(s) of maps placed overlapping judged, %zu contradicted "
        "(agreement below %.2f of the kept edges' median %.2f)\n",
        run.overlaps.pairs.size(), bad, contradiction_ratio, run.overlaps.reference_agreement);
    for (std::size_t c = 0; c < run.overlaps.contradicted_per_component.size(); ++c) {
      const std::size_t k = run.overlaps.contradicted_per_component[c];
      if (k == 0) continue;
      say("component %zu is not consistent: %zu pair(s) of its maps overlap where their "
          "landmarks disagree, so an edge in it puts a map in the wrong place "
          "(overlap_check.csv)\n",
          c, k);
    }
  }
  for (std::size_t i = 0; i < maps.size(); ++i) {
    const MapPose& p = run.result.maps[i];
    if (!p.scale_free && p.scale == 1.0) continue;
    say("scale of %s: %.6g world units per map unit (sd %.2g)%s\n", names[i].c_str(), p.scale,
        p.scale_sd, p.scale_free ? "" : " (held)");
  }
  for (std::size_t e = 0; e < run.edges.size(); ++e) {
    const EdgeReport& r = run.result.edges[e];
    if (!r.rejected) continue;
    if (r.reject_reason.empty()) {
      say("rejected edge: %s -> %s (chi2 %.1f after optimisation)\n",
          names[run.edges[e].source].c_str(), names[run.edges[e].target].c_str(), r.chi2);
    } else {
      say("rejected edge: %s -> %s (%s)\n", names[run.edges[e].source].c_str(),
          names[run.edges[e].target].c_str(), r.reject_reason.c_str());
    }
  }
  const std::vector<MapNote> notes = map_notes(maps, run.edges, run.result);
  for (std::size_t i = 0; i < maps.size(); ++i) {
    if (notes[i].same_landmarks_as) {
      say("same landmarks: %s and %s (one map listed twice, or one map in two files)\n",
          names[*notes[i].same_landmarks_as].c_str(), names[i].c_str());
    }
  }
  for (std::size_t i = 0; i < maps.size(); ++i) {
    if (!notes[i].alone.empty()) say("alone: %s: %s\n", names[i].c_str(), notes[i].alone.c_str());
  }
  // Folds it could not rule out (merge/folds.hpp): part of a component placed twice over, by a
  // look-alike place or a wrong prior.
  for (const SuspectedFold& f : suspected_folds(maps, run.edges, run.result)) {
    std::string fold_maps;
    for (const std::size_t i : f.maps) fold_maps += (fold_maps.empty() ? "" : ", ") + names[i];
    say("suspected fold: %zu trusted edges that the graph rejected agree on moving part of "
        "component %zu by %.3g m / %.3g deg (maps %s): a look-alike place, or a wrong prior, may "
        "have put those maps in the wrong place; see suspected_folds in summary.json "
        "(docs/merge.md)\n",
        f.edges.size(), run.result.maps[f.maps.front()].component, f.motion_m, f.motion_deg,
        fold_maps.c_str());
  }
}

// The merge against the ground truth (merge --ground-truth), map by map.
void print_ground_truth(const std::vector<Map>& maps, const std::vector<std::string>& names,
                        const MergeRun& run, const std::vector<Similarity3>& truth,
                        const std::vector<double>& thr) {
  GroundTruthThresholds t;
  t.rotation_deg = thr[0];
  t.translation_m = thr[1];
  const MergeEvaluation ev = evaluate_merge(run.result, run.edges, truth, t);
  say("ground truth (within %g deg / %g m): %zu part(s), the largest of %zu map(s); the kept "
      "edges join the maps into %zu piece(s)\n",
      t.rotation_deg, t.translation_m, ev.num_parts, ev.largest_part, ev.num_edge_parts);
  for (std::size_t i = 0; i < maps.size(); ++i) {
    const MapError& e = ev.maps[i];
    if (std::isnan(e.rotation_deg)) {
      say("  %-20s component %zu  not placed: alone in its part\n", names[i].c_str(),
          run.result.maps[i].component);
      continue;
    }
    say("  %-20s component %zu  rotation %.3f deg  translation %.4f m  scale error %.2e%s\n",
        names[i].c_str(), run.result.maps[i].component, e.rotation_deg, e.translation_m,
        e.scale_error,
        !e.placed  ? "  (not placed: in a part apart from the others)"
        : e.within ? ""
                   : "  (outside)");
  }
  const std::size_t pairs = maps.size() * (maps.size() - 1) / 2;
  char pair_text[96] = "not computed (over 2000 maps)";
  if (!std::isnan(ev.pair_fraction_within)) {
    std::snprintf(pair_text, sizeof pair_text, "%zu of %zu (%.1f%%)", ev.pairs_within, pairs,
                  100.0 * ev.pair_fraction_within);
  }
  say("  within: %.1f%% of the maps (placed: %zu of %zu); pairs within: %s; edges kept %zu, "
      "false kept %zu, precision %.3f, recall %.3f; largest scale error: maps %.2e, pairs "
      "%.2e\n",
      100.0 * ev.fraction_within, ev.placed, maps.size(), pair_text, ev.kept_edges,
      ev.false_kept_edges, ev.edge_precision, ev.edge_recall, ev.max_scale_error,
      ev.max_pair_scale_error);
}

// The folder -o, checked before anything is read: not a file, no edges of an earlier run
// without --resume, never over an input.
void check_merge_output(const MergeArgs& a, const std::vector<std::string>& inputs) {
  refuse_standard_output_folder("-o", a.out_dir);
  std::error_code ec;
  if (fs::exists(a.out_dir, ec) && !fs::is_directory(a.out_dir, ec)) {
    throw InvalidArgument("-o " + a.out_dir + ": exists and is not a folder");
  }
  if (!a.resume && fs::exists(fs::path(a.out_dir) / "edges", ec) &&
      !fs::is_empty(fs::path(a.out_dir) / "edges", ec)) {
    throw InvalidArgument("-o " + a.out_dir +
                          ": holds edges/ of an earlier run; pass --resume to reuse them, or "
                          "choose another folder");
  }
  for (const std::string& in : inputs) refuse_output_over_input("-o", a.out_dir, {in});
}

// The supported range (core/supported_range.hpp): such landmarks are left out of every edge (each
// edge's trust reason counts them) and of the merged map (summary.json); said once per map.
void warn_far_landmarks(const std::vector<Map>& maps, const std::vector<std::string>& names) {
  for (std::size_t i = 0; i < maps.size(); ++i) {
    std::size_t far = 0;
    for (const Landmark& l : maps[i].landmarks) far += within_supported_range(l.p_world) ? 0 : 1;
    if (far > 0) {
      std::fprintf(stderr,
                   "lmalign merge: map '%s': %zu landmark(s) beyond the supported range "
                   "(|coordinate| > %g m) left out\n",
                   names[i].c_str(), far, kMaxCoordinateM);
    }
  }
}

int run_merge_command(const MergeArgs& a) {
  if (!a.dask_scheduler.empty() && !a.settings.empty()) {
    throw InvalidArgument(
        "--set is not handed over to a Dask cluster yet: run the merge without --dask-scheduler");
  }
  const MergeArgs defaults;
  if (!a.dask_scheduler.empty() && (a.candidates_per_map != defaults.candidates_per_map ||
                                    a.verify_per_map != defaults.verify_per_map)) {
    throw InvalidArgument(
        "--candidates-per-map and --verify-per-map are not handed over to a Dask cluster yet: run "
        "the merge without --dask-scheduler");
  }
  if (!a.dask_scheduler.empty()) return exec_python_merge(a);
  const std::vector<std::pair<std::string, SettingValue>> settings = edge_settings(a.settings);
  if (a.max_pairs < 0) throw InvalidArgument("--max-pairs must be >= 0 (0 = no limit)");
  if (a.candidates_per_map < 1) throw InvalidArgument("--candidates-per-map must be >= 1");
  if (a.verify_per_map < 0 || a.verify_per_map > 100000) {
    throw InvalidArgument("--verify-per-map must be in [0, 100000] (0 = no verification)");
  }
  if (a.threads < 0) throw InvalidArgument("--threads must be >= 0 (0 = all)");
  const std::vector<double> thr =
      parse_number_list("--thresholds", a.thresholds, 2, "ROT_DEG,TRANS_M, e.g. 5,0.1");
  const ScaleMode scale_mode = parse_scale_mode(a.scale);
  const Manifest manifest = read_manifest(a.manifest);
  std::vector<std::string> names, sessions;
  std::vector<std::optional<MapPrior>> priors;
  std::vector<std::string> inputs{a.manifest};
  for (const ManifestEntry& e : manifest.maps) {
    names.push_back(e.name);
    sessions.push_back(e.session);
    priors.push_back(e.prior);
    inputs.push_back(e.path);
  }
  check_merge_output(a, inputs);
  std::vector<Similarity3> truth;
  std::fprintf(stderr, "lmalign merge: reading %zu maps\n", manifest.maps.size());
  const std::vector<Map> maps = load_manifest_maps(manifest);
  warn_far_landmarks(maps, names);
  if (!a.ground_truth.empty()) {
    if (a.ground_truth == "identity") {
      truth.assign(maps.size(), Similarity3{});
    } else {
      truth = read_ground_truth_similarities(a.ground_truth, names);
    }
  }
  MergeOptions options;
  options.candidates.max_pairs = static_cast<std::size_t>(a.max_pairs);
  options.candidates.keep_per_map = static_cast<std::size_t>(a.candidates_per_map);
  options.candidates.verify_per_map = static_cast<std::size_t>(a.verify_per_map);
  options.threads = a.threads;
  options.edges.scale = scale_mode;
  options.edges.settings = settings;
  options.edge_cache_dir = (fs::path(a.out_dir) / "edges").string();
  set_overlap_check_mode(a.overlap_check, &options);
  if (a.plan_only) return plan_only(maps, names, priors, options, a.out_dir);
  const StopSignals signals;
  stop_flag().store(false);
  auto progress = [](const std::string& stage, std::size_t done, std::size_t total) {
    std::fprintf(stderr, "\rlmalign merge: %s %zu/%zu", stage.c_str(), done, total);
    if (done == total) std::fprintf(stderr, "\n");
  };
  const MergeRun run = run_merge(maps, names, priors, options, progress, &stop_flag());
  if (run.cancelled) {
    std::fprintf(stderr,
                 "\nlmalign merge: interrupted; %zu of %zu edges are kept in %s; rerun with "
                 "--resume to continue\n",
                 run.edges.size(), run.candidates.size(), options.edge_cache_dir.c_str());
    return 130;
  }
  MergeOutputOptions oo;
  oo.fuse_landmarks = !a.no_fuse;
  write_merge_outputs(a.out_dir, names, sessions, maps, run.edges, run.result, oo, &run.overlaps);
  print_merge_summary(maps, names, run, options.overlaps.contradiction_ratio);
  if (!truth.empty()) print_ground_truth(maps, names, run, truth, thr);
  const bool plotted = !a.no_plots && plot_merge(a.out_dir);
  say("wrote: %s (poses.yaml, poses.json, edges.csv, summary.json, overlap_check.csv, merged "
      "map%s, edges/%s)\n",
      a.out_dir.c_str(), run.result.num_components > 1 ? "s per component" : "",
      plotted ? ", merge_graph.png, merged_landmarks.png" : "");
  return 0;
}

}  // namespace

CommandRunner add_merge_command(CLI::App& root) {
  auto args = std::make_shared<MergeArgs>();
  CLI::App* cmd = root.add_subcommand(
      "merge",
      "Merge many mini-maps into one frame (docs/merge.md): candidate pairs (priors, else all\n"
      "pairs or a pre-filter), one adaptive alignment per pair (kept when trusted, with its 6x6\n"
      "covariance; a similarity with its scale where a map has no metric scale, --scale), a\n"
      "robust pose graph (Ceres; SE(3), plus a log scale per map without metric scale) that\n"
      "rejects edges inconsistent with the rest, and the outputs in OUTDIR: poses.yaml/json\n"
      "(T_world_map and scale: p_world = scale * R * p_map + t, metres, scale = world units per\n"
      "map unit, 1 for a metric map; 6x6 covariance of xi = (rho m, phi rad), left perturbation\n"
      "in the world frame), edges.csv, summary.json, merged_map.txt. A graph in several parts is\n"
      "reported part by part, each in its own frame (its first map's, or its priors'). Finished\n"
      "edges are kept in OUTDIR/edges/ as they finish; Ctrl-C stops after the alignments in\n"
      "flight, and --resume reuses them.");
  cmd->add_option("MANIFEST", args->manifest,
                  "YAML manifest: maps with name, path, optional format, session, T_world_map "
                  "prior (4x4) with prior_sigma [rot_deg, trans_m] or prior_covariance (6x6)")
      ->required();
  cmd->add_option("-o,--output", args->out_dir, "Output folder (created)")->required();
  cmd->add_option("--ground-truth", args->ground_truth,
                  "YAML 'maps: {name: 4x4 T_world_map (m)}' (a similarity [sR t; 0 0 0 1] for a "
                  "map without metric scale, s = world units per map unit), or 'identity' (all "
                  "maps share the true frame): per-map errors (rotation, translation, relative "
                  "scale |s_est/s_true - 1|), edge precision and recall");
  cmd->add_option("--thresholds", args->thresholds,
                  "Ground truth: ROT_DEG,TRANS_M within which a map or edge counts as right "
                  "(5,0.1 indoors; 5,1 outdoors)")
      ->capture_default_str();
  cmd->add_option("--max-pairs", args->max_pairs, "At most this many candidate pairs (0 = all)")
      ->capture_default_str();
  cmd->add_option("--candidates-per-map", args->candidates_per_map,
                  "Without priors, beyond 12 maps: each map's K most similar maps by retrieval "
                  "(a bag of words over its landmarks' neighbourhood descriptors) are its "
                  "candidates (docs/merge.md, \"Candidates\")")
      ->capture_default_str();
  cmd->add_option("--verify-per-map", args->verify_per_map,
                  "Without priors, beyond 12 maps: each map's N most similar maps are verified "
                  "by the correspondence search (the largest clique of consistent landmark "
                  "matches, about 4 ms a pair of 500-landmark maps; the default verifies every "
                  "pair of up to 201 maps) and the K of --candidates-per-map are the best "
                  "verified; 0 = retrieval alone")
      ->capture_default_str();
  cmd->add_option("--scale", args->scale,
                  "auto: a map without metric scale (its header: COLMAP, Bundler, monocular "
                  "stella_vslam) gets a scale of its own, s = world units per map unit, and its "
                  "pairs are aligned as similarities (Sim(3), docs/scale.md); maps with metric "
                  "scale and manifest priors hold the scale. free: every pair's scale is "
                  "estimated too. fixed: rigid (SE(3)) edges and poses for every map")
      ->check(CLI::IsMember({"auto", "free", "fixed"}))
      ->capture_default_str();
  cmd->add_option("--overlap-check", args->overlap_check,
                  "After the pose graph, pairs of maps it places overlapping are compared "
                  "landmark by landmark (overlap_check.csv): repair: a part they contradict is "
                  "repaired by dropping the edges that fold it; check: reported only; off: "
                  "neither (docs/merge.md, \"Maps the graph puts on top of each other\")")
      ->check(CLI::IsMember({"repair", "check", "off"}))
      ->capture_default_str();
  cmd->add_option("--set", args->settings,
                  "KEY=VALUE: a setting of every pair's alignment (repeatable; lmalign options "
                  "adaptive lists them with their bounds). A pair with a prior is checked by the "
                  "maps' own search, whose complete search only guards a trusted answer "
                  "(init.prior_complete_search=check; rescue: it also re-searches an untrusted "
                  "pair, at its cost; --set init.prior_check=off: the prior's search alone). In a "
                  "merge of more than 12 maps a pair without a prior gets the first pass, the "
                  "complete search only checking a trusted answer (search.complete_search=check; "
                  "rescue: every pair's complete search; docs/merge.md)");
  cmd->add_flag("--resume", args->resume, "Reuse the finished edges in OUTDIR/edges/");
  cmd->add_option("--threads", args->threads,
                  "OpenMP threads over the pairs (0 = all); the result does not depend on it")
      ->capture_default_str();
  cmd->add_flag("--no-fuse", args->no_fuse,
                "Do not fuse landmarks with the same id in maps of the same session");
  cmd->add_option("--dask-scheduler", args->dask_scheduler,
                  "Run the pairwise alignments on this Dask scheduler (e.g. tcp://host:8786): "
                  "hands over to the Python package (python3 -m lmalign.merge_cli; needs it "
                  "installed and python3-distributed; the maps on a filesystem every worker "
                  "sees). Same result as in process");
  cmd->add_flag("--plan-only", args->plan_only,
                "Only plan the candidate pairs: write OUTDIR/candidates.csv and stop");
  cmd->add_flag("--no-plots", args->no_plots,
                "Do not draw merge_graph.png and merged_landmarks.png (scripts/plot_merge.py)");
  return [args]() { return run_merge_command(*args); };
}

}  // namespace lmalign::cli
