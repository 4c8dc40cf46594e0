// Scaling of lmalign with the number of landmarks N (docs/performance.md): a seeded simulated
// SLAM map pair (lmalign/sim/slam_sim.hpp) of N landmarks per map, weighted k=5 (observation
// weights), started 5 cm and 2 degrees off the truth. One N per process (--n), so that the memory
// figures are clean; bench/run_bench.py --scaling runs them all and fits the growth.
//
// Reported per N:
//   - plain_per_iteration_s: a full correspondence search of every point (reuse off), per
//     iteration, from the difference of two forced runs (so setup and scores cancel out);
//   - reuse_per_iteration_s: 150 forced iterations with the exact reuse, total / 150;
//   - added heap and RSS of registration beyond the loaded maps: everything from extracting the
//     source positions and building the PreparedTarget (kd-tree, uniform and observation
//     weights) to the end of align(), as the peak above the level before it. Heap bytes come from
//     counting operator new/delete in this process.
#include <malloc.h>
#include <omp.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <new>
#include <string>

#include "common.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/sim/slam_sim.hpp"
#include "lmalign/weights/weights.hpp"

// ---- heap accounting: live bytes and their peak, for every operator new in the process

namespace {
std::atomic<long long> g_live{0};
std::atomic<long long> g_peak{0};

void note_alloc(void* p) {
  if (p == nullptr) return;
  const long long now = g_live += static_cast<long long>(malloc_usable_size(p));
  long long peak = g_peak.load(std::memory_order_relaxed);
  while (now > peak && !g_peak.compare_exchange_weak(peak, now)) {
  }
}
void note_free(void* p) {
  if (p != nullptr) g_live -= static_cast<long long>(malloc_usable_size(p));
}
void* counted_alloc(std::size_t n) {
  void* p = std::malloc(n == 0 ? 1 : n);
  if (p == nullptr) throw std::bad_alloc();
  note_alloc(p);
  return p;
}
void* counted_aligned(std::size_t n, std::align_val_t a) {
  const std::size_t al = static_cast<std::size_t>(a);
  void* p = std::aligned_alloc(al, ((n == 0 ? 1 : n) + al - 1) / al * al);
  if (p == nullptr) throw std::bad_alloc();
  note_alloc(p);
  return p;
}
void counted_free(void* p) {
  note_free(p);
  std::free(p);
}
}  // namespace

