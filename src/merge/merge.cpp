// A whole merge in one call (include/lmalign/merge/merge.hpp).
#include "lmalign/merge/merge.hpp"

#include <omp.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <mutex>
#include <new>

#include "lmalign/core/error.hpp"
#include "lmalign/core/first_exception.hpp"
#include "lmalign/merge/output.hpp"
#include "lmalign/merge/overlap_repair.hpp"

namespace lmalign {

bool MergeOptions::is_valid(std::string* why) const {
  std::string w;
  if (!candidates.is_valid(&w)) {
    if (why) *why = "candidates: " + w;
    return false;
  }
  if (!edges.is_valid(&w)) {
    if (why) *why = "edges: " + w;
    return false;
  }
  if (!graph.is_valid(&w)) {
    if (why) *why = "graph: " + w;
    return false;
  }
  if (!overlaps.is_valid(&w)) {
    if (why) *why = "overlaps: " + w;
    return false;
  }
  if (!repair.is_valid(&w)) {
    if (why) *why = "repair: " + w;
    return false;
  }
  if (threads < 0) {
    if (why) *why = "threads must be >= 0";
    return false;
  }
  return true;
}

void set_overlap_check_mode(const std::string& mode, MergeOptions* options) {
  if (mode != "repair" && mode != "check" && mode != "off") {
    throw InvalidArgument("overlap_check: expected 'repair', 'check' or 'off', got '" + mode + "'");
  }
  options->overlaps.enabled = mode != "off";
  options->repair.enabled = mode == "repair";
}

std::vector<bool> scale_free_maps(const std::vector<Map>& maps, ScaleMode mode) {
  std::vector<bool> out(maps.size(), false);
  for (std::size_t i = 0; i < maps.size(); ++i) {
    out[i] = mode != ScaleMode::kFixed && maps[i].header.scale != MapScale::kMetric;
  }
  return out;
}

MergeGraph solve_and_check(const std::vector<Map>& maps,
                           const std::vector<std::optional<MapPrior>>& priors,
                           const std::vector<Edge>& edges, const MergeOptions& options) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("merge options: " + why);
  MergeGraph out;
  const std::vector<bool> scale_free = scale_free_maps(maps, options.edges.scale);
  out.result = solve_pose_graph(maps.size(), priors, edges, options.graph, scale_free);
  if (!options.overlaps.enabled) return out;
  const auto t0 = std::chrono::steady_clock::now();
  OverlapCheckOptions o = options.overlaps;
  if (o.threads == 0) o.threads = options.threads;
  out.overlaps = check_overlaps(maps, out.result, edges, o);
  if (options.repair.enabled && out.overlaps.num_contradicted() > 0) {
    out.repair = repair_overlaps(maps, priors, edges, options.graph, scale_free, o, options.repair,
                                 &out.result, &out.overlaps);
  }
  out.seconds_check = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

MergeRun run_merge(const std::vector<Map>& maps, const std::vector<std::string>& names,
                   const std::vector<std::optional<MapPrior>>& priors, const MergeOptions& options,
                   const MergeProgress& progress, const std::atomic<bool>* cancel) {
  std::string why;
  if (!options.is_valid(&why)) throw InvalidArgument("merge options: " + why);
  if (names.size() != maps.size() || priors.size() != maps.size()) {
    throw InvalidArgument("run_merge: maps, names and priors differ in number");
  }
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  MergeRun run;
  const std::size_t n = maps.size();
  std::vector<MapSummary> summaries(n);
  std::vector<std::string> fingerprints(n);
  for (std::size_t i = 0; i < n; ++i) {
    summaries[i] = summarise_map(maps[i], options.candidates, i + 1);
    fingerprints[i] = map_fingerprint(maps[i]);
  }
  run.candidates = plan_candidates(summaries, priors, options.candidates);
  const std::size_t m = run.candidates.size();
  if (!options.edge_cache_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(options.edge_cache_dir, ec);
    if (ec) throw IoError("cannot create '" + options.edge_cache_dir + "': " + ec.message());
  }
  // Cached edges first (serially), then the rest in parallel, one slot per pair.
  std::vector<std::optional<Edge>> slots(m);
  std::vector<std::string> keys(m);
  for (std::size_t k = 0; k < m; ++k) {
    const CandidatePair& c = run.candidates[k];
    keys[k] = edge_key(fingerprints[c.source], fingerprints[c.target], c, options.edges);
    if (options.edge_cache_dir.empty()) continue;
    const std::string path =
        edge_file_path(options.edge_cache_dir, names[c.source], names[c.target]);
    std::optional<Edge> e = read_edge_file(path);
    if (e && e->key == keys[k] && e->source == c.source && e->target == c.target) {
      slots[k] = std::move(e);
      ++run.edges_reused;
    }
  }
  // Targets prepared once (immutable, shared by the threads), only for the maps needed.
  std::vector<std::unique_ptr<PreparedTarget>> prepared(n);
  std::vector<std::unique_ptr<SourceLandmarks>> sources(n);
  for (std::size_t k = 0; k < m; ++k) {
    if (slots[k]) continue;
    const CandidatePair& c = run.candidates[k];
    if (!prepared[c.target]) prepared[c.target] = std::make_unique<PreparedTarget>(maps[c.target]);
    if (!sources[c.source])
      sources[c.source] = std::make_unique<SourceLandmarks>(edge_source(maps[c.source]));
  }
  std::size_t done = run.edges_reused;
  if (progress) progress("edges", done, m);
  std::mutex mutex;
  // An exception may not leave the parallel loop: the first one stops the remaining edges and is
  // reported after it (the progress callback's included).
  FirstException error;
  const int threads = options.threads > 0 ? options.threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::ptrdiff_t kk = 0; kk < static_cast<std::ptrdiff_t>(m); ++kk) {
    const std::size_t k = static_cast<std::size_t>(kk);
    if (slots[k]) continue;
    if (cancel != nullptr && cancel->load()) continue;
    if (error.failed()) continue;
    error.capture([&] {
      const CandidatePair& c = run.candidates[k];
      Edge e = align_edge(*sources[c.source], *prepared[c.target], c, options.edges);
      e.key = keys[k];
      if (!options.edge_cache_dir.empty()) {
        write_edge_file(edge_file_path(options.edge_cache_dir, names[c.source], names[c.target]),
                        e);
      }
      std::lock_guard<std::mutex> lock(mutex);
      slots[k] = std::move(e);
      ++done;
      if (progress) progress("edges", done, m);
    });
  }
  try {
    error.rethrow();
  } catch (const std::bad_alloc&) {
    throw;  // out of memory stays what it is
  } catch (const std::exception& ex) {
    throw InvalidArgument(std::string("merge: an edge failed: ") + ex.what());
  }
  const auto t1 = Clock::now();
  run.seconds_edges = std::chrono::duration<double>(t1 - t0).count();
  for (auto& s : slots) {
    if (s) run.edges.push_back(std::move(*s));
  }
  if (run.edges.size() < m) {
    run.cancelled = true;
    return run;
  }
  if (progress) progress("graph", 0, 1);
  // Maps without metric scale get a scale of their own (Sim(3)), unless the scale is fixed.
  MergeGraph graph = solve_and_check(maps, priors, run.edges, options);
  run.result = std::move(graph.result);
  run.overlaps = std::move(graph.overlaps);
  run.repair = std::move(graph.repair);
  run.seconds_check = graph.seconds_check;
  if (progress) progress("graph", 1, 1);
  run.seconds_graph = std::chrono::duration<double>(Clock::now() - t1).count() - run.seconds_check;
  return run;
}

}  // namespace lmalign