void* operator new(std::size_t n) { return counted_alloc(n); }
void* operator new[](std::size_t n) { return counted_alloc(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_alloc(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  try {
    return counted_alloc(n);
  } catch (...) {
    return nullptr;
  }
}
void* operator new(std::size_t n, std::align_val_t a) { return counted_aligned(n, a); }
void* operator new[](std::size_t n, std::align_val_t a) { return counted_aligned(n, a); }
void operator delete(void* p) noexcept { counted_free(p); }
void operator delete[](void* p) noexcept { counted_free(p); }
void operator delete(void* p, std::size_t) noexcept { counted_free(p); }
void operator delete[](void* p, std::size_t) noexcept { counted_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { counted_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { counted_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { counted_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { counted_free(p); }

namespace lmalign::bench {
namespace {

/// The paper's observations strategy, forced to `iterations`, from `start` (bench/common.hpp).
RegistrationResult forced(const Points3& source, const PreparedTarget& target, int iterations,
                          bool reuse, const Isometry3& start) {
  AlignRequest request = forced_paper_request(iterations, reuse, false);
  request.initial_guess = start;
  SourceView view;
  view.positions = &source;
  static const Preset preset = find_preset("observations");
  return align(preset, view, target, request).registration;
}

int run(const Args& args) {
  const std::size_t n =
      std::strtoull(args.extra.count("n") ? args.extra.at("n").c_str() : "10000", nullptr, 10);
  sim::SlamSimOptions so;
  so.num_landmarks = n;
  so.seed = 2024;
  so.overlap = 1.0;  // both sessions map the same stretch: ICP has the true transform as minimum
  so.T_target_source = pose_from_xyz_rpy_deg(0.4, -0.3, 0.1, 2, -3, 25);
  const double t_sim = now_s();
  const sim::SlamMapPair pair = sim::simulate_map_pair(so);
  const double sim_s = now_s() - t_sim;
  const Isometry3 start = so.T_target_source * pose_from_xyz_rpy_deg(0.04, -0.03, 0.01, 1, -1, 2);
  malloc_trim(0);

  // Memory: one cold registration (150 forced iterations with reuse), peaks above the level
  // with only the maps loaded.
  const bool peak_reset = reset_peak_rss();
  const std::size_t rss_before = rss_bytes();
  const long long heap_before = g_live.load();
  g_peak.store(heap_before);
  RegistrationResult reuse_run;
  double reuse_s = 0.0;
  std::size_t tree_bytes = 0;
  {
    const double t0 = now_s();
    // What a user of one strategy builds: the kd-tree and the one weight kind it uses.
    // (PreparedTarget(Map) computes all four kinds: 8 more bytes per target landmark each.)
    const Points3 source = pair.source.positions();
    PreparedTarget target(pair.target.positions());
    target.set_weights(WeightKind::kObservations,
                       compute_weights(pair.target, WeightKind::kObservations));
    tree_bytes = target.tree().memory_bytes();
    reuse_run = forced(source, target, args.iterations, true, start);
    reuse_s = now_s() - t0;
  }
  const long long heap_peak = g_peak.load();
  const std::size_t rss_peak = peak_rss_bytes();

  // Time: the prepared target built once, then runs of each kind.
  const Points3 source = pair.source.positions();
  const PreparedTarget target(pair.target);
  const int reps = args.reps;
  std::vector<double> reuse_t, plain_t;
  for (int r = 0; r < reps; ++r) {
    RegistrationResult res = forced(source, target, args.iterations, true, start);
    reuse_t.push_back(res.wall_time_s);
  }
  // Plain search per iteration: difference of a (2 + m)- and a 2-iteration run.
  const int m = n >= 300000 ? 4 : n >= 30000 ? 10 : 30;
  for (int r = 0; r < reps; ++r) {
    const double a = forced(source, target, 2 + m, false, start).wall_time_s;
    const double b = forced(source, target, 2, false, start).wall_time_s;
    plain_t.push_back((a - b) / m);
  }
  const double reuse_med = median(reuse_t);
  std::printf(
      "{\"n\": %zu, \"threads\": %d, \"iterations\": %d, \"simulate_s\": %.6g, "
      "\"reuse_total_s\": %.9g, \"reuse_per_iteration_s\": %.9g, \"plain_per_iteration_s\": "
      "%.9g, \"cold_reuse_total_s_with_setup\": %.9g, \"final_score_m2\": %.17g, "
      "\"added_heap_peak_bytes\": %lld, \"added_rss_peak_bytes\": %zu, \"peak_rss_reset\": %s, "
      "\"kdtree_bytes\": %zu, \"source_landmarks\": %zu, \"target_landmarks\": %zu}\n",
      n, omp_get_max_threads(), reuse_run.iterations, sim_s, reuse_med, reuse_med / args.iterations,
      median(plain_t), reuse_s, reuse_run.final_score_m2, heap_peak - heap_before,
      rss_peak > rss_before ? rss_peak - rss_before : 0, peak_reset ? "true" : "false", tree_bytes,
      pair.source.landmarks.size(), pair.target.landmarks.size());
  return 0;
}

}  // namespace
}  // namespace lmalign::bench

int main(int argc, char** argv) {
  try {
    std::vector<char*> args(argv, argv + argc);
    std::string config = "--config";
    std::string name = "scaling";
    args.push_back(config.data());
    args.push_back(name.data());
    return lmalign::bench::run(
        lmalign::bench::parse_args(static_cast<int>(args.size()), args.data()));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_scaling: %s\n", e.what());
    return 2;
  }
}
